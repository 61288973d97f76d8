// `pathtracer render`: load a scene (or the built-in Cornell box), render it to a sample count or
// a time budget with progress on stderr, write the image atomically and a JSON sidecar that
// records everything needed to reproduce it.
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <iostream>
#include <sstream>
#include <nlohmann/json.hpp>

#include "backends/backend_select.h"
#include "commands.h"
#include "integrator/sidecar.h"
#include "settings_cli.h"
#include "image/image.h"
#include "integrator/black_image.h"
#include "integrator/export.h"
#include "integrator/renderer.h"
#include "image/display.h"
#include "scene/compiled_scene.h"
#include "scene/loader.h"

namespace app {
namespace {

struct RenderOptions {
  std::string scene;
  std::string out = "out/render.png";
  bool quiet = false;
  std::string aov;       // --aov albedo,normal,depth,id
  bool aov_png = false;  // --aov-png
  SettingArgs settings;  // the table's flags and --set
};

std::string fmt_seconds(double s) {
  char buf[32];
  if (s < 60) snprintf(buf, sizeof buf, "%.1f s", s);
  else snprintf(buf, sizeof buf, "%dm%02ds", int(s) / 60, int(s) % 60);
  return buf;
}

int run_render(const RenderOptions& o) {
  using clock = std::chrono::steady_clock;
  const auto t_start = clock::now();
  tracer::Scene scene;
  if (!load_scene_or_report(o.scene, &scene)) return kExitInputError;

  std::string problem;
  if (o.settings.flags.count("render.spp") && o.settings.flags.count("render.time_limit_s")) {
    std::cerr << "error: --spp and --time exclude each other (a render stops at one of them)\n";
    return kExitUsage;
  }
  if (!apply_setting_args(o.settings, &scene, &problem)) {
    std::cerr << "error: " << problem << "\n";
    return kExitUsage;
  }
  const tracer::RenderSettings& rs = scene.settings;
  if (rs.spp == 0 && rs.time_limit_s <= 0.0) {
    std::cerr << "error: render.spp is 0 (no limit) and there is no time limit: give --spp or "
                 "--time; nothing was rendered\n";
    return kExitUsage;
  }
  try {
    tracer::validate_scene(scene);  // the command line may have made the image too large
  } catch (const tracer::InputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  if (!report_scene_messages(scene, o.quiet)) return kExitInputError;
  {  // Refuse an output the writer cannot produce before spending the render on it.
    const std::string ext = o.out.size() > 4 ? o.out.substr(o.out.size() - 4) : "";
    std::string lower = ext;
    for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (lower != ".png" && lower != ".exr") {
      std::cerr << "error: " << o.out << ": unsupported image format (use .png or .exr); "
                << "nothing was rendered\n";
      return kExitUsage;
    }
    try {  // and an output it cannot create (a missing or unwritable folder)
      tracer::check_writable(o.out);
    } catch (const std::exception& e) {
      std::cerr << "error: " << e.what() << "\n";
      return kExitInputError;
    }
  }
  tracer::AovRequest aovs;
  aovs.png = o.aov_png;
  if (!tracer::parse_aov_list(o.aov, &aovs, &problem)) {
    std::cerr << "error: " << problem << "\n";
    return kExitUsage;
  }
  if (o.aov_png && !aovs.any()) {
    std::cerr << "error: --aov-png needs --aov (which AOVs to write)\n";
    return kExitUsage;
  }
  const bool denoise = scene.display.denoise != tracer::DenoiseMode::kOff;
  if (denoise && !tracer::denoiser_available()) {
    std::cerr << "error: display.denoise is on but the denoiser is absent: "
              << tracer::denoiser_status() << "\nnothing was rendered\n";
    return kExitInputError;
  }
  const tracer::ToneMap op = scene.display.tone_map;
  const tracer::BackendChoice choice = rs.backend;
  std::unique_ptr<tracer::Renderer> renderer;
  std::string note;
  try {
    renderer = tracer::make_renderer(choice, rs.threads, &note);
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  if (!note.empty() && !o.quiet) std::cerr << "note: " << note << "\n";

  const tracer::CompiledScene compiled(scene, rs.width, rs.height);
  const tracer::IntegratorSettings cfg = tracer::make_integrator_settings(rs);
  try {
    renderer->set_gpu_options(scene.gpu);
    renderer->set_scene(compiled, cfg);  // e.g. more than the GPU's free memory: says so
    renderer->set_aovs(aovs.any() || denoise);  // the denoiser is guided by albedo and normal
  } catch (const std::exception& e) {
    std::cerr << "error: " << o.scene << ": " << e.what() << "\n";
    return kExitInputError;
  }
  const double setup_s = std::chrono::duration<double>(clock::now() - t_start).count();

  // Passes sized so that progress updates about twice a second.
  const bool timed = rs.time_limit_s > 0.0;
  const uint32_t target = timed ? 0u : uint32_t(rs.spp);
  const bool tty = isatty(STDERR_FILENO);
  const auto r_start = clock::now();
  auto last_print = r_start;
  uint32_t pass = 1;
  tracer::RayCounts rays;
  double render_s = 0.0;
  std::string last_note;
  tracer::FrameStats last_stats;
  uint64_t clamped = 0;
  double clamped_luminance = 0.0;
  for (;;) {
    const uint32_t done = renderer->samples_done();
    if (!timed && done >= target) break;
    if (timed && render_s >= rs.time_limit_s) break;
    uint32_t n = timed ? pass : std::min(pass, target - done);
    const tracer::FrameStats fs = renderer->render(n);
    if (!fs.note.empty() && fs.note != last_note && !o.quiet) {
      std::cerr << (tty ? "\n" : "") << "note: " << fs.note << "\n";
      last_note = fs.note;
    }
    last_stats = fs;
    rays.camera += fs.rays.camera;
    rays.extension += fs.rays.extension;
    rays.shadow += fs.rays.shadow;
    rays.walk_capped += fs.rays.walk_capped;
    rays.medium_leaks += fs.rays.medium_leaks;
    clamped += fs.clamped;
    clamped_luminance += fs.clamped_luminance;
    render_s = std::chrono::duration<double>(clock::now() - r_start).count();
    const double per_spp = fs.ms / 1000.0 / n;
    double budget = 0.5;
    if (timed) budget = std::min(budget, rs.time_limit_s - render_s);
    pass = uint32_t(std::clamp(budget / std::max(per_spp, 1e-6), 1.0, 4096.0));
    const auto now = clock::now();
    if (!o.quiet && std::chrono::duration<double>(now - last_print).count() > (tty ? 0.25 : 5.0)) {
      last_print = now;
      const uint32_t d = renderer->samples_done();
      const double sps = double(d) * rs.width * rs.height / render_s;
      const double eta = timed ? rs.time_limit_s - render_s : (target - d) * render_s / d;
      std::cerr << (tty ? "\r" : "") << "render: " << d << (timed ? "" : "/" + std::to_string(target))
                << " spp, " << std::fixed << std::setprecision(2) << sps / 1e6 << " Msamples/s, ETA "
                << fmt_seconds(std::max(0.0, eta)) << (tty ? "   " : "\n") << std::flush;
    }
  }
  if (!o.quiet && tty) std::cerr << "\n";
  const uint32_t spp_done = renderer->samples_done();
  const uint64_t nonfinite = renderer->nonfinite_total();
  const tracer::ImageRGB img = renderer->image();
  tracer::SidecarRun run;
  run.output = o.out;
  run.backend = renderer->backend_name();
  run.device = renderer->device_name();
  run.spp = spp_done;
  run.wall_time_s = render_s;
  run.setup_time_s = setup_s;
  run.rays = rays;
  run.nonfinite = nonfinite;
  run.clamped = clamped;
  run.clamped_luminance = clamped_luminance;
  for (size_t i = 0; i < img.pixels.size(); i += 3)
    run.kept_luminance += tracer::luminance(
        tracer::vec3(img.pixels[i], img.pixels[i + 1], img.pixels[i + 2]));
  run.kept_luminance *= double(spp_done);
  run.features = tracer::describe_features(compiled.features());
  run.last = last_stats;
  run.aov_samples = renderer->aov_samples();
  run.guide = renderer->guide_status();
  tracer::ExportResult exported;
  try {
    // The AOVs come back to the host only to be written; the denoiser reads them on the device.
    const tracer::AovImages aov_images = aovs.any() ? renderer->aov_images() : tracer::AovImages();
    tracer::ImageRGB denoised;
    tracer::DenoiseInfo info;
    if (denoise) denoised = renderer->denoised_image(&info);  // on the GPU in device memory
    exported = tracer::export_render(o.out, img, &aov_images, aovs, scene, run,
                                     denoise ? &denoised : nullptr, &info);
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
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
      late_warnings.push_back(o.out + ": the image is entirely black: " +
                              tracer::explain_black_image(scene, compiled));
    } else if (!any_shown && o.out.size() > 4 && o.out.substr(o.out.size() - 4) != ".exr") {
      std::ostringstream stops;
      stops << scene.display.exposure;
      late_warnings.push_back(o.out + ": the image is black after the display transform "
                              "(display.exposure " + stops.str() +
                              " stops): raise --exposure; the linear image is not black");
    }
  }
  std::string clamp_report;
  if (rs.clamp > 0.0f) {
    clamp_report = "clamp " + std::to_string(rs.clamp) + ": " + std::to_string(clamped) +
                   " samples scaled down, removing " +
                   std::to_string(100.0 * tracer::clamp_removed_fraction(run)) +
                   "% of the image's luminance (bias)";
  }
  if (!o.quiet) {
    std::cerr << "wrote " << o.out << " (" << rs.width << "x" << rs.height << ", " << spp_done
              << " spp, " << fmt_seconds(render_s) << ", " << renderer->backend_name() << ")";
    if (nonfinite) std::cerr << "; " << nonfinite << " NaN/Inf samples rejected";
    std::cerr << "\n";
    if (!exported.denoise.denoiser.empty())
      std::cerr << "denoised with " << exported.denoise.denoiser << " (" << exported.denoise.device
                << ", " << exported.denoise.inputs << ", " << std::fixed << std::setprecision(1)
                << exported.denoise.ms << " ms): "
                << (scene.display.denoise == tracer::DenoiseMode::kOn
                        ? o.out
                        : tracer::denoised_path(o.out))
                << " (biased: the raw image is the unbiased estimate)\n";
    for (const std::string& f : exported.files)
      if (f != o.out && f != o.out + ".json") std::cerr << "wrote " << f << "\n";
    if (!clamp_report.empty()) std::cerr << "note: " << clamp_report << "\n";
    if (run.guide.on) std::cerr << "path guiding: " << run.guide.describe() << "\n";
  }
  if (rays.walk_capped)
    late_warnings.push_back(std::to_string(rays.walk_capped) +
                            " subsurface random walks stopped at " +
                            std::to_string(tracer::kMaxWalkSteps) +
                            " steps (their paths end there: energy is lost)");
  if (rays.medium_leaks)
    late_warnings.push_back(std::to_string(rays.medium_leaks) +
                            " paths left a subsurface medium without crossing its boundary: a "
                            "mesh with subsurface material is not closed");
  // Warnings are shown even with --quiet: they are about the result, not progress.
  const char* kind = rs.strict ? "error: " : "warning: ";
  for (const std::string& w : late_warnings) std::cerr << kind << w << "\n";
  if (rs.strict && !late_warnings.empty()) {
    std::cerr << "error: --strict (render.strict): the render ended with "
              << late_warnings.size() << (late_warnings.size() == 1 ? " warning" : " warnings")
              << " (the image was written)\n";
    return kExitInputError;
  }
  return 0;
}

}  // namespace

Runner add_render_command(CLI::App& cmd) {
  auto o = std::make_shared<RenderOptions>();
  cmd.add_option("scene", o->scene, "Scene file (.json, .pbrt, .obj, .gltf, .glb, .ply); default: built-in Cornell box")
      ->check(CLI::ExistingFile);
  cmd.add_option("--out", o->out, "Output file: .png (tone-mapped sRGB) or .exr (linear float)")
      ->capture_default_str();
  cmd.add_flag("--quiet,-q", o->quiet, "No progress or summary on stderr");
  cmd.add_option("--aov", o->aov,
                 "Feature buffers to write: albedo, normal, depth, id (material and object) or "
                 "all, comma-separated: layers of an .exr output (albedo.R, normal.X, depth.Z, "
                 "id.material, id.object), PNG images beside a .png output (name.albedo.png)");
  cmd.add_flag("--aov-png", o->aov_png, "Also write the --aov images as PNG beside an .exr output");
  add_setting_options(cmd, &o->settings, {"render", "gpu", "display", "environment"},
                      {"render.samples_per_frame"});
  return [o] { return run_render(*o); };
}

}  // namespace app
