#include "integrator/guide_host.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <thread>

#include "bvh/bvh.h"
#include "integrator/guide_calibration.h"
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
                         uint32_t sample, const GuideCalibration& calibration) {
  GuideView v;
  if (calibration.retires() || (guide_calibrates(sample) && !guide_calibration_guided(sample)))
    return v;
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

void GuideCalibration::add_time(bool guided, double sample_seconds) {
  if (samples[guided] < kEach) seconds[guided][samples[guided]++] = sample_seconds;
}

double GuideCalibration::time_ratio() const {
  if (samples[0] == 0 || samples[1] == 0) return 1.0;
  auto median = [&](int kind) {
    double t[kEach];
    const uint32_t n = samples[kind];
    for (uint32_t i = 0; i < n; ++i) {  // insertion sort of at most kEach
      uint32_t j = i;
      for (; j > 0 && t[j - 1] > seconds[kind][i]; --j) t[j] = t[j - 1];
      t[j] = seconds[kind][i];
    }
    return n % 2 ? t[n / 2] : 0.5 * (t[n / 2 - 1] + t[n / 2]);
  };
  const double unguided = median(0);
  return unguided > 0.0 ? median(1) / unguided : 1.0;
}

double GuideCalibration::variance_ratio() const {
  return noise[0] > 0.0 && noise[1] >= 0.0 ? noise[1] / noise[0] : 1.0;
}

double guide_block_noise(const double* now, const double* then, const double* base,
                         double inv_block, double inv_base, size_t floats) {
  double total = 0.0;
  for (size_t i = 0; i < floats; ++i)
    total += guide_moment_term((now[i] - then[i]) * inv_block, base[i] * inv_base);
  return total;
}

GuideStatus GuideStatus::of(const GuideGrid& grid, uint32_t samples, uint32_t builds,
                            uint32_t learned, uint32_t guiding,
                            const GuideCalibration& calibration) {
  GuideStatus s;
  s.on = true;
  s.trained_samples = std::min(samples, kGuideTrainSamples);
  s.builds = builds;
  s.learned_cells = learned;
  s.guiding_cells = guiding;
  s.cells = grid.cells();
  s.calibration = calibration;
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
  if (frozen()) {
    const GuideCalibration& c = calibration;
    std::string verdict;
    if (!c.done()) {
      verdict = "; calibrating (" + std::to_string(c.samples[0] + c.samples[1]) + " of " +
                std::to_string(kGuideCalibrationSamples) + " spp)";
    } else {
      char ratios[96];
      std::snprintf(ratios, sizeof(ratios), "%.2fx the variance for %.2fx the time per sample",
                    c.variance_ratio(), c.time_ratio());
      verdict = std::string(c.retires() ? "; retired (unguided from here): " : "; kept: ") + ratios;
    }
    return "frozen after " + std::to_string(kGuideTrainSamples) + " spp, " + cells_text + verdict;
  }
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
  calibration_ = GuideCalibration();
}

void HostGuide::clear() {
  std::fill(hist_.begin(), hist_.end(), 0.0f);
  std::fill(dist_.begin(), dist_.end(), 0.0f);
  std::fill(counts_.begin(), counts_.end(), 0u);
  std::fill(records_.begin(), records_.end(), kNoRecord);
  builds_ = learned_ = guiding_ = 0;
  calibration_ = GuideCalibration();
}

GuideView HostGuide::view(uint32_t first_sample) {
  return guide_view_for(grid_, {dist_.data(), hist_.data(), counts_.data(), records_.data()},
                        builds_, first_sample, calibration_);
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
  return ready() ? GuideStatus::of(grid_, samples, builds_, learned_, guiding_, calibration_)
                 : GuideStatus();
}

}  // namespace tracer
