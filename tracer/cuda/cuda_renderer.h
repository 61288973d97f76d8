// The CUDA backend: the scene in device memory, a float4 progressive accumulator with an O(1)
// reset, and either the wavefront (with optional compaction in its shade kernel or by CUB, a
// megakernel tail for its last short queues, material sorting and first-bounce cache) or the
// megakernel, each specialised on the scene's features.
#pragma once

#include <memory>

#include "integrator/renderer.h"

namespace tracer {

class CudaRenderer final : public Renderer {
 public:
  explicit CudaRenderer(int device);
  ~CudaRenderer() override;
  std::string backend_name() const override { return "cuda"; }
  std::string device_name() const override;
  void set_scene(const CompiledScene& scene, const IntegratorSettings& cfg) override;
  void set_settings(const IntegratorSettings& cfg) override;
  void reset() override;
  FrameStats render(uint32_t spp) override;
  uint32_t samples_done() const override;
  void set_next_sample(uint32_t index) override;
  uint32_t next_sample() const override;
  uint32_t half_samples(int half) const override;
  uint64_t nonfinite_total() const override;
  ImageRGB image() const override;
  void set_gpu_options(const GpuOptions& o) override;
  void half_images(ImageRGB* even, ImageRGB* odd) const override;
  void half_sums(float* even, float* odd) const override;
  void set_aovs(bool on) override;
  bool aovs() const override;
  AovImages aov_images(int half = -1) const override;
  uint32_t aov_samples() const override;
  GuideStatus guide_status() const override;
  ImageRGB denoised_image(DenoiseInfo* info = nullptr) const override;
  void display_rgba8(std::vector<uint32_t>& out, float exposure_scale, ToneMap op) const override;
  uint32_t width_times_height() const;
  // Writes the display image (RGBA8) into device memory, e.g. a mapped OpenGL pixel buffer.
  void display_to_device(void* rgba8, float exposure_scale, ToneMap op) const;

  // Device bytes per pixel of path state and of the scene, for reports.
  size_t path_state_bytes_per_pixel() const override;
  size_t scene_bytes() const override;
  // The design --kernel auto chose (after its first frames), or the forced one.
  std::string chosen_kernel() const override;
  AutoKernelTimes auto_kernel_times() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Device-to-device copy bandwidth in GB/s (bytes read + bytes written, 1 GiB buffers): the
// ceiling the wavefront's memory traffic is measured against.
double measure_copy_bandwidth_gbs();

// nullptr with the reason when no usable device exists.
std::unique_ptr<Renderer> make_cuda_renderer(std::string* why_not, int device);
int cuda_device_count();
// cudaHostRegister / cudaHostUnregister, false (and the error cleared) where the driver refuses.
bool cuda_pin_host(void* ptr, size_t bytes);
void cuda_unpin_host(void* ptr);

}  // namespace tracer
