// The CPU backend: every core runs the shared trace_path over rows of pixels. Each pixel's samples
// are summed by one thread in sample order, so the image is the same for any thread count.
#pragma once

#include <atomic>
#include <vector>

#include "integrator/renderer.h"

namespace tracer {

class CpuRenderer final : public Renderer {
 public:
  explicit CpuRenderer(int threads = 0);  // 0: std::thread::hardware_concurrency()
  std::string backend_name() const override { return "cpu"; }
  std::string device_name() const override;
  void set_scene(const CompiledScene& scene, const IntegratorSettings& cfg) override;
  void set_settings(const IntegratorSettings& cfg) override;
  void reset() override;
  FrameStats render(uint32_t spp) override;
  uint32_t samples_done() const override { return samples_; }
  void set_next_sample(uint32_t index) override;
  uint32_t next_sample() const override { return next_; }
  uint32_t half_samples(int half) const override { return half_count_[half & 1]; }
  uint64_t nonfinite_total() const override { return nonfinite_; }
  ImageRGB image() const override;
  void half_images(ImageRGB* even, ImageRGB* odd) const override;
  void half_sums(float* even, float* odd) const override;
  void set_aovs(bool on) override;
  bool aovs() const override { return aovs_on_; }
  AovImages aov_images(int half = -1) const override;
  uint32_t aov_samples() const override { return aov_count_[0] + aov_count_[1]; }
  GuideStatus guide_status() const override { return guide_.status(next_); }
  int threads() const { return threads_; }
  // When set, render() checks the flag between rows and abandons the pass (adding nothing and
  // returning spp_added = 0) once it is true: edits in the workbench never wait for a pass.
  void set_cancel_flag(const std::atomic<bool>* flag) { cancel_ = flag; }
  // The SSE traversal of the CPU BVH layout (bvh/cpu_bvh.h, on by default where the build has
  // it) or the shared scalar traversal the GPU runs: the same hits, for A/B measurements.
  void set_simd_traversal(bool on) { simd_traversal_ = on; }
  bool simd_traversal() const { return simd_traversal_ && cpu_bvh_supported(); }
  // The flat primitive list of small scenes (bvh/flat_list.h), which the GPU uses by default;
  // off by default here, where the SSE BVH is faster. For tests and A/B measurements.
  void set_flat_list(bool on) { flat_list_ = on; }

 private:
  int threads_;
  const CompiledScene* scene_ = nullptr;
  bool mnee_casters_ = false;  // mnee_has_casters(*scene_): else no manifold NEE requests
  bool light_paths_ = false;   // light_tracing_has_paths(*scene_, cfg_): else no light paths
  IntegratorSettings cfg_;
  std::vector<double> sum_even_, sum_odd_;    // 3 per pixel: samples 0, 2, 4... and 1, 3, 5...
  std::vector<double> pass_even_, pass_odd_;  // this call's sums, added when it completes
  // With AOVs on: 7 per pixel (albedo, normal, depth), summed per half like the colour, and
  // the material and primitive of the first AOV sample (2 per pixel).
  bool aovs_on_ = false;
  std::vector<double> aov_even_, aov_odd_, pass_aov_even_, pass_aov_odd_;
  std::vector<uint32_t> aov_ids_, pass_aov_ids_;
  uint32_t aov_count_[2] = {0, 0};  // AOV samples in each half
  void allocate_aovs();
  // Path guiding (render.guiding): sized by set_settings, cleared by reset().
  HostGuide guide_;
  void setup_guide();
  // Its calibration (guide_host.h): the sums before the first block and before the current one.
  std::vector<double> calibration_base_, calibration_then_;
  uint32_t calibration_base_count_ = 0;
  std::vector<double> total_sums() const;  // sum_even_ + sum_odd_
  // Adds spp samples within one pass of the guide's schedule (all of them when not guiding).
  FrameStats render_pass(uint32_t spp);
  const std::atomic<bool>* cancel_ = nullptr;
  uint32_t samples_ = 0;            // added
  uint32_t next_ = 0;               // the next sample's number
  uint32_t half_count_[2] = {0, 0};  // added, of even and of odd numbers
  uint64_t nonfinite_ = 0;
  bool simd_traversal_ = true;
  bool flat_list_ = false;
};

}  // namespace tracer
