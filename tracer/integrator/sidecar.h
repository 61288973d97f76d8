// The JSON sidecar written beside every exported image (render, the workbench's export, bench
// references): every setting of the settings table, the materials, and how the image was made.
// One writer, so every command records the same things under the same names.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "image/denoise.h"
#include "integrator/distributed.h"
#include "integrator/gpu_options.h"
#include "integrator/renderer.h"
#include "scene/scene.h"

namespace tracer {

// What happened in the run that made the image.
struct SidecarRun {
  std::string output;  // the image's path
  std::string backend, device;
  uint32_t spp = 0;
  double wall_time_s = 0.0;  // rendering time
  double setup_time_s = -1;  // loading and building (< 0: not recorded)
  RayCounts rays;            // over the whole run
  uint64_t nonfinite = 0;
  uint64_t clamped = 0;            // samples the radiance clamp scaled down
  double clamped_luminance = 0.0;  // luminance it removed, summed over samples
  double kept_luminance = 0.0;     // the image's luminance summed over samples
  std::string features;            // describe_features() of the compiled scene
  FrameStats last;                 // the last frame: kernel, specialization, note
  std::vector<std::string> aovs;   // the feature layers written with the image (EXR) or beside it
  uint32_t aov_samples = 0;        // the samples the AOVs averaged
  GuideStatus guide;               // path guiding's training (render.guiding)
  // The denoiser, when display.denoise was on: what ran and where its image went.
  DenoiseInfo denoise;
  std::string denoised_output;
  // A distributed render (MPI): every rank's share, and the reduction of the accumulators to
  // rank 0 (seconds; < 0: none). The image's half-buffer relMSE is recorded when >= 0.
  std::vector<RankShare> ranks;
  double reduce_s = -1.0;
  double relmse_halves = -1.0;
};

// What the GPU ran for a request (resolve_gpu_options()): the effective switches, the wavefront's
// design paths, the build variant and every override with its reason.
nlohmann::json effective_gpu_json(const EffectiveGpuOptions& e);

// The clamp's bias: the share of the image's luminance it removed.
double clamp_removed_fraction(const SidecarRun& run);

nlohmann::json make_sidecar(const Scene& scene, const SidecarRun& run);
// make_sidecar() written atomically to `run.output` + ".json".
void write_sidecar(const Scene& scene, const SidecarRun& run);

}  // namespace tracer
