// CPU backend: rows of pixels handed to worker threads through an atomic counter.
#include "cpu/cpu_backend.h"

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>

#include "integrator/aov.h"
#include "integrator/light_path.h"

namespace tracer {

CpuRenderer::CpuRenderer(int threads) {
  threads_ = threads > 0 ? threads : int(std::max(1u, std::thread::hardware_concurrency()));
}

std::string CpuRenderer::device_name() const {
  return "CPU, " + std::to_string(threads_) + (threads_ == 1 ? " thread" : " threads");
}

void CpuRenderer::set_scene(const CompiledScene& scene, const IntegratorSettings& cfg) {
  scene_ = &scene;
  mnee_casters_ = mnee_has_casters(scene);
  set_settings(cfg);
}

void CpuRenderer::set_settings(const IntegratorSettings& cfg) {
  cfg_ = cfg;
  light_paths_ = cfg.light_tracing && scene_ && light_tracing_has_paths(*scene_, cfg);
  cfg_.guide = GuideView();
  const size_t n = size_t(cfg.width) * cfg.height * 3;
  for (auto* b : {&sum_even_, &sum_odd_, &pass_even_, &pass_odd_}) b->assign(n, 0.0);
  allocate_aovs();
  setup_guide();
  samples_ = next_ = half_count_[0] = half_count_[1] = 0;
  nonfinite_ = 0;
}

void CpuRenderer::reset() {
  std::fill(sum_even_.begin(), sum_even_.end(), 0.0);
  std::fill(sum_odd_.begin(), sum_odd_.end(), 0.0);
  allocate_aovs();
  if (guide_.ready()) guide_.clear();
  samples_ = next_ = half_count_[0] = half_count_[1] = 0;
  nonfinite_ = 0;
}

void CpuRenderer::set_next_sample(uint32_t index) {
  if (guide_.ready() && index != next_)
    throw std::logic_error("CpuRenderer::set_next_sample: path guiding trains on the samples in "
                           "their order from 0 (sample " + std::to_string(index) +
                           " asked for, " + std::to_string(next_) + " next)");
  next_ = index;
}

void CpuRenderer::setup_guide() {
  if (cfg_.guiding && scene_) {
    guide_.setup(guide_grid(*scene_, cfg_.width * cfg_.height), cfg_.width * cfg_.height);
  } else {
    guide_ = HostGuide();
  }
}

void CpuRenderer::allocate_aovs() {
  const size_t pixels = aovs_on_ ? size_t(cfg_.width) * cfg_.height : 0;
  for (auto* b : {&aov_even_, &aov_odd_, &pass_aov_even_, &pass_aov_odd_})
    b->assign(pixels * kAovFloats, 0.0);
  aov_ids_.assign(pixels * 2, kInvalid);
  pass_aov_ids_.assign(pixels * 2, kInvalid);
  aov_count_[0] = aov_count_[1] = 0;
}

void CpuRenderer::set_aovs(bool on) {
  if (on == aovs_on_) return;
  aovs_on_ = on;
  allocate_aovs();
}

namespace {

// What one pass hands every worker thread, and what each thread counts.
struct Pass {
  const SceneView* view;
  const IntegratorSettings* cfg;
  uint32_t first_sample, spp;
  std::atomic<uint32_t>* next_row;
  double* pass_even;  // 3 per pixel
  double* pass_odd;
  double* aov_even;  // kAovFloats per pixel, or null while AOVs are off
  double* aov_odd;
  uint32_t* aov_ids;  // 2 per pixel
  bool aov_first;     // the pass holds the first AOV sample: it writes the ids
  const std::atomic<bool>* cancel;
};
struct ThreadTotals {
  RayCounts rays;
  uint64_t nonfinite = 0, clamped = 0;
  double removed = 0.0;
};

// One worker's share of a pass: rows taken from the shared counter until none is left.
TRACER_CPU_MULTIVERSION void render_rows(const Pass& p, ThreadTotals& out) {
  const IntegratorSettings& cfg = *p.cfg;
  RayCounts rc;
  uint64_t nonfinite = 0, clamps = 0;
  double lost = 0.0;
  for (uint32_t y; (y = p.next_row->fetch_add(1)) < cfg.height;) {
    for (uint32_t x = 0; x < cfg.width; ++x) {
      const uint32_t pixel = y * cfg.width + x;
      double acc[2][3] = {{0, 0, 0}, {0, 0, 0}};
      for (uint32_t s = 0; s < p.spp; ++s) {
        const uint32_t sample = p.first_sample + s;
        vec3 L = trace_path(*p.view, cfg, pixel, sample, &rc);  // trains the guide, if any
        if (!is_finite(L)) {
          ++nonfinite;  // counted and reported, never added
          continue;
        }
        float cut;
        L = clamp_radiance(L, cfg.clamp, &cut);
        if (cut > 0.0f) {
          ++clamps;
          lost += cut;
        }
        double* a = acc[sample & 1];
        a[0] += L.x;
        a[1] += L.y;
        a[2] += L.z;
      }
      for (int c = 0; c < 3; ++c) {
        p.pass_even[size_t(pixel) * 3 + c] = acc[0][c];
        p.pass_odd[size_t(pixel) * 3 + c] = acc[1][c];
      }
      if (p.aov_even) {
        double aov[2][kAovFloats] = {};
        for (uint32_t s = 0; s < p.spp; ++s) {
          const uint32_t sample = p.first_sample + s;
          const AovSample a = trace_aov(*p.view, cfg, pixel, sample);
          double* d = aov[sample & 1];
          const float v[kAovFloats] = {a.albedo.x, a.albedo.y, a.albedo.z, a.normal.x,
                                       a.normal.y, a.normal.z, a.depth};
          for (size_t c = 0; c < kAovFloats; ++c) d[c] += v[c];
          if (p.aov_first && s == 0) {
            p.aov_ids[size_t(pixel) * 2] = a.material;
            p.aov_ids[size_t(pixel) * 2 + 1] = a.prim;
          }
        }
        for (size_t c = 0; c < kAovFloats; ++c) {
          p.aov_even[size_t(pixel) * kAovFloats + c] = aov[0][c];
          p.aov_odd[size_t(pixel) * kAovFloats + c] = aov[1][c];
        }
      }
    }
    if (p.cancel && p.cancel->load(std::memory_order_relaxed)) break;
  }
  out.rays = rc;
  out.nonfinite = nonfinite;
  out.clamped = clamps;
  out.removed = lost;
}

// Adds v to *p from several threads.
inline void atomic_add(double* p, double v) {
  double old;
  __atomic_load(p, &old, __ATOMIC_RELAXED);
  double next = old + v;
  while (!__atomic_compare_exchange(p, &old, &next, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED))
    next = old + v;
}

// One worker's share of a pass's light paths (cfg.light_tracing; integrator/light_path.h):
// width x height per sample, in chunks from the shared counter, splatted into the pass's sums of
// each sample's half.
TRACER_CPU_MULTIVERSION void trace_light_paths(const Pass& p, std::atomic<uint32_t>* next_chunk,
                                               ThreadTotals& out) {
  const IntegratorSettings& cfg = *p.cfg;
  const uint32_t n = light_paths_per_sample(*p.view, cfg.width * cfg.height);
  const uint64_t total = uint64_t(n) * p.spp;
  constexpr uint32_t kChunk = 1024;
  const float norm = filter_profile_integral(cfg.filter, cfg.filter_radius);
  uint64_t segments = 0, connections = 0;
  for (uint64_t c; (c = uint64_t(next_chunk->fetch_add(1)) * kChunk) < total;) {
    for (uint64_t i = c; i < std::min(total, c + kChunk); ++i) {
      const uint32_t sample = p.first_sample + uint32_t(i / n);
      double* sums = (sample & 1) ? p.pass_odd : p.pass_even;
      auto splat = [&](uint32_t pixel, vec3 v) {
        float cut;
        v = clamp_radiance(v, cfg.clamp, &cut);
        if (cut > 0.0f) {
          ++out.clamped;
          out.removed += cut;
        }
        atomic_add(&sums[size_t(pixel) * 3 + 0], v.x);
        atomic_add(&sums[size_t(pixel) * 3 + 1], v.y);
        atomic_add(&sums[size_t(pixel) * 3 + 2], v.z);
      };
      const LightPathCounts lc =
          trace_light_path<kAllFeatures>(*p.view, cfg, uint32_t(i % n), sample, n, norm, splat);
      segments += lc.segments;
      connections += lc.connections;
    }
    if (p.cancel && p.cancel->load(std::memory_order_relaxed)) break;
  }
  out.rays.extension += segments;
  out.rays.shadow += connections;
}

}  // namespace

FrameStats CpuRenderer::render(uint32_t spp) {
  if (!scene_) throw std::logic_error("CpuRenderer::render: no scene set");
  if (!guide_.ready()) return render_pass(spp);
  // Guiding: the guide is rebuilt at the end of each training pass, so a call that spans passes
  // renders them one after another; the calibration's samples (guide_host.h) one at a time.
  const auto start = std::chrono::steady_clock::now();
  FrameStats total;
  for (uint32_t done = 0; done < spp;) {
    const uint32_t first = next_;
    uint32_t chunk = spp - done;
    if (guide_trains(first)) {
      chunk = std::min(chunk, guide_pass_end(first) - first + 1);
    } else if (guide_calibrates(first)) {
      chunk = 1;
    } else if (first < kGuideCalibrationStart) {
      chunk = std::min(chunk, kGuideCalibrationStart - first);
    }
    const bool calibrating = guide_calibrates(first) && !guide_.calibration().done();
    if (calibrating && guide_calibration_block_starts(first)) {
      // The sums before a block: the first block's also give the mean both blocks are
      // measured against.
      calibration_then_ = total_sums();
      if (first == kGuideCalibrationStart) {
        calibration_base_ = calibration_then_;
        calibration_base_count_ = samples_;
      }
    }
    FrameStats st = render_pass(chunk);
    if (st.spp_added == 0) break;  // cancelled
    if (calibrating) {
      GuideCalibration& c = guide_.calibration();
      const bool guided = guide_calibration_guided(first);
      c.add_time(guided, st.ms * 1e-3);
      if (guide_calibration_block_ends(first) && calibration_base_count_ > 0) {
        const std::vector<double> now = total_sums();
        c.noise[guided] = guide_block_noise(now.data(), calibration_then_.data(),
                                            calibration_base_.data(), 1.0 / kGuideCalibrationBlock,
                                            1.0 / calibration_base_count_, now.size());
      }
    }
    if (guide_trains(next_ - 1) && guide_builds_after(next_ - 1)) guide_.build(threads_);
    if (done == 0) {
      total = st;
    } else {
      total.spp_added += st.spp_added;
      total.rays += st.rays;
      total.nonfinite += st.nonfinite;
      total.clamped += st.clamped;
      total.clamped_luminance += st.clamped_luminance;
    }
    done += chunk;
  }
  total.ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return total;
}

FrameStats CpuRenderer::render_pass(uint32_t spp) {
  const auto start = std::chrono::steady_clock::now();
  IntegratorSettings cfg = cfg_;
  if (guide_.ready()) cfg.guide = guide_.view(next_);
  // Manifold NEE with nothing to connect through: no requests (the same image, as on the GPU).
  if (!mnee_casters_) cfg.mnee = 0;
  // Light tracing with no path worth tracing or without jitter: none traced.
  if (!light_tracing_runs(cfg, light_paths_)) cfg.light_tracing = 0;
  SceneView view = scene_->view();
  if (!simd_traversal_) view.cpu_bvh = CpuBvhView();
  view.use_flat = flat_list_ && scene_->flat_list().enabled ? 1u : 0u;
  std::atomic<uint32_t> next_row{0};
  const bool aovs = aovs_on_ && !aov_even_.empty();
  const Pass pass{&view,
                  &cfg,
                  next_,
                  spp,
                  &next_row,
                  pass_even_.data(),
                  pass_odd_.data(),
                  aovs ? pass_aov_even_.data() : nullptr,
                  aovs ? pass_aov_odd_.data() : nullptr,
                  aovs ? pass_aov_ids_.data() : nullptr,
                  aov_count_[0] + aov_count_[1] == 0,
                  cancel_};
  std::vector<ThreadTotals> totals(threads_);
  auto worker = [&](int t) { render_rows(pass, totals[t]); };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads_; ++t) pool.emplace_back(worker, t);
  worker(0);
  for (auto& th : pool) th.join();
  if (cfg.light_tracing) {  // after the camera paths, which write the pass's sums
    std::vector<ThreadTotals> light(threads_);
    std::atomic<uint32_t> next_chunk{0};
    auto light_worker = [&](int t) { trace_light_paths(pass, &next_chunk, light[t]); };
    pool.clear();
    for (int t = 1; t < threads_; ++t) pool.emplace_back(light_worker, t);
    light_worker(0);
    for (auto& th : pool) th.join();
    for (int t = 0; t < threads_; ++t) {
      totals[t].rays += light[t].rays;
      totals[t].clamped += light[t].clamped;
      totals[t].removed += light[t].removed;
    }
  }

  FrameStats st;
  st.kernel = "cpu";
  if (cancel_ && cancel_->load()) {  // abandoned: the accumulator is unchanged
    st.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count();
    return st;
  }
  for (size_t i = 0; i < sum_even_.size(); ++i) {
    sum_even_[i] += pass_even_[i];
    sum_odd_[i] += pass_odd_[i];
  }
  if (aovs) {
    for (size_t i = 0; i < aov_even_.size(); ++i) {
      aov_even_[i] += pass_aov_even_[i];
      aov_odd_[i] += pass_aov_odd_[i];
    }
    if (aov_count_[0] + aov_count_[1] == 0) aov_ids_ = pass_aov_ids_;
    for (uint32_t k = 0; k < spp; ++k) ++aov_count_[(next_ + k) & 1];
  }
  for (uint32_t k = 0; k < spp; ++k) ++half_count_[(next_ + k) & 1];
  st.spp_added = spp;
  for (const ThreadTotals& t : totals) {
    st.rays += t.rays;
    st.nonfinite += t.nonfinite;
    st.clamped += t.clamped;
    st.clamped_luminance += t.removed;
  }
  samples_ += spp;
  next_ += spp;
  nonfinite_ += st.nonfinite;
  st.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return st;
}

std::vector<double> CpuRenderer::total_sums() const {
  std::vector<double> t(sum_even_.size());
  for (size_t i = 0; i < t.size(); ++i) t[i] = sum_even_[i] + sum_odd_[i];
  return t;
}

ImageRGB CpuRenderer::image() const {
  ImageRGB img;
  img.width = int(cfg_.width);
  img.height = int(cfg_.height);
  img.pixels.resize(sum_even_.size());
  const double inv = samples_ > 0 ? 1.0 / samples_ : 0.0;
  for (size_t i = 0; i < sum_even_.size(); ++i)
    img.pixels[i] = float((sum_even_[i] + sum_odd_[i]) * inv);
  return img;
}

void CpuRenderer::half_images(ImageRGB* even, ImageRGB* odd) const {
  const std::vector<double>* sums[2] = {&sum_even_, &sum_odd_};
  ImageRGB* outs[2] = {even, odd};
  const uint32_t* counts = half_count_;
  for (int k = 0; k < 2; ++k) {
    if (!outs[k]) continue;
    ImageRGB& img = *outs[k];
    img.width = int(cfg_.width);
    img.height = int(cfg_.height);
    img.pixels.resize(sums[k]->size());
    const double inv = counts[k] > 0 ? 1.0 / counts[k] : 0.0;
    for (size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = float((*sums[k])[i] * inv);
  }
}

void CpuRenderer::half_sums(float* even, float* odd) const {
  for (size_t i = 0; i < sum_even_.size(); ++i) {
    even[i] = float(sum_even_[i]);
    odd[i] = float(sum_odd_[i]);
  }
}

AovImages CpuRenderer::aov_images(int half) const {
  AovImages out;
  const uint32_t count = half < 0 ? aov_count_[0] + aov_count_[1] : aov_count_[half & 1];
  if (aov_even_.empty() || aov_count_[0] + aov_count_[1] == 0) return out;
  const size_t n = size_t(cfg_.width) * cfg_.height;
  out.albedo = make_image(int(cfg_.width), int(cfg_.height));
  out.normal = make_image(int(cfg_.width), int(cfg_.height));
  out.depth.assign(n, 0.0f);
  out.material.resize(n);
  out.prim.resize(n);
  const double inv = count > 0 ? 1.0 / count : 0.0;
  for (size_t i = 0; i < n; ++i) {
    double v[kAovFloats];
    for (size_t c = 0; c < kAovFloats; ++c) {
      const size_t k = i * kAovFloats + c;
      v[c] = (half < 0 ? aov_even_[k] + aov_odd_[k] : half == 0 ? aov_even_[k] : aov_odd_[k]) *
             inv;
    }
    for (int c = 0; c < 3; ++c) {
      out.albedo.pixels[3 * i + c] = float(v[c]);
      out.normal.pixels[3 * i + c] = float(v[3 + c]);
    }
    out.depth[i] = float(v[6]);
    out.material[i] = aov_ids_[2 * i];
    out.prim[i] = aov_ids_[2 * i + 1];
  }
  return out;
}

}  // namespace tracer
