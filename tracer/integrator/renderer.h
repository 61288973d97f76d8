// The host-side interface every backend implements: load a compiled scene, add samples to a
// progressive accumulator, read the mean image and per-frame statistics.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "image/denoise.h"
#include "image/image.h"
#include "integrator/gpu_options.h"
#include "integrator/guide_host.h"
#include "integrator/path.h"
#include "scene/compiled_scene.h"

namespace tracer {

// The bounce from which the wavefront's tail runs (0: none): the first after the camera rays'
// whose estimated queue (paths entering each bounce, as measured in an earlier sample; a bounce
// past its end, or one not measured because an earlier tail took over, counts as short) holds
// fewer than fraction x pixels, among the `iterations` bounces the stages would run.
uint32_t wavefront_tail_bounce(const std::vector<uint32_t>& estimate, float fraction,
                               uint32_t pixels, uint32_t iterations);

// Milliseconds per stage of one wavefront bounce.
struct BounceTimes {
  double intersect = 0, sort = 0, shade = 0, shadow = 0, compact = 0;
  double mnee = 0;  // manifold NEE's stage (render.mnee)
  // The fused trace stage that traced this bounce's extension rays together with the previous
  // bounce's shadow rays (EffectiveGpuOptions::fused_trace; then intersect is 0 here and the
  // previous bounce's shadow is 0).
  double trace = 0;
};

// Milliseconds spent per wavefront stage in one call of render() (zero for the megakernel).
struct StageTimes {
  double generate = 0, intersect = 0, sort = 0, shade = 0, shadow = 0, compact = 0;
  double intersect_first = 0;  // the camera rays' share of `intersect`
  // Fused trace stages (a bounce's shadow rays with the next bounce's extension rays).
  double trace = 0;
  double mnee = 0;  // manifold NEE's stage (render.mnee): its solves and their rays
  double light = 0;  // light tracing's paths (render.light_tracing), after the camera paths
  std::vector<BounceTimes> bounces;  // the same per bounce (wavefront only)
  double tail = 0;         // the wavefront's tail kernel
  uint32_t tail_from = 0;  // the bounce its tail began at (0: none)
  bool rays_at_slots = false;  // its rays and hits were stored at their queue slots
  bool fused_trace = false;    // its shadow and next intersect stages ran fused (trace)
  double megakernel = 0;
  // The whole sample (intersect includes intersect_first).
  double total() const {
    return generate + intersect + sort + shade + shadow + trace + compact + mnee + light + tail +
           megakernel;
  }
};

struct FrameStats {
  uint32_t spp_added = 0;
  double ms = 0.0;
  RayCounts rays;
  uint64_t nonfinite = 0;  // samples rejected because they were NaN or infinite
  uint64_t clamped = 0;         // samples the radiance clamp scaled down
  double clamped_luminance = 0;  // luminance the clamp removed (sum over samples): its bias
  StageTimes stages;
  std::vector<uint32_t> alive_per_bounce;  // paths entering each bounce (first call's wave)
  // Shadow rays the wavefront's stages traced per bounce (same wave; only with compaction in the
  // shade kernel, which queues them; empty otherwise).
  std::vector<uint32_t> shadow_per_bounce;
  // ... and the paths that ended without a shadow ray, which the shadow stage's last lanes add
  // to the film (same wave, same condition).
  std::vector<uint32_t> finished_per_bounce;
  // Manifold NEE's requests per bounce (same wave; render.mnee on the GPU only).
  std::vector<uint32_t> mnee_per_bounce;
  std::string kernel;                      // "wavefront", "megakernel", "cpu"
  std::string specialization;              // which compiled variant ran
  std::string note;                        // e.g. why the first-bounce cache is off
  // The GPU backend: the switches and design paths that ran, and what overrode the request and
  // why (EffectiveGpuOptions::overrides, describe()). Empty on the CPU.
  std::optional<EffectiveGpuOptions> gpu;
};

// --kernel auto's calibration: milliseconds per sample of each design, from the samples it timed.
struct AutoKernelTimes {
  double wavefront_ms = 0, megakernel_ms = 0;
};

// Feature values a pixel's AOV sums hold where a host keeps them (CPU backend, distributed
// rendering's sums): albedo rgb, normal xyz, depth.
inline constexpr size_t kAovFloats = 7;

// The means of the feature buffers (integrator/aov.h) over the samples so far.
struct AovImages {
  ImageRGB albedo, normal;               // linear RGB; unit normals averaged (not renormalised)
  std::vector<float> depth;              // width * height: mean distance to the first hit
  std::vector<uint32_t> material, prim;  // width * height, of each pixel's sample 0
  bool empty() const { return albedo.pixels.empty(); }
};

class Renderer {
 public:
  virtual ~Renderer() = default;
  virtual std::string backend_name() const = 0;  // "cpu" or "cuda"
  virtual std::string device_name() const = 0;    // e.g. "2 threads" or the GPU's name
  // Takes the scene (the caller keeps it alive) and clears the accumulator.
  virtual void set_scene(const CompiledScene& scene, const IntegratorSettings& cfg) = 0;
  virtual void set_settings(const IntegratorSettings& cfg) = 0;  // clears the accumulator
  virtual void reset() = 0;                                        // O(1) on the GPU
  // Adds `spp` samples per pixel; blocks until done. They are the samples numbered from the
  // next sample index on (0 after set_scene, set_settings and reset; each call moves it on).
  virtual FrameStats render(uint32_t spp) = 0;
  // The samples added so far (whichever their numbers).
  virtual uint32_t samples_done() const = 0;
  // Makes the next render() start at sample `index`. A sample's number alone seeds its paths, so
  // processes that render disjoint ranges of numbers add up to the image one process renders
  // with all of them (distributed rendering: integrator/distributed.h). Path guiding trains by
  // the numbers from 0 on: with a guide, only the next index itself is accepted (throws
  // std::logic_error otherwise).
  virtual void set_next_sample(uint32_t index) = 0;
  virtual uint32_t next_sample() const = 0;
  // The samples of even (half 0) and of odd numbers (half 1) added: what half_images() average.
  virtual uint32_t half_samples(int half) const = 0;
  virtual uint64_t nonfinite_total() const = 0;
  // The mean radiance per pixel so far.
  virtual ImageRGB image() const = 0;
  // Means of the even-numbered and of the odd-numbered samples: two independent estimates whose
  // difference measures the remaining noise (relMSE between half buffers).
  virtual void half_images(ImageRGB* even, ImageRGB* odd) const = 0;
  // The halves' sums (not means; 3 floats per pixel each, zero where a half has no sample) into
  // the caller's memory, e.g. a window shared with other processes: what distributed ranks add.
  virtual void half_sums(float* even, float* odd) const;
  // The feature buffers (integrator/aov.h: one more camera ray, and the specular chain behind
  // it, per sample). Off by default. Turning them on does not clear the colour: they start with
  // the next sample (so a viewer can switch a denoiser on without restarting the render);
  // reset() and set_settings() clear them with the colour and keep them on.
  virtual void set_aovs(bool on) = 0;
  virtual bool aovs() const = 0;
  // Their means: over every AOV sample (half -1), the even-numbered (0) or the odd-numbered
  // ones (1). Empty while off or before their first sample.
  virtual AovImages aov_images(int half = -1) const = 0;
  // AOV samples so far (fewer than samples_done() when they were turned on late).
  virtual uint32_t aov_samples() const = 0;
  // image() denoised (image/denoise.h), guided by the albedo and normal AOVs when they are on.
  // The CUDA backend denoises in device memory (no copy of the inputs through the host). Throws
  // with the reason when the denoiser is absent or fails.
  virtual ImageRGB denoised_image(DenoiseInfo* info = nullptr) const;
  // The display image, exposure and tone map applied, as RGBA8 rows top first.
  virtual void display_rgba8(std::vector<uint32_t>& out, float exposure_scale, ToneMap op) const;
  // Path guiding's progress (render.guiding; off when not asked for).
  virtual GuideStatus guide_status() const { return {}; }
  // GPU-only switches; the CPU backend ignores them.
  virtual void set_gpu_options(const GpuOptions&) {}

  // Figures for reports (`pathtracer bench`, tests). The defaults are the CPU backend's: it keeps
  // no path state between stages and no copy of the scene, and has one design.
  // Bytes per pixel of the path state kept between stages.
  virtual size_t path_state_bytes_per_pixel() const { return 0; }
  // Bytes of the scene copied into the backend's own (device) memory.
  virtual size_t scene_bytes() const { return 0; }
  // The design that renders: the forced one, the one --kernel auto chose after its first
  // frames ("auto (not decided yet)" before), or the backend's name where it has one design.
  virtual std::string chosen_kernel() const { return backend_name(); }
  // What --kernel auto timed for each design before choosing (zero where it timed nothing).
  virtual AutoKernelTimes auto_kernel_times() const { return {}; }
};

// The integrator's settings from a scene's render settings, for set_scene and set_settings.
IntegratorSettings make_integrator_settings(const RenderSettings& rs);

// relMSE (pbrt's MRSE) between the two half-buffer estimates; their mean's error is about half.
double half_buffer_relmse(const Renderer& r);
// The same between two half images (pbrt's MRSE with 0.01 added to the denominator's mean).
double half_images_relmse(const ImageRGB& even, const ImageRGB& odd);

}  // namespace tracer
