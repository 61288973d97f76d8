// `pathtracer render`: load a scene (or the built-in Cornell box), render it to a sample count or
// a time budget with progress on stderr, write the image atomically and a JSON sidecar that
// records everything needed to reproduce it.
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "image/image.h"
#include "integrator/renderer.h"
#include "scene/compiled_scene.h"
#include "scene/loader.h"

namespace app {
namespace {

struct RenderOptions {
  std::string scene;
  std::string out = "out/render.png";
  std::string backend = "auto";
  int spp = 0, width = 0, height = 0, max_depth = 0, threads = 0, rr_start = 0;
  double time = 0.0;
  long long seed = -1;
  std::string nee, mis, rr;  // "on"/"off" or empty: keep the scene's setting
  std::string sampler;       // "random"/"sobol" or empty: keep the scene's setting
  float exposure = 0.0f;
  std::string tonemap = "none";
  bool quiet = false;
  // GPU switches (ignored by the CPU backend).
  std::string kernel = "auto";
  std::string compaction = "on", sort = "off", cache = "on", flat = "on";
  float tail = tracer::GpuOptions().tail_fraction;
  std::string jitter;
  float clamp = -1.0f;  // < 0: the scene's setting
};

tracer::GpuOptions gpu_options(const RenderOptions& o) {
  tracer::GpuOptions g;
  g.kernel = o.kernel == "wavefront"    ? tracer::KernelMode::kWavefront
             : o.kernel == "megakernel" ? tracer::KernelMode::kMegakernel
                                        : tracer::KernelMode::kAuto;
  tracer::parse_compaction(o.compaction, &g.compaction);  // (checked by the option)
  g.sort_materials = o.sort == "on";
  g.first_bounce_cache = o.cache == "on";
  g.flat_list = o.flat == "on";
  g.tail_fraction = o.tail;
  return g;
}

std::string fmt_seconds(double s) {
  char buf[32];
  if (s < 60) snprintf(buf, sizeof buf, "%.1f s", s);
  else snprintf(buf, sizeof buf, "%dm%02ds", int(s) / 60, int(s) % 60);
  return buf;
}

void apply_switch(const std::string& v, bool& target) {
  if (v == "on") target = true;
  if (v == "off") target = false;
}

int run_render(const RenderOptions& o) {
  using clock = std::chrono::steady_clock;
  const auto t_start = clock::now();
  tracer::Scene scene;
  if (!load_scene_or_report(o.scene, &scene)) return kExitInputError;
  for (const auto& w : scene.diagnostics.warnings) std::cerr << "warning: " << w << "\n";

  tracer::RenderSettings rs = scene.settings;
  if (o.width > 0) rs.width = o.width;
  if (o.height > 0) rs.height = o.height;
  if (o.spp > 0) rs.spp = o.spp;
  if (o.time > 0) rs.time_limit_s = o.time;
  if (o.max_depth > 0) rs.max_depth = o.max_depth;
  if (o.rr_start > 0) rs.rr_start_depth = o.rr_start;
  if (o.seed >= 0) rs.seed = uint32_t(o.seed);
  apply_switch(o.nee, rs.nee);
  apply_switch(o.mis, rs.mis);
  apply_switch(o.rr, rs.russian_roulette);
  apply_switch(o.jitter, rs.jitter);
  if (o.clamp >= 0.0f) rs.clamp = o.clamp;
  if (!o.sampler.empty()) tracer::parse_sampler(o.sampler, &rs.sampler);
  scene.settings = rs;
  try {
    tracer::validate_scene(scene);  // the command line may have made the image too large
  } catch (const tracer::InputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  {  // Refuse an output the writer cannot produce before spending the render on it.
    const std::string ext = o.out.size() > 4 ? o.out.substr(o.out.size() - 4) : "";
    std::string lower = ext;
    for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (lower != ".png" && lower != ".exr") {
      std::cerr << "error: " << o.out << ": unsupported image format (use .png or .exr); "
                << "nothing was rendered\n";
      return kExitUsage;
    }
  }
  tracer::ToneMap op;
  if (!tracer::parse_tone_map(o.tonemap, &op)) {
    std::cerr << "error: --tonemap " << o.tonemap << ": expected none, reinhard or aces\n";
    return kExitUsage;
  }

  const tracer::BackendChoice choice = o.backend == "cpu"    ? tracer::BackendChoice::kCpu
                                       : o.backend == "cuda" ? tracer::BackendChoice::kCuda
                                                             : tracer::BackendChoice::kAuto;
  std::unique_ptr<tracer::Renderer> renderer;
  std::string note;
  try {
    renderer = tracer::make_renderer(choice, o.threads, &note);
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  if (!note.empty() && !o.quiet) std::cerr << "note: " << note << "\n";

  const tracer::CompiledScene compiled(scene, rs.width, rs.height);
  const tracer::IntegratorSettings cfg = tracer::make_integrator_settings(rs);
  renderer->set_gpu_options(gpu_options(o));
  renderer->set_scene(compiled, cfg);
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
  std::string last_note, last_kernel, last_spec;
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
    last_kernel = fs.kernel;
    last_spec = fs.specialization;
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
  std::string clamp_report;
  const uint64_t nonfinite = renderer->nonfinite_total();
  const tracer::ImageRGB img = renderer->image();
  try {
    tracer::write_image(o.out, img, o.exposure, op);
    nlohmann::json j;
    j["scene"] = o.scene.empty() ? "<built-in>" : o.scene;
    j["output"] = o.out;
    j["version"] = TRACER_VERSION;
    j["backend"] = renderer->backend_name();
    j["device"] = renderer->device_name();
    j["settings"] = {{"width", rs.width},         {"height", rs.height},
                     {"spp", rs.spp},             {"time_limit_s", rs.time_limit_s},
                     {"max_depth", rs.max_depth}, {"nee", rs.nee},
                     {"mis", rs.mis},             {"russian_roulette", rs.russian_roulette},
                     {"rr_start_depth", rs.rr_start_depth}, {"seed", rs.seed},
                     {"exposure", o.exposure},    {"tonemap", tracer::tone_map_name(op)},
                     {"jitter", rs.jitter}};
    j["settings"]["sampler"] = tracer::sampler_name(rs.sampler);
    if (renderer->backend_name() == "cuda") {
      j["gpu"] = {{"kernel_option", o.kernel}, {"kernel", last_kernel},
                  {"specialization", last_spec}, {"compaction", o.compaction},
                  {"sort", o.sort}, {"first_bounce_cache", o.cache}, {"flat", o.flat},
                  {"note", last_note}};
    }
    j["spp"] = spp_done;
    j["wall_time_s"] = render_s;
    j["setup_time_s"] = setup_s;
    j["rays"] = {{"camera", rays.camera}, {"extension", rays.extension}, {"shadow", rays.shadow}};
    j["mrays_per_s"] = double(rays.camera + rays.extension + rays.shadow) / render_s / 1e6;
    j["nonfinite_samples"] = nonfinite;
    j["random_walks_capped"] = rays.walk_capped;
    if (rs.clamp > 0.0f) {
      // The bias the clamp introduced: the share of the image's luminance it removed.
      double kept = 0.0;
      for (size_t i = 0; i < img.pixels.size(); i += 3)
        kept += tracer::luminance(tracer::vec3(img.pixels[i], img.pixels[i + 1], img.pixels[i + 2]));
      kept *= double(spp_done);
      j["clamp"] = {{"value", rs.clamp},
                    {"samples_clamped", clamped},
                    {"luminance_removed_fraction",
                     clamped_luminance / std::max(1e-30, kept + clamped_luminance)}};
      clamp_report = "clamp " + std::to_string(rs.clamp) + ": " + std::to_string(clamped) +
                     " samples scaled down, removing " +
                     std::to_string(100.0 * clamped_luminance /
                                    std::max(1e-30, kept + clamped_luminance)) +
                     "% of the image's luminance (bias)";
    }
    j["medium_leaks"] = rays.medium_leaks;
    j["features"] = tracer::describe_features(compiled.features());
    j["warnings"] = scene.diagnostics.warnings;
    const std::string cmd_seed = std::to_string(rs.seed);
    tracer::write_text_atomic(o.out + ".json", j.dump(2) + "\n");
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  if (!o.quiet) {
    std::cerr << "wrote " << o.out << " (" << rs.width << "x" << rs.height << ", " << spp_done
              << " spp, " << fmt_seconds(render_s) << ", " << renderer->backend_name() << ")";
    if (nonfinite) std::cerr << "; " << nonfinite << " NaN/Inf samples rejected";
    std::cerr << "\n";
    if (!clamp_report.empty()) std::cerr << "note: " << clamp_report << "\n";
    if (rays.walk_capped)
      std::cerr << "warning: " << rays.walk_capped << " subsurface random walks stopped at "
                << tracer::kMaxWalkSteps << " steps (their paths end there: energy is lost)\n";
    if (rays.medium_leaks)
      std::cerr << "warning: " << rays.medium_leaks << " paths left a subsurface medium without "
                << "crossing its boundary: a mesh with subsurface material is not closed\n";
  }
  return 0;
}

}  // namespace

Runner add_render_command(CLI::App& cmd) {
  auto o = std::make_shared<RenderOptions>();
  cmd.add_option("scene", o->scene, "Scene file (.json, .obj, .gltf, .glb); default: built-in Cornell box")
      ->check(CLI::ExistingFile);
  auto* spp = cmd.add_option("--spp", o->spp, "Samples per pixel")->check(CLI::Range(1, 1 << 24));
  auto* time = cmd.add_option("--time", o->time, "Render for this many seconds instead of --spp")
                   ->check(CLI::Range(1e-3, 1e7));
  spp->excludes(time);
  cmd.add_option("--width", o->width, "Image width in pixels")->check(CLI::Range(1, 16384));
  cmd.add_option("--height", o->height, "Image height in pixels")->check(CLI::Range(1, 16384));
  cmd.add_option("--max-depth", o->max_depth, "Maximum path segments (camera ray included)")
      ->check(CLI::Range(1, 1024));
  cmd.add_option("--backend", o->backend, "auto, cpu or cuda")
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  cmd.add_option("--seed", o->seed, "Random seed")->check(CLI::Range(0LL, 4294967295LL));
  cmd.add_option("--out", o->out, "Output file: .png (tone-mapped sRGB) or .exr (linear float)")
      ->capture_default_str();
  cmd.add_option("--threads", o->threads, "CPU threads (0: all cores)")->check(CLI::Range(0, 1024));
  cmd.add_option("--nee", o->nee, "Next-event estimation: on or off")->check(CLI::IsMember({"on", "off"}));
  cmd.add_option("--mis", o->mis, "Multiple importance sampling: on or off")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option("--rr", o->rr, "Russian roulette: on or off")->check(CLI::IsMember({"on", "off"}));
  cmd.add_option("--rr-start", o->rr_start, "Path depth at which Russian roulette starts")
      ->check(CLI::Range(1, 1024));
  cmd.add_option("--exposure", o->exposure, "Exposure in stops for the PNG")
      ->check(CLI::Range(-20.0, 20.0));
  cmd.add_option("--tonemap", o->tonemap, "PNG tone mapping: none, reinhard or aces")
      ->check(CLI::IsMember({"none", "reinhard", "aces"}));
  cmd.add_option("--clamp", o->clamp,
                 "Clamp each sample's radiance to this per channel (0: off); reports the bias")
      ->check(CLI::Range(0.0, 1e30));
  cmd.add_option("--jitter", o->jitter, "Jitter samples inside pixels: on or off")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option("--sampler", o->sampler,
                 "Sample points: sobol (Owen-scrambled Sobol, stratified), sobol-pairs (two "
                 "independent Sobol halves: exact half-buffer noise) or random (PCG32)")
      ->check(CLI::IsMember({"random", "sobol", "sobol-pairs"}));
  cmd.add_flag("--quiet,-q", o->quiet, "No progress or summary on stderr");
  const char* gpu = "GPU (CUDA backend)";
  cmd.add_option("--kernel", o->kernel, "auto (time both, keep the faster), wavefront or megakernel")
      ->check(CLI::IsMember({"auto", "wavefront", "megakernel"}))->group(gpu)->capture_default_str();
  cmd.add_option("--compaction", o->compaction,
                 "Compact live path indices after each bounce: shade (the shade kernel appends "
                 "the paths that go on to the next bounce's queue, and the shadow rays to the "
                 "shadow stage's), cub (a CUB select over the alive flags after each bounce), on "
                 "or auto (shade, but cub for textured scenes) or off")
      ->check(CLI::IsMember({"on", "auto", "shade", "cub", "off"}))
      ->group(gpu)
      ->capture_default_str();
  cmd.add_option("--sort", o->sort, "Sort paths by material before shading")
      ->check(CLI::IsMember({"on", "off"}))->group(gpu)->capture_default_str();
  cmd.add_option("--cache", o->cache, "First-bounce cache (needs --jitter off and no depth of field)")
      ->check(CLI::IsMember({"on", "off"}))->group(gpu)->capture_default_str();
  cmd.add_option("--flat", o->flat,
                 "Scenes of at most 64 primitives (quads count once, spheres twice): every lane "
                 "tests every primitive in one uniform loop instead of walking the BVH")
      ->check(CLI::IsMember({"on", "off"}))->group(gpu)->capture_default_str();
  cmd.add_option("--tail", o->tail,
                 "Wavefront with compaction: once fewer than this fraction of the pixels' paths "
                 "remain, one megakernel launch runs their remaining bounces (0: off)")
      ->check(CLI::Range(0.0f, 1.0f))->group(gpu)->capture_default_str();
  return [o] { return run_render(*o); };
}

}  // namespace app
