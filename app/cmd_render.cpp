// `pathtracer render`: load a scene (or the built-in Cornell box), render it to a sample count or
// a time budget with progress on stderr, write the image atomically and a JSON sidecar that
// records everything needed to reproduce it. --frames renders a sequence of scene files; under
// an MPI launcher the render (or the sequence) is spread over the ranks (mpi_render.cpp).
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <thread>
#include <nlohmann/json.hpp>

#include "backends/backend_select.h"
#include "commands.h"
#include "render_job.h"
#include "image/image.h"
#include "integrator/black_image.h"
#include "image/display.h"
#include "scene/loader.h"

namespace app {

std::string fmt_seconds(double s) {
  char buf[32];
  if (s < 60) snprintf(buf, sizeof buf, "%.1f s", s);
  else snprintf(buf, sizeof buf, "%dm%02ds", int(s) / 60, int(s) % 60);
  return buf;
}

int prepare_render(const RenderOptions& o, const std::string& scene_path, const std::string& out,
                   const HostSlot* slot, bool writes, bool quiet, std::ostream& err,
                   RenderJob* job) {
  using clock = std::chrono::steady_clock;
  const auto t_start = clock::now();
  job->scene_path = scene_path;
  job->out = out;
  tracer::Scene& scene = job->scene;
  if (!load_scene_or_report(scene_path, &scene, err)) return kExitInputError;

  std::string problem;
  if (o.settings.flags.count("render.spp") && o.settings.flags.count("render.time_limit_s")) {
    err << "error: --spp and --time exclude each other (a render stops at one of them)\n";
    return kExitUsage;
  }
  if (!apply_setting_args(o.settings, &scene, &problem)) {
    err << "error: " << problem << "\n";
    return kExitUsage;
  }
  const tracer::RenderSettings& rs = scene.settings;
  if (rs.spp == 0 && rs.time_limit_s <= 0.0) {
    err << "error: render.spp is 0 (no limit) and there is no time limit: give --spp or "
           "--time; nothing was rendered\n";
    return kExitUsage;
  }
  try {
    tracer::validate_scene(scene);  // the command line may have made the image too large
  } catch (const tracer::InputError& e) {
    err << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  if (!report_scene_messages(scene, quiet, err)) return kExitInputError;
  {  // Refuse an output the writer cannot produce before spending the render on it.
    const std::string ext = out.size() > 4 ? out.substr(out.size() - 4) : "";
    std::string lower = ext;
    for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (lower != ".png" && lower != ".exr") {
      err << "error: " << out << ": unsupported image format (use .png or .exr); "
          << "nothing was rendered\n";
      return kExitUsage;
    }
    try {  // and an output it cannot create (a missing or unwritable folder)
      if (writes) tracer::check_writable(out);
    } catch (const std::exception& e) {
      err << "error: " << e.what() << "\n";
      return kExitInputError;
    }
  }
  job->aovs = tracer::AovRequest();
  job->aovs.png = o.aov_png;
  if (!tracer::parse_aov_list(o.aov, &job->aovs, &problem)) {
    err << "error: " << problem << "\n";
    return kExitUsage;
  }
  if (o.aov_png && !job->aovs.any()) {
    err << "error: --aov-png needs --aov (which AOVs to write)\n";
    return kExitUsage;
  }
  job->denoise = scene.display.denoise != tracer::DenoiseMode::kOff;
  if (writes && job->denoise && !tracer::denoiser_available()) {
    err << "error: display.denoise is on but the denoiser is absent: "
        << tracer::denoiser_status() << "\nnothing was rendered\n";
    return kExitInputError;
  }
  std::string note;
  try {
    if (slot) {
      const int gpus = rs.backend == tracer::BackendChoice::kCpu ? 0 : tracer::cuda_device_count();
      const tracer::RankPlacement place =
          tracer::place_rank(rs.backend, rs.threads, slot->local_rank, slot->local_size, gpus,
                             int(std::thread::hardware_concurrency()));
      job->renderer = tracer::make_renderer(place.backend, place.threads, &note, place.device);
      if (!place.note.empty()) note = place.note + (note.empty() ? "" : "; " + note);
    } else {
      job->renderer = tracer::make_renderer(rs.backend, rs.threads, &note);
    }
  } catch (const std::exception& e) {
    err << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  if (!note.empty() && !quiet) err << "note: " << note << "\n";

  job->compiled = std::make_unique<tracer::CompiledScene>(scene, rs.width, rs.height);
  job->cfg = tracer::make_integrator_settings(rs);
  try {
    job->renderer->set_gpu_options(scene.gpu);
    job->renderer->set_scene(*job->compiled, job->cfg);  // e.g. more than the GPU's free memory
    job->renderer->set_aovs(job->aovs.any() || job->denoise);  // the denoiser's guides
  } catch (const std::exception& e) {
    err << "error: " << scene_path << ": " << e.what() << "\n";
    return kExitInputError;
  }
  job->setup_s = std::chrono::duration<double>(clock::now() - t_start).count();
  return 0;
}

void render_progressive(RenderJob& job, bool quiet, tracer::SidecarRun* run) {
  using clock = std::chrono::steady_clock;
  const tracer::RenderSettings& rs = job.scene.settings;
  tracer::Renderer& renderer = *job.renderer;
  // Passes sized so that progress updates about twice a second.
  const bool timed = rs.time_limit_s > 0.0;
  const uint32_t target = timed ? 0u : uint32_t(rs.spp);
  const bool tty = isatty(STDERR_FILENO);
  const auto r_start = clock::now();
  auto last_print = r_start;
  uint32_t pass = 1;
  double render_s = 0.0;
  std::string last_note;
  for (;;) {
    const uint32_t done = renderer.samples_done();
    if (!timed && done >= target) break;
    if (timed && render_s >= rs.time_limit_s) break;
    uint32_t n = timed ? pass : std::min(pass, target - done);
    const tracer::FrameStats fs = renderer.render(n);
    if (!fs.note.empty() && fs.note != last_note && !quiet) {
      std::cerr << (tty ? "\n" : "") << "note: " << fs.note << "\n";
      last_note = fs.note;
    }
    run->last = fs;
    run->rays += fs.rays;
    run->clamped += fs.clamped;
    run->clamped_luminance += fs.clamped_luminance;
    render_s = std::chrono::duration<double>(clock::now() - r_start).count();
    const double per_spp = fs.ms / 1000.0 / n;
    double budget = 0.5;
    if (timed) budget = std::min(budget, rs.time_limit_s - render_s);
    pass = uint32_t(std::clamp(budget / std::max(per_spp, 1e-6), 1.0, 4096.0));
    const auto now = clock::now();
    if (!quiet && std::chrono::duration<double>(now - last_print).count() > (tty ? 0.25 : 5.0)) {
      last_print = now;
      print_progress(rs, renderer.samples_done(), render_s, "", tty);
    }
  }
  if (!quiet && tty) std::cerr << "\n";
  run->backend = renderer.backend_name();
  run->device = renderer.device_name();
  run->spp = renderer.samples_done();
  run->wall_time_s = render_s;
  run->setup_time_s = job.setup_s;
  run->nonfinite = renderer.nonfinite_total();
  run->aov_samples = renderer.aov_samples();
  run->guide = renderer.guide_status();
}

int finish_render(RenderJob& job, const tracer::ImageRGB& img, const tracer::AovImages& aov_images,
                  const tracer::ImageRGB* denoised, const tracer::DenoiseInfo* denoised_info,
                  tracer::SidecarRun run, bool quiet, std::ostream& err) {
  const tracer::Scene& scene = job.scene;
  const tracer::RenderSettings& rs = scene.settings;
  const std::string& out = job.out;
  const tracer::ToneMap op = scene.display.tone_map;
  run.output = out;
  run.kept_luminance = 0.0;
  for (size_t i = 0; i < img.pixels.size(); i += 3)
    run.kept_luminance += tracer::luminance(
        tracer::vec3(img.pixels[i], img.pixels[i + 1], img.pixels[i + 2]));
  run.kept_luminance *= double(run.spp);
  run.features = tracer::describe_features(job.compiled->features());
  tracer::ExportResult exported;
  try {
    exported = tracer::export_render(out, img, &aov_images, job.aovs, scene, run,
                                     job.denoise ? denoised : nullptr, denoised_info);
  } catch (const std::exception& e) {
    err << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  // An all-black result is almost never what was wanted: say why it is black, and count it as a
  // warning (--strict: exit 1).
  std::vector<std::string> late_warnings;
  {
    bool any_light = false, any_shown = false;
    const float scale = std::exp2(scene.display.exposure);
    for (size_t i = 0; i + 2 < img.pixels.size() && !any_shown; i += 3) {
      const tracer::vec3 c(img.pixels[i], img.pixels[i + 1], img.pixels[i + 2]);
      if (!(c.x > 0.0f || c.y > 0.0f || c.z > 0.0f)) continue;
      any_light = true;
      any_shown = (tracer::display_rgba8(c, scale, op) & 0xffffffu) != 0;
    }
    if (!any_light) {
      late_warnings.push_back(out + ": the image is entirely black: " +
                              tracer::explain_black_image(scene, *job.compiled));
    } else if (!any_shown && out.size() > 4 && out.substr(out.size() - 4) != ".exr") {
      std::ostringstream stops;
      stops << scene.display.exposure;
      late_warnings.push_back(out + ": the image is black after the display transform "
                              "(display.exposure " + stops.str() +
                              " stops): raise --exposure; the linear image is not black");
    }
  }
  std::string clamp_report;
  if (rs.clamp > 0.0f) {
    clamp_report = "clamp " + std::to_string(rs.clamp) + ": " + std::to_string(run.clamped) +
                   " samples scaled down, removing " +
                   std::to_string(100.0 * tracer::clamp_removed_fraction(run)) +
                   "% of the image's luminance (bias)";
  }
  if (!quiet) {
    const std::string where =
        run.ranks.size() > 1 ? std::to_string(run.ranks.size()) + " MPI ranks" : run.backend;
    err << "wrote " << out << " (" << rs.width << "x" << rs.height << ", " << run.spp << " spp, "
        << fmt_seconds(run.wall_time_s) << ", " << where << ")";
    if (run.nonfinite) err << "; " << run.nonfinite << " NaN/Inf samples rejected";
    err << "\n";
    if (!exported.denoise.denoiser.empty())
      err << "denoised with " << exported.denoise.denoiser << " (" << exported.denoise.device
          << ", " << exported.denoise.inputs << ", " << std::fixed << std::setprecision(1)
          << exported.denoise.ms << " ms): "
          << (scene.display.denoise == tracer::DenoiseMode::kOn ? out : tracer::denoised_path(out))
          << " (biased: the raw image is the unbiased estimate)\n";
    for (const std::string& f : exported.files)
      if (f != out && f != out + ".json") err << "wrote " << f << "\n";
    if (!clamp_report.empty()) err << "note: " << clamp_report << "\n";
    if (run.guide.on) err << "path guiding: " << run.guide.describe() << "\n";
  }
  if (run.rays.walk_capped)
    late_warnings.push_back(std::to_string(run.rays.walk_capped) +
                            " subsurface random walks stopped at " +
                            std::to_string(tracer::kMaxWalkSteps) +
                            " steps (their paths end there: energy is lost)");
  if (run.rays.medium_leaks)
    late_warnings.push_back(std::to_string(run.rays.medium_leaks) +
                            " paths left a subsurface medium without crossing its boundary: a "
                            "mesh with subsurface material is not closed");
  // Warnings are shown even with --quiet: they are about the result, not progress.
  const char* kind = rs.strict ? "error: " : "warning: ";
  for (const std::string& w : late_warnings) err << kind << w << "\n";
  if (rs.strict && !late_warnings.empty()) {
    err << "error: --strict (render.strict): the render ended with " << late_warnings.size()
        << (late_warnings.size() == 1 ? " warning" : " warnings") << " (the image was written)\n";
    return kExitInputError;
  }
  return 0;
}

int render_one(const RenderOptions& o, const std::string& scene_path, const std::string& out,
               const HostSlot* slot, bool quiet, std::ostream& err) {
  RenderJob job;
  if (const int rc = prepare_render(o, scene_path, out, slot, true, quiet, err, &job)) return rc;
  tracer::SidecarRun run;
  render_progressive(job, quiet, &run);
  tracer::Renderer& r = *job.renderer;
  const tracer::ImageRGB img = r.image();
  run.relmse_halves = tracer::half_buffer_relmse(r);
  // The AOVs come back to the host only to be written; the denoiser reads them on the device.
  const tracer::AovImages aov_images = job.aovs.any() ? r.aov_images() : tracer::AovImages();
  tracer::ImageRGB denoised;
  tracer::DenoiseInfo info;
  try {
    if (job.denoise) denoised = r.denoised_image(&info);  // on the GPU in device memory
  } catch (const std::exception& e) {
    err << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  return finish_render(job, img, aov_images, job.denoise ? &denoised : nullptr, &info, run, quiet,
                       err);
}

void print_progress(const tracer::RenderSettings& rs, uint32_t done, double seconds,
                    const std::string& where, bool tty) {
  const bool timed = rs.time_limit_s > 0.0;
  const double sps = double(done) * rs.width * rs.height / std::max(seconds, 1e-9);
  const double eta = timed ? rs.time_limit_s - seconds
                           : done ? (double(rs.spp) - done) * seconds / done : 0.0;
  std::cerr << (tty ? "\r" : "") << "render: " << done
            << (timed ? "" : "/" + std::to_string(rs.spp)) << " spp" << where << ", " << std::fixed
            << std::setprecision(2) << sps / 1e6 << " Msamples/s, ETA "
            << fmt_seconds(std::max(0.0, eta)) << (tty ? "   " : "\n") << std::flush;
}

bool mpi_environment() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS"})
    if (std::getenv(v)) return true;
  return false;
}

namespace {

// --frames A..B in this process: each frame a whole render; a failed frame does not stop the
// others, and the exit code says that one failed.
int render_frames(const RenderOptions& o) {
  int first = 0, last = 0;
  std::string problem;
  if (!tracer::parse_frame_range(o.frames, &first, &last, &problem)) {
    std::cerr << "error: " << problem << "\n";
    return kExitUsage;
  }
  int failed = 0;
  for (int f = first; f <= last; ++f) {
    const std::string scene = tracer::frame_path(o.scene, f), out = tracer::frame_path(o.out, f);
    if (!o.quiet) std::cerr << "frame " << f << " (" << f - first + 1 << " of " << last - first + 1
                            << "): " << scene << " -> " << out << "\n";
    if (render_one(o, scene, out, nullptr, o.quiet, std::cerr)) {
      std::cerr << "error: frame " << f << " (" << scene << ") failed\n";
      ++failed;
    }
  }
  if (failed)
    std::cerr << "error: " << failed << " of " << last - first + 1 << " frames failed\n";
  return failed ? kExitInputError : 0;
}

int run_render(const RenderOptions& o) {
  if (!o.frames.empty()) {  // (without --frames a '#' is an ordinary character of a path)
    std::string problem;
    if (!tracer::has_frame_field(o.out))
      problem = "--frames needs a run of '#' in --out for the frame number (e.g. out/f_####.png)";
    else if (!tracer::has_frame_field(o.scene))
      problem = "--frames needs a run of '#' in the scene path for the frame number (e.g. "
                "shot_####.json: one scene file per frame)";
    if (!problem.empty()) {
      std::cerr << "error: " << problem << "\n";
      return kExitUsage;
    }
  }
  if (mpi_environment()) return run_render_mpi(o);
  if (!o.frames.empty()) return render_frames(o);
  return render_one(o, o.scene, o.out, nullptr, o.quiet, std::cerr);
}

}  // namespace

Runner add_render_command(CLI::App& cmd) {
  auto o = std::make_shared<RenderOptions>();
  cmd.add_option("scene", o->scene,
                 "Scene file (.json, .pbrt, .obj, .gltf, .glb, .ply); default: built-in Cornell "
                 "box. With --frames, a pattern whose run of '#' is the frame number "
                 "(shot_####.json)");
  cmd.add_option("--out", o->out, "Output file: .png (tone-mapped sRGB) or .exr (linear float)")
      ->capture_default_str();
  cmd.add_flag("--quiet,-q", o->quiet, "No progress or summary on stderr");
  cmd.add_option("--aov", o->aov,
                 "Feature buffers to write: albedo, normal, depth, id (material and object) or "
                 "all, comma-separated: layers of an .exr output (albedo.R, normal.X, depth.Z, "
                 "id.material, id.object), PNG images beside a .png output (name.albedo.png)");
  cmd.add_flag("--aov-png", o->aov_png, "Also write the --aov images as PNG beside an .exr output");
  cmd.add_option("--frames", o->frames,
                 "Render a sequence: frames A..B of the scene pattern to the --out pattern (a "
                 "run of '#' in each is the frame number, zero-padded to its length); under "
                 "mpirun the frames are spread over the ranks");
  add_setting_options(cmd, &o->settings, {"render", "gpu", "display", "environment"},
                      {"render.samples_per_frame"});
  return [o] { return run_render(*o); };
}

}  // namespace app
