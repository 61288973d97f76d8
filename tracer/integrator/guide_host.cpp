#include "integrator/guide_host.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>

#include "bvh/bvh.h"
#include "scene/compiled_scene.h"

namespace tracer {

GuideGrid guide_grid(vec3 lo, vec3 hi, uint32_t side_cells) {
  GuideGrid g;
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z) || !is_finite(lo) || !is_finite(hi)) return g;
  const vec3 extent = hi - lo;
  const float longest = std::max(extent.x, std::max(extent.y, extent.z));
  if (!(longest > 0.0f)) {
    g.lo = lo - vec3(0.5f);
    return g;
  }
  const vec3 margin(longest * 1e-3f);
  lo -= margin;
  hi += margin;
  side_cells = std::clamp(side_cells, 1u, kGuideMaxSide);
  const float cell = (longest * 1.002f) / float(side_cells);
  auto side = [&](float e) {
    return std::clamp(uint32_t(std::ceil(e / cell)), 1u, side_cells);
  };
  g.nx = side(hi.x - lo.x);
  g.ny = side(hi.y - lo.y);
  g.nz = side(hi.z - lo.z);
  g.lo = lo;
  g.inv_cell = vec3(float(g.nx) / (hi.x - lo.x), float(g.ny) / (hi.y - lo.y),
                    float(g.nz) / (hi.z - lo.z));
  return g;
}

uint32_t guide_grid_side(uint32_t pixels) {
  return std::clamp(uint32_t(std::lround(std::cbrt(double(pixels) / 8.0))), 2u, kGuideMaxSide);
}

GuideGrid guide_grid(const CompiledScene& scene, uint32_t pixels) {
  Aabb box;
  const std::vector<BvhNode>& nodes = scene.nodes();
  if (!nodes.empty())
    for (const BvhSlot& c : nodes[0].child)
      if (c.lo.x <= c.hi.x) {
        box.grow(c.lo);
        box.grow(c.hi);
      }
  return guide_grid(box.lo, box.hi, guide_grid_side(pixels));
}

GuideView guide_view_for(const GuideGrid& grid, const GuideArrays& arrays, uint32_t builds,
                         uint32_t sample) {
  GuideView v;
  v.lo = grid.lo;
  v.inv_cell = grid.inv_cell;
  v.nx = grid.nx;
  v.ny = grid.ny;
  v.nz = grid.nz;
  if (builds > 0) v.dist = arrays.dist;
  if (guide_trains(sample)) {
    v.hist = arrays.hist;
    v.counts = arrays.counts;
    v.records = arrays.records;
  }
  return v;
}

GuideStatus GuideStatus::of(const GuideGrid& grid, uint32_t samples, uint32_t builds,
                            uint32_t learned, uint32_t guiding) {
  GuideStatus s;
  s.on = true;
  s.trained_samples = std::min(samples, kGuideTrainSamples);
  s.builds = builds;
  s.learned_cells = learned;
  s.guiding_cells = guiding;
  s.cells = grid.cells();
  return s;
}

std::string GuideStatus::describe() const {
  if (!on) return "off";
  auto grouped = [](uint32_t v) {
    std::string s = std::to_string(v);
    for (int i = int(s.size()) - 3; i > 0; i -= 3) s.insert(size_t(i), ",");
    return s;
  };
  const std::string cells_text =
      grouped(learned_cells) + " of " + grouped(cells) + " cells learned, " +
      grouped(guiding_cells) + " guide";
  if (frozen()) return "frozen after " + std::to_string(kGuideTrainSamples) + " spp, " + cells_text;
  return "training: pass " + std::to_string(builds + 1) + " of 8 (" +
         std::to_string(trained_samples) + " of " + std::to_string(kGuideTrainSamples) +
         " spp), " + cells_text;
}

uint32_t guide_builds_done(uint32_t samples) {
  uint32_t n = 0;
  for (uint32_t s = 0; s < samples && s < kGuideTrainSamples; ++s) n += guide_builds_after(s);
  return n;
}

uint32_t guide_pass_end(uint32_t sample) {
  for (uint32_t s = sample; s < kGuideTrainSamples; ++s)
    if (guide_builds_after(s)) return s;
  return kGuideTrainSamples - 1;
}

// A record of no sample (sample kInvalid): stale for every one.
constexpr GuideRecord kNoRecord{0, 0.0f, 0.0f, kInvalid, 0.0f, 0.0f, 0.0f, 0.0f};

void HostGuide::setup(const GuideGrid& grid, uint32_t pixels) {
  grid_ = grid;
  hist_.assign(size_t(grid.cells()) * kGuideHistFloats, 0.0f);
  dist_.assign(size_t(grid.cells()) * kGuideDistFloats, 0.0f);
  counts_.assign(grid.cells(), 0u);
  records_.assign(size_t(pixels) * kGuideRecords, kNoRecord);
  builds_ = learned_ = guiding_ = 0;
}

void HostGuide::clear() {
  std::fill(hist_.begin(), hist_.end(), 0.0f);
  std::fill(dist_.begin(), dist_.end(), 0.0f);
  std::fill(counts_.begin(), counts_.end(), 0u);
  std::fill(records_.begin(), records_.end(), kNoRecord);
  builds_ = learned_ = guiding_ = 0;
}

GuideView HostGuide::view(uint32_t first_sample) {
  return guide_view_for(grid_, {dist_.data(), hist_.data(), counts_.data(), records_.data()},
                        builds_, first_sample);
}

void HostGuide::build(int threads) {
  const uint32_t cells = grid_.cells();
  std::atomic<uint32_t> next{0}, learned{0}, guiding{0};
  auto work = [&] {
    uint32_t mine = 0, guides = 0;
    for (uint32_t c; (c = next.fetch_add(64)) < cells;)
      for (uint32_t k = c; k < std::min(cells, c + 64); ++k)
        if (guide_build_cell(hist_.data(), counts_.data(), dist_.data(), k)) {
          ++mine;
          guides += dist_[size_t(k) * kGuideDistFloats] > 0.0f;
        }
    learned += mine;
    guiding += guides;
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  learned_ = learned;
  guiding_ = guiding;
  ++builds_;
}

GuideStatus HostGuide::status(uint32_t samples) const {
  return ready() ? GuideStatus::of(grid_, samples, builds_, learned_, guiding_) : GuideStatus();
}

}  // namespace tracer
