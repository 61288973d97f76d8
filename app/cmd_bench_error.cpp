// `pathtracer bench --error`: renders (or loads) a reference with its per-pixel variance, then
// sweeps each configuration over doubling sample counts and measures relMSE, RMSE and LDR-FLIP
// against wall-clock time; prints a table, writes CSVs and log-log plots (SVG).
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <future>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "backends/backend_select.h"
#include "bench_error.h"
#include "commands.h"
#include "settings_cli.h"
#include "core/diagnostics.h"
#include "cpu/cpu_backend.h"
#include "image/convergence.h"
#include "image/denoise.h"
#include "image/flip.h"
#include "image/image.h"
#include "image/svg_plot.h"
#include "integrator/sidecar.h"
#include "scene/compiled_scene.h"
#include "scene/loader.h"

namespace app {
namespace {

using Clock = std::chrono::steady_clock;
// The reference's samples are seeded apart from every configuration's, so that they are
// independent estimates (the same seed would trace the same first paths).
constexpr uint32_t kReferenceSeedOffset = 0x5EED0001u;

// One configuration of the sweep: a backend (and GPU kernel) plus modifiers, each a setting of
// the settings table as --set spells it without its section, e.g. "megakernel+rr=off",
// "cpu+max_depth=4", "wavefront+compaction=off".
struct Config {
  std::string name;
  bool cpu = false;
  tracer::GpuOptions gpu;
  bool nee = true, mis = true, rr = true, schlick = false;
  int max_depth = 0;  // 0: the bench's
  float clamp = 0;
  int sampler = -1;         // tracer::kSamplerRandom or kSamplerSobol; < 0: the scene's
  int light_sampler = -1;   // tracer::kLightSampler*; < 0: the scene's
  int guiding = -1;         // path guiding 0/1; < 0: the scene's
  int mnee = -1;            // manifold NEE 0/1; < 0: the scene's
  int light_tracing = -1;   // light tracing of caustics 0/1; < 0: the scene's
  bool scalar_bvh = false;  // CPU: the shared scalar traversal instead of the SSE one
  bool cpu_flat = false;    // CPU: the flat primitive list of small scenes (as the GPU)
  // Each checkpoint's image denoised (image/denoise.h, guided by the albedo and normal AOVs);
  // its time includes the AOVs and the denoise. Biased by construction.
  bool denoise = false;
};

const std::vector<std::string> kBases = {"cpu", "megakernel", "wavefront", "auto"};
// Modifiers that are no setting of the settings table.
const std::vector<std::string> kOwnModifiers = {"schlick", "scalar-bvh", "denoise"};

// The settings a configuration may change: those of the table that shape the estimate or the GPU
// design (not the image size, the stop condition, the seed or the backend, which the bench
// fixes). Named by key ("render.nee"), name ("nee") or flag ("rr").
const tracer::Setting* modifier_setting(const std::string& name) {
  static const std::vector<std::string> kKeys = {
      "render.nee",   "render.mis",     "render.russian_roulette", "render.max_depth",
      "render.clamp", "render.sampler", "render.light_sampler",    "render.guiding",
      "render.mnee",  "render.light_tracing",
      "gpu.compaction",
      "gpu.sort",     "gpu.cache",      "gpu.flat",                "gpu.tail"};
  for (const std::string& key : kKeys) {
    const tracer::Setting& s = *tracer::find_setting(key);
    if (name == s.key || name == s.name() || (!s.flag.empty() && "--" + name == s.flag)) return &s;
  }
  return nullptr;
}

std::string modifier_list() {
  std::string out;
  for (const tracer::Setting& s : tracer::settings_table())
    if (modifier_setting(s.key) == &s)
      out += (out.empty() ? "" : ", ") + s.name() + "=" + tracer::setting_values_text(s);
  return out + ", schlick, scalar-bvh (cpu), denoise";
}

// Throws std::invalid_argument with a message naming the bad token.
Config parse_config(const std::string& text) {
  Config c;
  c.name = text;
  std::vector<std::string> tokens;
  std::stringstream ss(text);
  for (std::string t; std::getline(ss, t, '+');) tokens.push_back(t);
  if (tokens.empty() || tokens[0].empty()) throw std::invalid_argument("empty configuration");
  const std::string& base = tokens[0];
  using K = tracer::KernelMode;
  if (base == "cpu")
    c.cpu = true;
  else if (base == "megakernel")
    c.gpu.kernel = K::kMegakernel;
  else if (base == "wavefront")
    c.gpu.kernel = K::kWavefront;
  else if (base == "auto")
    c.gpu.kernel = K::kAuto;
  else {
    const std::string guess = tracer::did_you_mean(base, kBases);
    throw std::invalid_argument("configuration \"" + text +
                                "\" must start with cpu, megakernel, "
                                "wavefront or auto, not \"" +
                                base + "\"" +
                                (guess.empty() ? "" : " (did you mean \"" + guess + "\"?)"));
  }
  c.gpu.first_bounce_cache = false;  // jitter stays on: the cache would never apply
  // The settings' modifiers are applied through the table (its checks and messages) to a scene
  // that holds the configuration's settings; what they change is copied out below.
  tracer::Scene tmpl;
  tmpl.gpu = c.gpu;
  std::vector<std::string> changed;
  for (size_t i = 1; i < tokens.size(); ++i) {
    const std::string& m = tokens[i];
    const size_t eq = m.find('=');
    if (m == "schlick") {
      c.schlick = true;
    } else if (m == "denoise") {
      c.denoise = true;
    } else if (m == "scalar-bvh") {
      if (!c.cpu)
        throw std::invalid_argument("\"scalar-bvh\" in \"" + text +
                                    "\" applies to cpu configurations only (the GPU always "
                                    "traverses the shared layout)");
      c.scalar_bvh = true;
    } else if (eq != std::string::npos && modifier_setting(m.substr(0, eq))) {
      const tracer::Setting& s = *modifier_setting(m.substr(0, eq));
      const std::string problem = tracer::set_setting_assignment(tmpl, s.key + m.substr(eq));
      if (!problem.empty())
        throw std::invalid_argument("\"" + m + "\" in \"" + text + "\": " + problem);
      changed.push_back(s.key);
    } else {
      std::vector<std::string> names = kOwnModifiers;
      for (const tracer::Setting& s : tracer::settings_table())
        if (modifier_setting(s.key) == &s) names.push_back(s.name());
      const std::string guess = tracer::did_you_mean(m.substr(0, eq), names);
      throw std::invalid_argument("unknown modifier \"" + m + "\" in \"" + text + "\"" +
                                  (guess.empty() ? "" : " (did you mean \"" + guess + "\"?)") +
                                  "; modifiers: " + modifier_list());
    }
  }
  const tracer::RenderSettings& rs = tmpl.settings;
  for (const std::string& key : changed) {
    if (key == "render.nee") c.nee = rs.nee;
    else if (key == "render.mis") c.mis = rs.mis;
    else if (key == "render.russian_roulette") c.rr = rs.russian_roulette;
    else if (key == "render.max_depth") c.max_depth = rs.max_depth;
    else if (key == "render.clamp") c.clamp = rs.clamp;
    else if (key == "render.sampler") c.sampler = int(rs.sampler);
    else if (key == "render.light_sampler") c.light_sampler = int(rs.light_sampler);
    else if (key == "render.guiding") c.guiding = rs.guiding ? 1 : 0;
    else if (key == "render.mnee") c.mnee = rs.mnee ? 1 : 0;
    else if (key == "render.light_tracing") c.light_tracing = rs.light_tracing ? 1 : 0;
    else if (key == "gpu.flat" && c.cpu) c.cpu_flat = tmpl.gpu.flat_list;  // the CPU's list
    else if (key.rfind("gpu.", 0) == 0) c.gpu = tmpl.gpu;
    else
      throw std::invalid_argument("\"" + key + "\" in \"" + text +
                                  "\" is no setting a configuration can change");
  }
  return c;
}

std::string default_suite(bool gpu) {
  if (gpu)
    return "megakernel,wavefront,wavefront+compaction=off,wavefront+sort=on,"
           "megakernel+rr=off,megakernel+nee=off,megakernel+mis=off,megakernel+schlick,"
           "megakernel+max_depth=4,megakernel+clamp=10,megakernel+sampler=random,"
           "megakernel+sampler=sobol-pairs,cpu";
  return "cpu,cpu+scalar-bvh,cpu+sampler=random,cpu+sampler=sobol-pairs,cpu+rr=off,"
         "cpu+nee=off,cpu+mis=off,cpu+schlick,cpu+max_depth=4,cpu+clamp=10";
}

struct Sweep {
  Config config;
  std::vector<tracer::Checkpoint> points;
  tracer::ConvergenceSummary summary;
  std::string kernel, specialization, device;
  uint64_t nonfinite = 0;
  double to_flip05 = -1;  // seconds to the first checkpoint of mean FLIP <= 0.05 (-1: never)
  std::string denoiser;   // what denoised it (denoise configurations)
  std::string guide;      // path guiding's status at the end (GuideStatus::describe; "" off)
};

// Pending FLIP jobs, oldest first: (checkpoint index, mean FLIP).
using FlipJobs = std::deque<std::future<std::pair<size_t, double>>>;

// Waits for pending FLIP jobs, oldest first, until at most `keep` remain.
void collect_flips(FlipJobs& jobs, Sweep& sw, size_t keep) {
  while (jobs.size() > keep) {
    const auto [index, value] = jobs.front().get();
    sw.points[index].flip = value;
    jobs.pop_front();
  }
}

// Loads the reference (and its variance image when present) or renders it with `r`.
// `settings` (what a reference must match) is kept in its sidecar as "reference_settings".
bool obtain_reference(const std::string& path, int spp, const tracer::Scene& scene,
                      const tracer::CompiledScene& cs, tracer::IntegratorSettings cfg,
                      tracer::Renderer& r, const nlohmann::json& settings,
                      tracer::ReferenceImage* ref) {
  const std::string var_path = tracer::variance_path_for(path);
  if (std::filesystem::exists(path)) {
    ref->mean = tracer::read_image(path);
    if (ref->mean.width != int(cfg.width) || ref->mean.height != int(cfg.height)) {
      std::cerr << "error: " << path << ": the reference is " << ref->mean.width << "x"
                << ref->mean.height << " but the bench renders " << cfg.width << "x" << cfg.height
                << "; pass another --reference or delete it to re-render\n";
      return false;
    }
    std::ifstream side(path + ".json");
    if (side) {
      const nlohmann::json j = nlohmann::json::parse(side, nullptr, false);
      // "reference_settings"; "settings" in sidecars of older versions.
      const char* key = j.contains("reference_settings") ? "reference_settings" : "settings";
      if (!j.is_discarded() && j.contains(key) && j[key] != settings) {
        std::cerr << "warning: " << path << ".json: the reference was rendered with settings "
                  << j[key].dump() << ", the bench uses " << settings.dump()
                  << "; errors include that difference\n";
      }
    }
    if (std::filesystem::exists(var_path)) {
      ref->variance = tracer::read_image(var_path);
      if (ref->variance.width != ref->mean.width || ref->variance.height != ref->mean.height) {
        std::cerr << "error: " << var_path << ": size differs from " << path << "\n";
        return false;
      }
    } else {
      std::cerr << "warning: " << var_path << " is missing: the reference's own noise is not "
                << "subtracted from the errors\n";
    }
    std::printf("reference: %s (loaded)\n", path.c_str());
    return true;
  }
  cfg.seed += kReferenceSeedOffset;
  // The variance image comes from the even/odd halves, which are independent only with the
  // paired Sobol sampler (core/sobol.h); the single sequence would overstate the reference's
  // noise. Both converge to the same mean.
  if (cfg.sampler == tracer::kSamplerSobol) cfg.sampler = tracer::kSamplerSobolPairs;
  r.set_scene(cs, cfg);
  const auto t0 = Clock::now();
  const uint32_t chunk = r.backend_name() == "cpu" ? 4u : 256u;
  uint64_t nonfinite = 0;
  while (r.samples_done() < uint32_t(spp)) {
    const uint32_t n = std::min<uint32_t>(chunk, uint32_t(spp) - r.samples_done());
    nonfinite += r.render(n).nonfinite;
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    if (isatty(2))
      std::fprintf(stderr, "\rreference: %u / %d spp, %.1f s, ETA %.0f s   ", r.samples_done(), spp,
                   s, s / r.samples_done() * (spp - r.samples_done()));
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  if (isatty(2)) std::fprintf(stderr, "\n");
  ref->mean = r.image();
  tracer::ImageRGB even, odd;
  r.half_images(&even, &odd);
  ref->variance = tracer::variance_from_halves(even, odd);
  // Variance first, mean last: a crash in between leaves no mean, which is re-rendered, rather
  // than a mean beside a stale variance image.
  tracer::write_image(var_path, ref->variance);
  tracer::write_image(path, ref->mean);
  // The one sidecar (integrator/sidecar.h), with the reference's own seed and sampler.
  tracer::Scene as_rendered;
  as_rendered.source = scene.source;
  as_rendered.camera = scene.camera;
  as_rendered.settings = scene.settings;
  as_rendered.settings.seed = cfg.seed;
  as_rendered.settings.sampler = cfg.sampler;
  as_rendered.settings.spp = spp;
  as_rendered.gpu = scene.gpu;
  as_rendered.display = scene.display;
  as_rendered.materials = scene.materials;
  as_rendered.diagnostics = scene.diagnostics;
  tracer::SidecarRun run;
  run.output = path;
  run.backend = r.backend_name();
  run.device = r.device_name();
  run.spp = uint32_t(spp);
  run.wall_time_s = seconds;
  run.nonfinite = nonfinite;
  run.features = tracer::describe_features(cs.features());
  nlohmann::json side = tracer::make_sidecar(as_rendered, run);
  side["reference_settings"] = settings;
  tracer::write_text_atomic(path + ".json", tracer::json_text(side));
  std::printf("reference: %s (%d spp on %s in %.1f s; variance in %s)\n", path.c_str(), spp,
              r.device_name().c_str(), seconds, var_path.c_str());
  return true;
}

Sweep run_sweep(const Config& c, tracer::Renderer& r, const tracer::CompiledScene& cs,
                tracer::IntegratorSettings cfg, const tracer::ReferenceImage& ref, int max_spp,
                double time_limit, bool flip) {
  Sweep sw;
  sw.config = c;
  cfg.nee = c.nee;
  cfg.mis = c.mis;
  cfg.russian_roulette = c.rr;
  if (c.max_depth > 0) cfg.max_depth = uint32_t(c.max_depth);
  cfg.clamp = c.clamp;
  if (c.sampler >= 0) cfg.sampler = uint32_t(c.sampler);
  if (c.light_sampler >= 0) cfg.light_sampler = uint32_t(c.light_sampler);
  if (c.guiding >= 0) cfg.guiding = uint32_t(c.guiding);
  if (c.mnee >= 0) cfg.mnee = uint32_t(c.mnee);
  if (c.light_tracing >= 0) cfg.light_tracing = uint32_t(c.light_tracing);
  r.set_gpu_options(c.gpu);
  r.set_scene(cs, cfg);
  r.set_aovs(c.denoise);
  r.render(c.gpu.kernel == tracer::KernelMode::kAuto ? 4 : 1);  // warm-up (and auto's timing)
  if (c.denoise) r.denoised_image();  // the denoiser's first call sets up its device and filter
  r.reset();
  sw.device = r.device_name();
  double seconds = 0;
  uint32_t done = 0;
  FlipJobs flips;
  for (uint32_t next = 1; next <= uint32_t(max_spp); next *= 2) {
    // Stop before a doubling that would overrun the budget (it costs about what was spent).
    if (done > 0 && seconds * (double(next) / done) > time_limit) break;
    const auto t0 = Clock::now();
    const tracer::FrameStats st = r.render(next - done);
    seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    done = next;
    sw.nonfinite += st.nonfinite;
    if (sw.kernel.empty()) {
      sw.kernel = st.kernel;
      sw.specialization = st.specialization;
    }
    tracer::Checkpoint cp;
    cp.spp = done;
    cp.seconds = seconds;
    tracer::ImageRGB img = r.image();
    if (c.denoise) {
      // What a user waits for: the resolves, the denoise and the image back in host memory, on
      // top of the samples (on the GPU the denoiser reads the renderer's device buffers).
      const auto t1 = Clock::now();
      tracer::DenoiseInfo info;
      img = r.denoised_image(&info);
      cp.seconds += std::chrono::duration<double>(Clock::now() - t1).count();
      sw.denoiser = info.denoiser + " (" + info.device + ", " + info.inputs + ")";
    }
    // The noise/bias split per pixel needs independent halves; with the single Sobol sequence
    // error_terms tests the bias on 8x8-block means instead (a lower bound, see convergence.h).
    if (done >= 2 && !c.denoise) {
      tracer::ImageRGB even, odd;
      r.half_images(&even, &odd);
      cp.error =
          tracer::error_terms(img, ref, &even, &odd, tracer::independent_halves(cfg.sampler));
    } else {
      cp.error = tracer::error_terms(img, ref);
    }
    sw.points.push_back(cp);
    if (flip) {
      // FLIP costs about a second at 1080p on one core: on the GPU it runs on other cores while
      // the next samples render; on the CPU backend it waits, so it never steals render time.
      const size_t index = sw.points.size() - 1;
      auto job = std::make_shared<tracer::ImageRGB>(img);
      flips.push_back(std::async(std::launch::async, [job, &ref, index] {
        return std::make_pair(index, tracer::ldr_flip(*job, ref.mean).mean);
      }));
      if (c.cpu || flips.size() >= 8) collect_flips(flips, sw, c.cpu ? 0 : 4);
    }
    if (isatty(2))
      std::fprintf(stderr, "\r%-32s %6u spp %8.3f s relMSE %.3e   ", c.name.c_str(), done, seconds,
                   cp.error.relmse);
  }
  const tracer::Checkpoint& last = sw.points.back();
  collect_flips(flips, sw, 0);
  std::fprintf(stderr, "%s%-32s %6u spp %8.3f s relMSE %.3e\n", isatty(2) ? "\r" : "",
               c.name.c_str(), last.spp, last.seconds, last.error.relmse);
  if (const tracer::GuideStatus g = r.guide_status(); g.on) {
    sw.guide = g.describe();
    std::fprintf(stderr, "  path guiding: %s\n", sw.guide.c_str());
  }
  sw.summary = tracer::summarize(sw.points);
  if (c.denoise) {  // a denoiser trades noise for bias whatever the slope says
    sw.summary.biased = true;
    sw.summary.verdict = "biased (denoised by " + sw.denoiser + ")";
  }
  for (const tracer::Checkpoint& p : sw.points) {
    if (p.flip >= 0 && p.flip <= 0.05) {
      sw.to_flip05 = p.seconds;
      break;
    }
  }
  return sw;
}

std::string fmt_time(const tracer::TimeToError& t) {
  if (t.seconds < 0) return "never";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%s%.3g", t.extrapolated ? "~" : "", t.seconds);
  return buf;
}

std::string csv_quote(const std::string& s) {
  return "\"" + s + "\"";
}

void write_outputs(const std::string& dir, const std::vector<Sweep>& sweeps,
                   const std::string& title, nlohmann::json meta) {
  std::filesystem::create_directories(dir);
  std::string pts =
      "config,spp,seconds,relmse,relmse_raw,reference_floor,rmse,flip,variance,"
      "bias2,bias2_stderr\n";
  std::string sum =
      "config,backend_kernel,specialization,final_spp,seconds,relmse,rmse,flip,"
      "time_to_1e-2_s,extrapolated_1e-2,time_to_1e-3_s,extrapolated_1e-3,"
      "efficiency,slope,slope_stderr,biased,nonfinite,time_to_flip_0.05_s,verdict\n";
  char buf[2048];
  nlohmann::json arr = nlohmann::json::array();
  tracer::PlotSpec relp, flipp;
  relp.title = title;
  relp.x_label = "render time (s)";
  relp.y_label = "relMSE against the reference";
  relp.y_marks = {{1e-2, "relMSE 1e-2"}, {1e-3, "relMSE 1e-3"}};
  flipp = relp;
  flipp.y_label = "mean LDR-FLIP";
  flipp.y_marks.clear();
  flipp.slope_guide = false;
  for (const Sweep& s : sweeps) {
    tracer::PlotSeries a{s.config.name, {}}, b{s.config.name, {}};
    for (const auto& p : s.points) {
      std::snprintf(buf, sizeof(buf), "%s,%u,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n",
                    csv_quote(s.config.name).c_str(), p.spp, p.seconds, p.error.relmse,
                    p.error.relmse_raw, p.error.reference_floor, p.error.rmse, p.flip,
                    p.error.variance, p.error.bias2, p.error.bias2_stderr);
      pts += buf;
      a.points.push_back({p.seconds, p.error.relmse});
      b.points.push_back({p.seconds, p.flip});
    }
    relp.series.push_back(a);
    flipp.series.push_back(b);
    const auto& last = s.points.back();
    const auto& m = s.summary;
    std::snprintf(
        buf, sizeof(buf), "%s,%s,%s,%u,%.6g,%.6g,%.6g,%.6g,%.6g,%d,%.6g,%d,%.6g,%.4f,%.4f,%d,%llu,",
        csv_quote(s.config.name).c_str(), s.kernel.c_str(), csv_quote(s.specialization).c_str(),
        last.spp, last.seconds, last.error.relmse, last.error.rmse, last.flip, m.to_1e2.seconds,
        int(m.to_1e2.extrapolated), m.to_1e3.seconds, int(m.to_1e3.extrapolated), m.efficiency,
        m.slope, m.slope_stderr, int(m.biased), static_cast<unsigned long long>(s.nonfinite));
    sum += buf;
    std::snprintf(buf, sizeof(buf), "%.6g,", s.to_flip05);
    sum += buf + csv_quote(m.verdict) + "\n";
    nlohmann::json cps = nlohmann::json::array();
    for (const auto& p : s.points)
      cps.push_back({{"spp", p.spp},
                     {"seconds", p.seconds},
                     {"relmse", p.error.relmse},
                     {"relmse_raw", p.error.relmse_raw},
                     {"rmse", p.error.rmse},
                     {"flip", p.flip},
                     {"variance", p.error.variance},
                     {"bias2", p.error.bias2},
                     {"bias2_stderr", p.error.bias2_stderr}});
    arr.push_back({{"config", s.config.name},
                   {"kernel", s.kernel},
                   {"specialization", s.specialization},
                   {"device", s.device},
                   {"time_to_1e-2_s", m.to_1e2.seconds},
                   {"time_to_1e-3_s", m.to_1e3.seconds},
                   {"extrapolated_1e-2", m.to_1e2.extrapolated},
                   {"extrapolated_1e-3", m.to_1e3.extrapolated},
                   {"efficiency", m.efficiency},
                   {"slope", m.slope},
                   {"slope_stderr", m.slope_stderr},
                   {"biased", m.biased},
                   {"verdict", m.verdict},
                   {"nonfinite", s.nonfinite},
                   {"time_to_flip_0.05_s", s.to_flip05},
                   {"guiding", s.guide},
                   {"checkpoints", cps}});
  }
  meta["configs"] = arr;
  tracer::write_text_atomic(dir + "/error_vs_time.csv", pts);
  tracer::write_text_atomic(dir + "/summary.csv", sum);
  tracer::write_text_atomic(dir + "/error_vs_time.svg", tracer::loglog_svg(relp));
  tracer::write_text_atomic(dir + "/flip_vs_time.svg", tracer::loglog_svg(flipp));
  tracer::write_text_atomic(dir + "/bench.json", tracer::json_text(meta));
}

}  // namespace

CLI::Option* add_error_bench_options(CLI::App& cmd, ErrorBenchOptions* o) {
  const std::string g = "Error against time (--error)";
  CLI::Option* flag =
      cmd.add_flag("--error", o->enabled,
                   "Measure error against time instead of speed: sweep each configuration over "
                   "doubling sample counts against a reference")
          ->group(g);
  cmd.add_option("--reference", o->reference,
                 "Reference EXR (with NAME.variance.exr beside it); rendered there when missing. "
                 "Default: OUT/reference-SCENE-WxH-dDEPTH.exr")
      ->group(g);
  cmd.add_option("--reference-spp", o->reference_spp,
                 "Samples for a new reference (default 32768 on the GPU, 1024 on the CPU)")
      ->check(CLI::Range(2, 1 << 24))
      ->group(g);
  cmd.add_option("--configs", o->configs,
                 "Comma-separated configurations: cpu|megakernel|wavefront|auto, each with "
                 "+modifiers: a setting as NAME=VALUE (nee, mis, rr, max_depth, clamp, sampler, "
                 "light_sampler, guiding, mnee, light_tracing, compaction, sort, cache, flat, tail: the settings "
                 "table's "
                 "names, values and checks; flat=on on cpu: the GPU's flat list of small scenes), schlick (every "
                 "dielectric with Schlick's Fresnel), scalar-bvh (CPU: the GPU's scalar "
                 "traversal instead of SSE), denoise (each checkpoint denoised by Open Image Denoise "
                 "with the albedo and normal AOVs; its time includes them; biased). Default: a "
                 "suite for the backends present")
      ->group(g);
  cmd.add_option("--max-spp", o->max_spp,
                 "Last sample count of each sweep (default 4096 GPU, "
                 "256 CPU); counts double from 1")
      ->check(CLI::Range(1, 1 << 24))
      ->group(g);
  cmd.add_option("--time-limit", o->time_limit, "Seconds of rendering per configuration")
      ->check(finite_number() & CLI::Range(0.001, 1e6))
      ->capture_default_str()
      ->group(g);
  cmd.add_option("--out", o->out_dir, "Directory for the CSVs, plots and JSON")
      ->capture_default_str()
      ->group(g);
  cmd.add_option("--flip", o->flip, "Compute mean LDR-FLIP at every checkpoint: on or off")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str()
      ->group(g);
  cmd.add_option("--threads", o->threads, "CPU backend threads (0: all cores)")
      ->check(CLI::Range(0, 1024))
      ->group(g);
  return flag;
}

int run_error_bench(const ErrorBenchScene& bs, const ErrorBenchOptions& o) {
  tracer::Scene scene;
  if (!load_scene_or_report(bs.scene, &scene)) return kExitInputError;
  for (const std::string& a : bs.sets) {
    const std::string problem = tracer::set_setting_assignment(scene, a);
    if (!problem.empty()) {
      std::cerr << "error: --set \"" << a << "\": " << problem << "\n";
      return kExitUsage;
    }
  }
  tracer::RenderSettings& rs = scene.settings;
  if (bs.width > 0) rs.width = bs.width;
  if (bs.height > 0) rs.height = bs.height;
  if (bs.max_depth > 0) rs.max_depth = bs.max_depth;
  try {
    tracer::validate_scene(scene);
  } catch (const tracer::InputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  // Renderers: the GPU when asked for and present, the CPU when a configuration needs it.
  std::unique_ptr<tracer::Renderer> gpu;
  std::string why = "--backend cpu";
  if (bs.backend != "cpu") gpu = tracer::make_cuda_renderer(&why);
  if (!gpu && bs.backend == "cuda") {
    std::cerr << "error: --backend cuda: " << why << "\n";
    return kExitInputError;
  }
  if (!gpu && bs.backend == "auto") {
    std::printf("no GPU (%s): CPU configurations only\n", why.c_str());
    std::fflush(stdout);
  }
  std::vector<Config> configs;
  try {
    std::stringstream ss(o.configs.empty() ? default_suite(gpu != nullptr) : o.configs);
    for (std::string t; std::getline(ss, t, ',');) {
      if (t.empty()) continue;
      configs.push_back(parse_config(t));
      if (!configs.back().cpu && !gpu)
        throw std::invalid_argument("configuration \"" + t + "\" needs the GPU: " + why);
      // A build variant's GPU rows carry its name (gpu_options.h), e.g. "wavefront [unfused]".
      if (!configs.back().cpu && tracer::gpu_build_variant() != "default")
        configs.back().name += " [" + tracer::gpu_build_variant() + "]";
    }
    if (configs.empty()) throw std::invalid_argument("--configs names no configuration");
  } catch (const std::invalid_argument& e) {
    std::cerr << "error: --configs: " << e.what() << "\n";
    return kExitUsage;
  }
  tracer::CpuRenderer cpu(o.threads);

  const tracer::CompiledScene cs(scene, rs.width, rs.height);
  std::unique_ptr<tracer::CompiledScene> cs_schlick;  // every boundary with Schlick's Fresnel
  const tracer::IntegratorSettings cfg = tracer::make_integrator_settings(rs);
  const std::string stem =
      bs.scene.empty() ? "cornell_box" : std::filesystem::path(bs.scene).stem().string();
  const nlohmann::json settings = {{"scene", bs.scene.empty() ? "<built-in>" : bs.scene},
                                   {"width", rs.width},
                                   {"height", rs.height},
                                   {"max_depth", rs.max_depth},
                                   {"nee", rs.nee},
                                   {"mis", rs.mis},
                                   {"russian_roulette", rs.russian_roulette},
                                   {"clamp", rs.clamp}};
  const std::string ref_path =
      !o.reference.empty()
          ? o.reference
          : o.out_dir + "/reference-" + stem + "-" + std::to_string(rs.width) + "x" +
                std::to_string(rs.height) + "-d" + std::to_string(rs.max_depth) + ".exr";
  std::printf("scene %s: %dx%d, max depth %d; features: %s\n",
              settings["scene"].get<std::string>().c_str(), rs.width, rs.height, rs.max_depth,
              tracer::describe_features(cs.features()).c_str());
  if (gpu) std::printf("GPU build variant: %s\n", tracer::gpu_build_variant().c_str());
  std::string ext = std::filesystem::path(ref_path).extension().string();
  for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  if (ext != ".exr") {
    std::cerr << "error: --reference " << ref_path << ": a reference must be an .exr file (linear "
              << "float); 8-bit images cannot hold one\n";
    return kExitUsage;
  }
  // Fail on an unwritable --out now, not after minutes of rendering.
  try {
    tracer::write_text_atomic(o.out_dir + "/.bench-write-check", "");
    std::filesystem::remove(o.out_dir + "/.bench-write-check");
  } catch (const std::exception& e) {
    std::cerr << "error: --out " << o.out_dir << ": " << e.what() << "\n";
    return kExitInputError;
  }
  tracer::ReferenceImage ref;
  try {
    tracer::Renderer& rr = gpu ? *gpu : static_cast<tracer::Renderer&>(cpu);
    if (gpu) gpu->set_gpu_options(tracer::GpuOptions{});
    const int ref_spp = o.reference_spp > 0 ? o.reference_spp : (gpu ? 32768 : 1024);
    if (!obtain_reference(ref_path, ref_spp, scene, cs, cfg, rr, settings, &ref))
      return kExitInputError;
  } catch (const std::exception& e) {  // bad files, and GPU failures while rendering it
    std::cerr << "error: reference " << ref_path << ": " << e.what() << "\n";
    return kExitInputError;
  }
  const tracer::ErrorTerms floor_terms = tracer::error_terms(ref.mean, ref);
  std::printf("reference noise floor: relMSE %.2e (subtracted from every figure below)\n",
              floor_terms.reference_floor);
  std::fflush(stdout);

  std::vector<Sweep> sweeps;
  bool failed = false;
  for (const Config& c : configs) {
    const tracer::CompiledScene* scs = &cs;
    if (c.schlick) {
      if (!cs_schlick) {
        tracer::Scene s2 = scene;
        for (auto& m : s2.materials)
          if (m.material.type == tracer::MaterialType::kDielectric ||
              m.material.type == tracer::MaterialType::kSubsurface)
            m.material.flags |= tracer::kMaterialSchlickFresnel;
        cs_schlick = std::make_unique<tracer::CompiledScene>(s2, rs.width, rs.height);
      }
      scs = cs_schlick.get();
    }
    const int max_spp = o.max_spp > 0 ? o.max_spp : (c.cpu ? 256 : 4096);
    cpu.set_simd_traversal(!c.scalar_bvh);
    cpu.set_flat_list(c.cpu_flat);
    tracer::Renderer& r = c.cpu ? static_cast<tracer::Renderer&>(cpu) : *gpu;
    const uint32_t sampler = c.sampler >= 0 ? uint32_t(c.sampler) : cfg.sampler;
    const std::string warn =
        tracer::reference_independence_warning(ref_path, cfg.seed, tracer::sampler_name(sampler));
    if (!warn.empty()) std::cerr << "warning: " << c.name << ": " << warn << "\n";
    try {
      sweeps.push_back(run_sweep(c, r, *scs, cfg, ref, max_spp, o.time_limit, o.flip == "on"));
    } catch (const std::exception& e) {  // e.g. a CUDA error: report it, keep the other sweeps
      std::cerr << "error: " << c.name << ": " << e.what() << "; this configuration is skipped\n";
      failed = true;
    }
  }
  if (sweeps.empty()) return kExitInputError;

  // The table.
  std::printf("\n%-30s %7s %8s %10s %9s %7s %9s %9s %9s %9s %7s  %s\n", "configuration",
              "spp", "time s", "relMSE", "RMSE", "FLIP", "t(1e-2)", "t(1e-3)", "t(F.05)", "1/(e*t)",
              "slope", "verdict");
  const Sweep* fastest3 = nullptr;
  for (const Sweep& s : sweeps) {
    const auto& p = s.points.back();
    const auto& m = s.summary;
    char flip[16] = "      -";  // not computed (--flip off)
    if (p.flip >= 0) std::snprintf(flip, sizeof(flip), "%7.4f", p.flip);
    char flip05[16] = "never";
    if (s.to_flip05 >= 0) std::snprintf(flip05, sizeof(flip05), "%.3g", s.to_flip05);
    std::printf("%-30s %7u %8.3f %10.3e %9.3e %s %9s %9s %9s %9.3g %7.2f  %s\n",
                s.config.name.c_str(), p.spp, p.seconds, p.error.relmse, p.error.rmse, flip,
                fmt_time(m.to_1e2).c_str(), fmt_time(m.to_1e3).c_str(), flip05, m.efficiency,
                m.slope, m.verdict.c_str());
    if (s.nonfinite)
      std::printf("%-30s   %llu NaN/Inf samples rejected\n", "",
                  static_cast<unsigned long long>(s.nonfinite));
    if (!m.biased && m.to_1e3.seconds >= 0 &&
        (!fastest3 || m.to_1e3.seconds < fastest3->summary.to_1e3.seconds))
      fastest3 = &s;
  }
  std::printf(
      "times: s of rendering to reach the relMSE (~: extrapolated as error ~ 1/time); "
      "relMSE excludes the reference's own noise; t(F.05): s to the first checkpoint of mean "
      "FLIP <= 0.05 (denoised configurations: the AOVs and the denoise included).\n");
  if (fastest3)
    std::printf("fastest unbiased configuration to relMSE 1e-3: %s, %s s\n",
                fastest3->config.name.c_str(), fmt_time(fastest3->summary.to_1e3).c_str());

  nlohmann::json meta = {{"settings", settings},
                         {"reference", ref_path},
                         {"reference_floor_relmse", floor_terms.reference_floor},
                         {"time_limit_s", o.time_limit}};
  if (gpu) meta["gpu"] = gpu->device_name();
  if (gpu) meta["gpu_build_variant"] = tracer::gpu_build_variant();
  meta["cpu"] = cpu.device_name();
  try {
    write_outputs(o.out_dir, sweeps,
                  "relMSE against time: " + stem + ", " + std::to_string(rs.width) + "x" +
                      std::to_string(rs.height) + ", depth " + std::to_string(rs.max_depth),
                  meta);
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  std::printf(
      "wrote %s/{error_vs_time.csv, summary.csv, error_vs_time.svg, flip_vs_time.svg, "
      "bench.json}\n",
      o.out_dir.c_str());
  return failed ? kExitInputError : 0;
}

}  // namespace app
