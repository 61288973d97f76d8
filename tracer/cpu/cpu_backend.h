// The CPU backend: every core runs the shared trace_path over rows of pixels. Each pixel's samples
// are summed by one thread in sample order, so the image is the same for any thread count.
#pragma once

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
  uint64_t nonfinite_total() const override { return nonfinite_; }
  ImageRGB image() const override;
  int threads() const { return threads_; }

 private:
  int threads_;
  const CompiledScene* scene_ = nullptr;
  IntegratorSettings cfg_;
  std::vector<double> sum_;  // 3 per pixel
  uint32_t samples_ = 0;
  uint64_t nonfinite_ = 0;
};

}  // namespace tracer
