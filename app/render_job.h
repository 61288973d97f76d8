// `pathtracer render`'s steps, shared by the single-process render, its frame sequences and the
// distributed render over MPI (mpi_render.cpp): set a render up, render it progressively, and
// export what it accumulated.
#pragma once

#include <iosfwd>
#include <memory>
#include <string>

#include "integrator/distributed.h"
#include "integrator/export.h"
#include "integrator/renderer.h"
#include "integrator/sidecar.h"
#include "scene/compiled_scene.h"
#include "scene/scene.h"
#include "settings_cli.h"

namespace app {

struct RenderOptions {
  std::string scene;  // a file, or a pattern with a run of '#' for --frames
  std::string out = "out/render.png";
  bool quiet = false;
  std::string aov;       // --aov albedo,normal,depth,id
  bool aov_png = false;  // --aov-png
  std::string frames;    // --frames A..B
  SettingArgs settings;  // the table's flags and --set
};

// A render set up and ready to add samples.
struct RenderJob {
  std::string scene_path, out;
  tracer::Scene scene;
  std::unique_ptr<tracer::CompiledScene> compiled;
  tracer::IntegratorSettings cfg;
  std::unique_ptr<tracer::Renderer> renderer;
  tracer::AovRequest aovs;
  bool denoise = false;
  double setup_s = 0.0;
};

// A process's place among the ranks of its host (distributed rendering); null: a lone process.
struct HostSlot {
  int local_rank = 0, local_size = 1;
};

// Loads `scene_path` (empty: the built-in box), applies the command line, checks everything that
// can fail before rendering (settings, output format and, where this process `writes` the
// output, its folder and the denoiser; the AOV list) and makes the renderer (on the device `slot`
// gives it, when given). Messages go to `err`. Returns 0, or the exit code after saying why.
int prepare_render(const RenderOptions& o, const std::string& scene_path, const std::string& out,
                   const HostSlot* slot, bool writes, bool quiet, std::ostream& err,
                   RenderJob* job);

// Adds samples to job.renderer until render.spp or render.time_limit_s, with progress on stderr
// unless quiet; fills run's render fields (spp, wall time, rays, counters, last frame).
void render_progressive(RenderJob& job, bool quiet, tracer::SidecarRun* run);

// Writes `img` (and the AOVs, the denoised image, the sidecar) to job.out, prints the summary
// and the warnings about the result. `run` holds the render's figures; the output, features and
// luminance are filled here. Returns 0 or the exit code.
int finish_render(RenderJob& job, const tracer::ImageRGB& img, const tracer::AovImages& aovs,
                  const tracer::ImageRGB* denoised, const tracer::DenoiseInfo* denoised_info,
                  tracer::SidecarRun run, bool quiet, std::ostream& err);

// One whole render of one scene in this process: prepare, render, finish.
int render_one(const RenderOptions& o, const std::string& scene_path, const std::string& out,
               const HostSlot* slot, bool quiet, std::ostream& err);

// "4.2 s" or "3m07s", for progress lines.
std::string fmt_seconds(double s);

// One progress line on stderr ("render: 120/4096 spp[where], 85.3 Msamples/s, ETA 12.0 s"): done
// samples after `seconds` of rendering towards rs.spp or rs.time_limit_s; on a terminal it
// rewrites its line.
void print_progress(const tracer::RenderSettings& rs, uint32_t done, double seconds,
                    const std::string& where, bool tty);

// Whether this process was started by an MPI launcher (mpirun, srun: its environment says so).
bool mpi_environment();
// The render (or --frames sequence) spread over the MPI job's ranks (mpi_render.cpp). In a
// build without MPI it says so and fails.
int run_render_mpi(const RenderOptions& o);

}  // namespace app
