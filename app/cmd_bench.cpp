// `pathtracer bench`: speed figures measured side by side in one run. On the GPU it times the
// megakernel and the wavefront with each switch (compaction in the shade kernel or by CUB, the
// tail, material sorting, first-bounce cache, the flat list), with per-stage times (also per
// bounce), paths alive per bounce, bytes moved per segment and the achieved bandwidth against the
// device's measured copy bandwidth; it also times the CPU backend on the same scene so the
// CPU/GPU ratio comes from one run. The engineering baselines (no dynamic fetch, general kernels,
// rays at ids, unfused stages) are build variants (gpu_options.h): a variant build labels its
// rows with its name.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "backends/backend_select.h"
#include "bench_error.h"
#include "commands.h"
#include "settings_cli.h"
#include "cpu/cpu_backend.h"
#include "image/image.h"
#include "scene/compiled_scene.h"
#include "scene/loader.h"

namespace app {
namespace {

struct BenchOptions {
  std::string scene;
  int width = 0, height = 0, max_depth = 0;  // 0: 1920x1080 depth 8 (speed), the scene's (--error)
  int spp = 16, cpu_spp = 1;
  std::string backend = "auto";
  std::string json_out;
  bool jitter_off_configs = true;
  SettingArgs settings;  // --nee, --tail and --set (settings table), applied after the defaults
  ErrorBenchOptions error;
};

struct Config {
  std::string name;
  tracer::GpuOptions gpu;
  bool jitter = true;
};

struct Result {
  std::string name, kernel, specialization, note;
  tracer::GpuOptions requested;  // the row's settings
  bool compacted = false;        // its wavefront compacted the live paths (effective options)
  std::string gpu_options;  // EffectiveGpuOptions::describe() (GPU only)
  // ms_per_spp: one call of `spp` samples, back to back as a progressive render runs them;
  // ms_per_frame: the median of one-sample calls, each waited for (what one display update of
  // the workbench costs, the host's synchronisation included).
  double ms_per_spp = 0, ms_per_frame = 0, segments_per_s = 0, rays_per_s = 0;
  // Wavefront rows: Mrays/s of the stages that trace one kind of ray alone (camera rays, bounce
  // rays, shadow rays; those a stage did not trace alone are absent).
  nlohmann::json ray_rates = nlohmann::json::object();
  tracer::RayCounts rays;  // per sample
  tracer::StageTimes stages;
  std::vector<uint32_t> alive;
  std::vector<uint32_t> shadows;  // shadow rays per bounce (queued by the shade kernel), or empty
  std::vector<uint32_t> finished;  // paths that ended without one, per bounce (the same)
  std::vector<uint32_t> mnee;      // manifold NEE's requests per bounce (render.mnee), or empty
};

// Bytes each wavefront stage reads and writes per path it processes (see the wavefront kernels' layout);
// scene data (BVH, triangles, materials) is left out: it is small and mostly cache-resident.
// A queued stage reads its 4-byte slot and no alive flag (a queue holds live paths only); the
// pass over every path reads the 1-byte flag of each, live or not (counted apart, per slot).
// With the shadow queue (compaction in the shade kernel) the shade kernel writes a shadow ray
// only where there is one, with its 4-byte slot in the shadow queue, and the shadow stage reads
// only those: shade_path() per path plus shade_ray() per shadow ray, shadow() per shadow ray.
// The shadow stage's last lanes then finish the paths that ended without a shadow ray: finish()
// each. Film sums (16 bytes per finished path) are counted there only.
// With rays at their queue slots the intersect stage reads no queue slot (its ray's index is
// the slot itself).
struct StageBytes {
  StageBytes(bool queued, bool at_slots) : slot(queued ? 4 : 1), at_slots(at_slots) {}
  double slot;
  bool at_slots;
  double generate = 65;                      // 4 float4 of state + the alive flag, written
  // ray origin + direction in, hit out
  double intersect() const { return 48 + (at_slots ? 0 : slot); }
  double sort = 45;
  // 5 float4 in, 4 float4 of state + 3 of shadow ray out, the alive flag out; with compaction
  // in the shade kernel also 4 bytes per path that goes on (the next queue's slot, apart).
  double shade() const { return 193 + slot; }
  double shade_path() const { return 145 + slot; }
  double shade_ray = 52;
  // Shadow ray, contribution and radiance in, radiance out, the alive flag and the slot.
  double shadow() const { return 81 + (slot == 4 ? 4 : 0); }
  // Slot, radiance and flags in, the film sum (16 bytes read and written) and the alive flag out.
  double finish = 4 + 16 + 4 + 32 + 1;
};

Result run_config(tracer::Renderer& r, const tracer::CompiledScene& cs,
                  tracer::IntegratorSettings cfg, const Config& c, int spp) {
  cfg.jitter = c.jitter;
  r.set_gpu_options(c.gpu);
  r.set_scene(cs, cfg);
  // Warm-up (module load, --kernel auto's calibration), then one timed sample at a time.
  r.render(c.gpu.kernel == tracer::KernelMode::kAuto ? 4 : 2);
  std::vector<double> ms;
  Result res;
  res.name = c.name;
  res.requested = c.gpu;
  tracer::RayCounts total;
  for (int i = 0; i < spp; ++i) {
    const tracer::FrameStats st = r.render(1);
    ms.push_back(st.ms);
    total.camera += st.rays.camera;
    total.extension += st.rays.extension;
    total.shadow += st.rays.shadow;
    if (i == 0) {
      res.stages = st.stages;
      res.alive = st.alive_per_bounce;
      res.shadows = st.shadow_per_bounce;
      res.finished = st.finished_per_bounce;
      res.mnee = st.mnee_per_bounce;
      res.kernel = st.kernel;
      res.specialization = st.specialization;
      res.note = st.note;
      if (st.gpu) res.gpu_options = st.gpu->describe();
      res.compacted = st.gpu ? st.gpu->compaction() : c.gpu.compaction != tracer::Compaction::kOff;
    }
  }
  std::sort(ms.begin(), ms.end());
  res.ms_per_frame = ms[ms.size() / 2];
  // Throughput: the same number of samples in one call. One-sample calls also pay, per sample,
  // the host's round trips (counter reads, event waits) while the GPU idles (PERFORMANCE.md).
  const tracer::FrameStats all = r.render(uint32_t(spp));
  res.ms_per_spp = all.ms / spp;
  res.rays.camera = (total.camera + all.rays.camera) / (2 * spp);
  res.rays.extension = (total.extension + all.rays.extension) / (2 * spp);
  res.rays.shadow = (total.shadow + all.rays.shadow) / (2 * spp);
  const double s = res.ms_per_spp * 1e-3;
  res.segments_per_s = double(res.rays.camera + res.rays.extension) / s;
  res.rays_per_s = double(res.rays.camera + res.rays.extension + res.rays.shadow) / s;
  return res;
}

// CUB's compactions in a sample, one stage each: after every staged bounce that another bounce
// or the tail follows (none with one bounce, or with a tail from bounce 1).
size_t cub_compactions(const tracer::StageTimes& t) {
  return size_t(std::count_if(t.bounces.begin(), t.bounces.end(),
                              [](const tracer::BounceTimes& b) { return b.compact > 0; }));
}

nlohmann::json bounce_json(const tracer::StageTimes& t) {
  nlohmann::json a = nlohmann::json::array();
  for (const tracer::BounceTimes& b : t.bounces)
    a.push_back({{"intersect", b.intersect}, {"sort", b.sort}, {"shade", b.shade},
                 {"shadow", b.shadow}, {"trace", b.trace}, {"compact", b.compact},
                 {"mnee", b.mnee}});
  return a;
}

nlohmann::json to_json(const Result& r) {
  return {{"config", r.name},
          {"kernel", r.kernel},
          {"specialization", r.specialization},
          {"ms_per_spp", r.ms_per_spp},
          {"ms_per_frame", r.ms_per_frame},
          {"M_segments_per_s", r.segments_per_s / 1e6},
          {"M_rays_per_s", r.rays_per_s / 1e6},
          {"rays_per_spp", {{"camera", r.rays.camera}, {"extension", r.rays.extension},
                            {"shadow", r.rays.shadow}}},
          {"stage_ms", {{"generate", r.stages.generate}, {"intersect", r.stages.intersect},
                        {"intersect_camera_rays", r.stages.intersect_first},
                        {"sort", r.stages.sort}, {"shade", r.stages.shade},
                        {"shadow", r.stages.shadow}, {"trace", r.stages.trace},
                        {"compact", r.stages.compact}, {"mnee", r.stages.mnee},
                        {"light", r.stages.light}, {"megakernel", r.stages.megakernel}}},
          {"alive_per_bounce", r.alive},
          {"shadow_rays_per_bounce", r.shadows},
          {"finished_without_shadow_ray_per_bounce", r.finished},
          {"mnee_requests_per_bounce", r.mnee},
          {"tail_from_bounce", r.stages.tail_from},
          {"rays_at_slots", r.stages.rays_at_slots},
          {"fused_trace", r.stages.fused_trace},
          {"tail_ms", r.stages.tail},
          {"bounce_stage_ms", bounce_json(r.stages)},
          {"ray_rates_M_per_s", r.ray_rates},
          {"note", r.note},
          {"gpu_options", r.gpu_options}};
}

// A row's name: its kernel and every GPU setting that differs from the defaults, as --set spells
// them without the section, and jitter=off for the rows without jitter.
std::string row_name(const tracer::GpuOptions& gpu, bool jitter) {
  tracer::Scene row, defaults;
  row.gpu = gpu;
  std::string name = tracer::setting_text(row, *tracer::find_setting("gpu.kernel"));
  for (const tracer::Setting& s : tracer::settings_table()) {
    if (s.section() != "gpu" || s.key == "gpu.kernel") continue;
    const std::string v = tracer::setting_text(row, s);
    if (v != tracer::setting_text(defaults, s)) name += " " + s.name() + "=" + v;
  }
  return name + (jitter ? "" : " jitter=off");
}

int run_bench(const BenchOptions& o) {
  tracer::Scene scene;
  if (!load_scene_or_report(o.scene, &scene)) return kExitInputError;
  tracer::RenderSettings rs = scene.settings;
  rs.width = o.width > 0 ? o.width : 1920;
  rs.height = o.height > 0 ? o.height : 1080;
  rs.max_depth = o.max_depth > 0 ? o.max_depth : 8;
  scene.settings = rs;
  std::string problem;
  if (!apply_setting_args(o.settings, &scene, &problem)) {
    std::cerr << "error: " << problem << "\n";
    return kExitUsage;
  }
  rs = scene.settings;
  try {
    tracer::validate_scene(scene);
  } catch (const tracer::InputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  const tracer::CompiledScene cs(scene, rs.width, rs.height);
  const tracer::IntegratorSettings cfg = tracer::make_integrator_settings(rs);
  nlohmann::json out;
  out["scene"] = o.scene.empty() ? "<built-in>" : o.scene;
  out["settings"] = {{"width", rs.width}, {"height", rs.height}, {"max_depth", rs.max_depth},
                     {"nee", rs.nee}, {"mis", rs.mis}, {"russian_roulette", rs.russian_roulette},
                     {"spp_timed", o.spp}};
  out["triangles"] = cs.view().tri_count;
  out["instances"] = cs.instances().size();
  out["instanced_triangles"] = scene.instanced_triangle_count();
  out["features"] = tracer::describe_features(cs.features());
  std::printf("scene %s: %u triangles, %u spheres, %zu instances of %zu triangles (%llu placed), "
              "features: %s\n",
              out["scene"].get<std::string>().c_str(), cs.view().tri_count,
              cs.view().sphere_count, cs.instances().size(), cs.inst_tri_verts().size(),
              (unsigned long long)scene.instanced_triangle_count(),
              tracer::describe_features(cs.features()).c_str());
  std::printf("settings: %dx%d, max depth %d, NEE %s, MIS %s, roulette %s (from depth %d)\n",
              rs.width, rs.height, rs.max_depth, rs.nee ? "on" : "off", rs.mis ? "on" : "off",
              rs.russian_roulette ? "on" : "off", rs.rr_start_depth);

  std::vector<Result> results;
  double gpu_best = 0.0;
  std::string why;
  std::unique_ptr<tracer::Renderer> gpu;
  if (o.backend != "cpu") gpu = tracer::make_cuda_renderer(&why);
  if (!gpu && o.backend == "cuda") {
    std::cerr << "error: --backend cuda: " << why << "\n";
    return kExitInputError;
  }
  if (gpu) {
    const double copy_gbs = tracer::measure_copy_bandwidth_gbs();
    std::printf("device: %s; measured copy bandwidth %.0f GB/s (read + write)\n",
                gpu->device_name().c_str(), copy_gbs);
    out["device"] = gpu->device_name();
    out["copy_bandwidth_GBps"] = copy_gbs;
    std::vector<Config> configs;
    // A variant build's rows carry its name: "wavefront+compaction [unfused]".
    const std::string variant = tracer::gpu_build_variant();
    std::printf("build variant: %s\n", variant.c_str());
    out["build_variant"] = variant;
    const std::string label = variant == "default" ? "" : " [" + variant + "]";
    // Each row is the scene's GPU settings (the defaults, or --set / --tail) with a few changed;
    // its name is the kernel and the settings that differ from the defaults, as --set spells
    // them (settings table): "wavefront compaction=cub", "megakernel flat=off".
    using C = tracer::Compaction;
    using K = tracer::KernelMode;
    auto add = [&](K k, C compaction, bool sort = false, bool jitter = true, bool cache = true,
                   bool flat = true, float tail = -1.0f) {
      Config c;
      c.gpu = scene.gpu;
      c.gpu.kernel = k;
      c.gpu.compaction = compaction;
      c.gpu.sort_materials = sort;
      c.gpu.first_bounce_cache = cache;
      c.gpu.flat_list = flat && scene.gpu.flat_list;
      if (tail >= 0.0f) c.gpu.tail_fraction = tail;
      c.jitter = jitter;
      c.name = row_name(c.gpu, jitter) + label;
      configs.push_back(c);
    };
    add(K::kMegakernel, C::kAuto);
    add(K::kWavefront, C::kOff);
    add(K::kWavefront, C::kAuto);
    add(K::kWavefront, C::kShade);
    add(K::kWavefront, C::kCub);
    add(K::kWavefront, C::kAuto, false, true, true, true, 0.0f);
    add(K::kWavefront, C::kAuto, true);
    add(K::kWavefront, C::kOff, true);
    if (o.jitter_off_configs && !(cs.features() & tracer::kFeatureDepthOfField)) {
      add(K::kWavefront, C::kAuto, false, false, false);
      add(K::kWavefront, C::kAuto, false, false, true);
    }
    if (cs.flat_list().enabled) {  // small scenes: the same designs through the BVH instead
      add(K::kMegakernel, C::kAuto, false, true, true, false);
      add(K::kWavefront, C::kAuto, false, true, true, false);
    }
    add(K::kAuto, C::kAuto);
    for (const Config& c : configs) results.push_back(run_config(*gpu, cs, cfg, c, o.spp));
    for (const auto& r : results) gpu_best = std::max(gpu_best, r.segments_per_s);
    out["path_state_bytes_per_pixel"] = gpu->path_state_bytes_per_pixel();
    out["scene_device_bytes"] = gpu->scene_bytes();
    out["bvh_bytes_per_triangle"] =
        cs.view().tri_count ? double(cs.nodes().size() * sizeof(tracer::BvhNode)) /
                                  cs.view().tri_count
                            : 0.0;

    std::printf("\n%-40s %-10s %9s %11s %10s %8s %8s %9s\n", "configuration", "kernel",
                "ms/spp", "Mseg/s", "Mrays/s", "ext/spp", "shd/spp", "ms/frame");
    for (const auto& r : results) {
      std::printf("%-40s %-10s %9.3f %11.0f %10.0f %7.2fM %7.2fM %9.3f\n", r.name.c_str(),
                  r.kernel.c_str(), r.ms_per_spp, r.segments_per_s / 1e6, r.rays_per_s / 1e6,
                  r.rays.extension / 1e6, r.rays.shadow / 1e6, r.ms_per_frame);
    }
    std::printf("specialization for this scene: %s\n", results.front().specialization.c_str());
    if (!results.back().note.empty()) std::printf("auto: %s\n", results.back().note.c_str());

    // Stage breakdown and bandwidth of each wavefront configuration; per bounce for the
    // compacted ones.
    const double copy_gbs_measured = out["copy_bandwidth_GBps"].get<double>();
    for (auto& r : results) {
      if (r.kernel != "wavefront" || r.alive.empty()) continue;
      const bool queued = r.compacted;
      const size_t compactions = cub_compactions(r.stages);
      const bool in_shade = queued && compactions == 0 &&
                            (r.stages.bounces.size() > 1 || r.stages.tail_from > 0);
      const StageBytes sb(queued, r.stages.rays_at_slots);
      // Bounces the stages ran: all, or those before the tail (which takes alive[tail_from]).
      const size_t staged = r.stages.tail_from
                                ? r.stages.tail_from
                                : std::max(r.alive.size(), r.stages.bounces.size());
      double processed = 0;  // path-bounces shaded by the stages
      // Paths entering bounce b (0 past the counts' end: trailing zeros are not kept).
      auto alive_at = [&](size_t b) { return b < r.alive.size() ? double(r.alive[b]) : 0.0; };
      for (size_t b = 0; b < staged; ++b) processed += alive_at(b);
      // Shadow rays of bounce b when the shade kernel queued them (with NEE off only the paths
      // it finished are counted, so either list says the queue ran).
      const bool shadow_queue = in_shade || !r.shadows.empty() || !r.finished.empty();
      auto shadows_at = [&](size_t b) {
        return b < r.shadows.size() ? double(r.shadows[b]) : 0.0;
      };
      double traced_shadows = 0;  // shadow rays of the staged bounces
      for (size_t b = 0; b < staged; ++b) traced_shadows += shadows_at(b);
      auto finished_at = [&](size_t b) {
        return b < r.finished.size() ? double(r.finished[b]) : 0.0;
      };
      // Bytes of the shade and shadow stages over `paths` paths with `shadows` shadow rays and
      // `finished` paths ended without one (their 4-byte slot at the shadow queue's far end).
      auto shade_bytes_of = [&](double paths, double shadows, double finished) {
        return shadow_queue ? sb.shade_path() * paths + sb.shade_ray * shadows + 4.0 * finished
                            : sb.shade() * paths;
      };
      double traced_finished = 0;
      for (size_t b = 0; b < staged; ++b) traced_finished += finished_at(b);
      auto shadow_bytes_of = [&](double paths, double shadows, double finished) {
        return shadow_queue ? sb.shadow() * shadows + sb.finish * finished : sb.shadow() * paths;
      };
      const double n = double(rs.width) * rs.height;
      const double bounces = double(staged);
      // Queue slots the shade kernel writes (the last staged bounce's go to the tail's queue).
      const double next_slots =
          processed - n + (r.stages.tail_from ? alive_at(r.stages.tail_from) : 0.0);
      auto gbs = [](double bytes, double ms) { return ms > 0 ? bytes / (ms * 1e-3) / 1e9 : 0.0; };
      const double total = r.stages.total();
      std::printf("\n[%s] stages (ms per spp, share, GB/s against %.0f copy):\n", r.name.c_str(),
                  copy_gbs_measured);
      auto row = [&](const char* name, double ms, double bytes) {
        const double g = gbs(bytes, ms);
        std::printf("  %-10s %8.3f ms %5.1f%%  %7.0f GB/s (%4.0f%%)\n", name, ms,
                    total > 0 ? 100.0 * ms / total : 0.0, g, 100.0 * g / copy_gbs_measured);
      };
      // Slots of dead paths that a pass over every path reads the flag of.
      const double dead = queued ? 0.0 : n * bounces - processed;
      const double shade_bytes = shade_bytes_of(processed, traced_shadows, traced_finished) + dead +
                                 (in_shade ? 4.0 * next_slots : 0.0);
      const double shadow_bytes = shadow_bytes_of(processed, traced_shadows, traced_finished) + dead;
      // With the fused trace stage, bounce b's extension rays (b > 0) were traced in one launch
      // with bounce b - 1's shadow stage: those bytes go to the trace row. The tail's bounce
      // too (then one bounce more has times than the stages shaded: the tail shades its hits).
      auto fused_at = [&](size_t b) {
        return b < r.stages.bounces.size() && r.stages.bounces[b].trace > 0;
      };
      const size_t timed_bounces = fused_at(staged) ? staged + 1 : staged;
      double trace_bytes = 0, trace_rays = 0, trace_shadows = 0;
      for (size_t b = 1; b < timed_bounces; ++b) {
        if (!fused_at(b)) continue;
        trace_bytes += sb.intersect() * alive_at(b) +
                       shadow_bytes_of(alive_at(b - 1), shadows_at(b - 1), finished_at(b - 1));
        trace_rays += alive_at(b);
        trace_shadows += shadows_at(b - 1);
      }
      // Extension rays (camera rays included) the stages traced.
      const double traced_rays = processed + (timed_bounces > staged ? alive_at(staged) : 0.0);
      const double intersect_bytes = sb.intersect() * (traced_rays - trace_rays) + dead;
      row("generate", r.stages.generate, sb.generate * n);
      row("intersect", r.stages.intersect, intersect_bytes);
      if (r.stages.sort > 0) row("sort", r.stages.sort, sb.sort * processed);
      row("shade", r.stages.shade, shade_bytes);
      // (The shadow stages not fused: all less those in the trace stage; none when the fused
      // stage also traced the tail's first rays.)
      if (r.stages.shadow > 0 || r.stages.trace == 0)
        row("shadow", r.stages.shadow, shadow_bytes - (trace_bytes - sb.intersect() * trace_rays));
      if (r.stages.trace > 0) row("trace", r.stages.trace, trace_bytes);
      if (r.stages.mnee > 0) {  // its solves and rays, not its bytes, bound it
        double requests = 0;
        for (uint32_t a : r.mnee) requests += a;
        std::printf("  %-10s %8.3f ms %5.1f%%  %.2f M requests (manifold NEE's solves), "
                    "%.1f M requests/s\n",
                    "mnee", r.stages.mnee, total > 0 ? 100.0 * r.stages.mnee / total : 0.0,
                    requests / 1e6, requests / (r.stages.mnee * 1e-3) / 1e6);
      }
      if (r.stages.light > 0)  // one thread per light path, atomics into the film
        std::printf("  %-10s %8.3f ms %5.1f%%  (light tracing's paths and camera connections)\n",
                    "light", r.stages.light, total > 0 ? 100.0 * r.stages.light / total : 0.0);
      // The intersect, shadow and trace stages together: all extension and shadow rays, the
      // same bytes with and without the fused stage.
      row("all rays", r.stages.intersect + r.stages.shadow + r.stages.trace,
          sb.intersect() * traced_rays + dead + shadow_bytes);
      const double bounce_ms = r.stages.intersect - r.stages.intersect_first;
      auto rate = [](double rays, double ms) { return rays / (ms * 1e-3) / 1e6; };
      if (r.stages.intersect_first > 0)
        r.ray_rates["camera"] = rate(n, r.stages.intersect_first);
      std::printf("  intersect: camera rays %.0f Mrays/s",
                  rate(n, r.stages.intersect_first));
      if (bounce_ms > 0) {
        r.ray_rates["bounce"] = rate(traced_rays - n - trace_rays, bounce_ms);
        std::printf(", bounce rays %.0f Mrays/s", rate(traced_rays - n - trace_rays, bounce_ms));
      }
      // The shadow stage's own rays: those the shade kernel queued less the fused ones, or,
      // without a tail, all of the sample's.
      const double stage_shadows = shadow_queue ? traced_shadows - trace_shadows
                                   : r.stages.tail_from == 0 ? double(r.rays.shadow) : 0.0;
      if (r.stages.shadow > 0 && stage_shadows > 0) {
        r.ray_rates["shadow"] = rate(stage_shadows, r.stages.shadow);
        std::printf(", shadow rays %.0f Mrays/s", rate(stage_shadows, r.stages.shadow));
      }
      std::printf("\n");
      if (r.stages.trace > 0)
        std::printf("  trace (a bounce's shadow stage with the next one's intersect stage): %.0f M "
                    "bounce rays + %.0f M shadow rays, %.0f Mrays/s\n",
                    trace_rays / 1e6, trace_shadows / 1e6,
                    (trace_rays + trace_shadows) / (r.stages.trace * 1e-3) / 1e6);
      if (r.stages.tail_from) {
        // Its segments: the sample's extension rays less those the stages shaded (after a fused
        // trace stage the tail's first rays were traced by it, and the tail shades them).
        const double tail_segments =
            double(r.rays.camera + r.rays.extension) - processed;
        std::printf("  %-10s %8.3f ms %5.1f%%  bounces %u on of %.0f paths: about %.2f M "
                    "segments, %.0f M segments/s\n",
                    "tail", r.stages.tail, total > 0 ? 100.0 * r.stages.tail / total : 0.0,
                    r.stages.tail_from, alive_at(r.stages.tail_from), tail_segments / 1e6,
                    r.stages.tail > 0 ? tail_segments / (r.stages.tail * 1e-3) / 1e6 : 0.0);
      }
      if (r.stages.compact > 0) {
        row("compact", r.stages.compact, (n + 4.0 * next_slots));
        std::printf("  compaction (CUB select): %.1f us per bounce, %.1f%% of the frame\n",
                    1000.0 * r.stages.compact / double(std::max<size_t>(1, compactions)),
                    100.0 * r.stages.compact / total);
      } else if (in_shade) {
        std::printf("  compaction: in the shade kernel (each block appends its paths that go on "
                    "to the next queue)\n");
      }
      std::printf("  bytes per segment (state traffic): %.0f\n",
                  (sb.generate * n + sb.intersect() * processed + shade_bytes + shadow_bytes +
                   dead + (r.stages.sort > 0 ? sb.sort * processed : 0.0)) /
                      processed);
      std::printf("  paths alive per bounce:");
      for (uint32_t a : r.alive) std::printf(" %u", a);
      std::printf("\n");
      if (shadow_queue) {
        std::printf("  shadow rays per bounce (queued by the shade kernel):");
        for (uint32_t a : r.shadows) std::printf(" %u", a);
        std::printf("\n  paths ended without one (finished by the shadow stage):");
        for (uint32_t a : r.finished) std::printf(" %u", a);
        std::printf("\n");
      }
      if (!r.mnee.empty()) {
        std::printf("  manifold NEE requests per bounce:");
        for (uint32_t a : r.mnee) std::printf(" %u", a);
        std::printf("\n");
      }
      if (!queued || r.stages.bounces.size() != timed_bounces) continue;
      // Per bounce: each stage's time and its bytes against the copy bandwidth; a short queue's
      // stage is bound by its launch and the GPU's fill and drain, not by its bytes.
      // With the fused trace stage, bounce b's trace column is its extension rays with bounce
      // b - 1's shadow stage (whose own shadow cell is then empty).
      const bool fused = r.stages.trace > 0;
      std::printf("  per bounce (us, %% of copy bandwidth):\n  %6s %9s %16s %16s %16s%s%s\n",
                  "bounce", "paths", "intersect", "shade", "shadow",
                  r.stages.compact > 0 ? "          compact" : "",
                  fused ? "  trace (shadow b-1)" : "");
      auto cell = [&](double ms, double bytes) {
        if (ms <= 0) {
          std::printf(" %16s", "-");
          return;
        }
        std::printf(" %9.1f (%3.0f%%)", 1000.0 * ms, 100.0 * gbs(bytes, ms) / copy_gbs_measured);
      };
      for (size_t b = 0; b < timed_bounces; ++b) {
        const tracer::BounceTimes& t = r.stages.bounces[b];
        const double paths = alive_at(b), next = alive_at(b + 1);
        std::printf("  %6zu %9.0f", b, paths);
        cell(t.intersect, sb.intersect() * paths);
        cell(t.shade, shade_bytes_of(paths, shadows_at(b), finished_at(b)) +
                          (in_shade ? 4.0 * next : 0.0));
        cell(t.shadow, shadow_bytes_of(paths, shadows_at(b), finished_at(b)));
        if (r.stages.compact > 0) cell(t.compact, n + 4.0 * next);
        if (fused)
          cell(t.trace, b > 0 ? sb.intersect() * paths + shadow_bytes_of(alive_at(b - 1),
                                                                         shadows_at(b - 1),
                                                                         finished_at(b - 1))
                              : 0.0);
        std::printf("\n");
      }
    }
    // The two compactions side by side: CUB's select is a stage of its own; the shade kernel's
    // appends cost what its shade stage takes beyond the same stage over CUB's queue (the same
    // paths, the same order of work otherwise).
    const Result* in_shade = nullptr;
    const Result* by_cub = nullptr;
    for (const auto& r : results) {
      if (r.kernel != "wavefront" || r.requested.sort_materials) continue;
      if (!in_shade && r.requested.compaction == tracer::Compaction::kShade) in_shade = &r;
      if (!by_cub && r.requested.compaction == tracer::Compaction::kCub) by_cub = &r;
    }
    // (Only when both ran the same bounces through their stages.)
    if (in_shade && by_cub && in_shade->alive.size() > 1 && by_cub->stages.compact > 0 &&
        in_shade->stages.tail_from == by_cub->stages.tail_from) {
      const double compacted = double(cub_compactions(by_cub->stages));
      const double extra = in_shade->stages.shade - by_cub->stages.shade;
      std::printf("\ncompaction per bounce: CUB select %.1f us (%.1f%% of its frame); in the shade "
                  "kernel %+.1f us of shade time against the CUB run (%.1f%% of its frame); "
                  "frames %.3f / %.3f ms\n",
                  1000.0 * by_cub->stages.compact / compacted,
                  100.0 * by_cub->stages.compact / by_cub->stages.total(), 1000.0 * extra / compacted,
                  100.0 * extra / in_shade->stages.total(), in_shade->stages.total(),
                  by_cub->stages.total());
      out["compaction_us_per_bounce"] = {{"cub", 1000.0 * by_cub->stages.compact / compacted},
                                         {"in_shade", 1000.0 * extra / compacted}};
    }
    std::printf("\npath state: %zu bytes per pixel; BVH: %.1f bytes per triangle\n",
                gpu->path_state_bytes_per_pixel(), out["bvh_bytes_per_triangle"].get<double>());
  } else if (o.backend != "cpu") {
    std::printf("no GPU: %s\n", why.c_str());
  }
  // The CPU backend on the same scene, for the CPU/GPU ratio.
  if (o.backend != "cuda" && o.cpu_spp > 0) {
    tracer::CpuRenderer cpu;
    if (results.empty())
      std::printf("\n%-40s %-10s %9s %11s %10s\n", "configuration", "kernel", "ms/spp", "Mseg/s",
                  "Mrays/s");
    Config c;
    c.name = "cpu (" + cpu.device_name() + ")";
    const Result r = run_config(cpu, cs, cfg, c, o.cpu_spp);
    results.push_back(r);
    std::printf("%-40s %-10s %9.3f %11.1f %10.1f\n", r.name.c_str(), "cpu", r.ms_per_spp,
                r.segments_per_s / 1e6, r.rays_per_s / 1e6);
    if (gpu_best > 0)
      std::printf("GPU (fastest) / CPU: %.0fx in path segments per second\n",
                  gpu_best / r.segments_per_s);
  }
  nlohmann::json arr = nlohmann::json::array();
  for (const auto& r : results) arr.push_back(to_json(r));
  out["results"] = arr;
  if (!o.json_out.empty()) {
    try {
      tracer::write_text_atomic(o.json_out, tracer::json_text(out));
    } catch (const std::exception& e) {
      std::cerr << "error: " << e.what() << "\n";
      return kExitInputError;
    }
  }
  return 0;
}

}  // namespace

Runner add_bench_command(CLI::App& cmd) {
  auto o = std::make_shared<BenchOptions>();
  cmd.add_option("scene", o->scene, "Scene file; default: built-in Cornell box")
      ->check(CLI::ExistingFile);
  cmd.add_option("--width", o->width, "Image width (default 1920; with --error the scene's)")
      ->check(CLI::Range(1, 16384));
  cmd.add_option("--height", o->height, "Image height (default 1080; with --error the scene's)")
      ->check(CLI::Range(1, 16384));
  cmd.add_option("--max-depth", o->max_depth,
                 "Maximum path segments (default 8; with --error the scene's)")
      ->check(CLI::Range(1, 1024));
  CLI::Option* spp = cmd.add_option("--spp", o->spp, "Timed samples per GPU configuration: as many one-sample frames (their median: ms/frame), then one call of as many samples (ms/spp, Mseg/s)")
      ->check(CLI::Range(1, 100000))->capture_default_str();
  CLI::Option* cpu_spp = cmd.add_option("--cpu-spp", o->cpu_spp, "Timed samples for the CPU backend (0: skip)")
      ->check(CLI::Range(0, 100000))->capture_default_str();
  cmd.add_option("--backend", o->backend, "auto, cpu or cuda")->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  CLI::Option* json = cmd.add_option("--json", o->json_out, "Also write the figures to this JSON file");
  // From the settings table: --nee, --tail and --set (the rows' base; --set also with --error).
  std::vector<std::string> skip;
  for (const tracer::Setting& s : tracer::settings_table())
    if (s.key != "render.nee" && s.key != "gpu.tail") skip.push_back(s.key);
  add_setting_options(cmd, &o->settings, {"render", "gpu", "environment"}, skip);
  // The speed bench's own options mean nothing to --error (its configurations carry nee=off,
  // its sweep its sample counts, --out its files): combining them is a usage error.
  CLI::Option* error = add_error_bench_options(cmd, &o->error);
  for (CLI::Option* opt : {spp, cpu_spp, json}) opt->excludes(error);
  return [o] {
    if (!o->error.enabled) return run_bench(*o);
    if (!o->settings.flags.empty()) {
      std::cerr << "error: --nee and --tail are the speed bench's; with --error, give each "
                   "configuration its modifiers (e.g. megakernel+nee=off)\n";
      return kExitUsage;
    }
    ErrorBenchScene s;
    s.scene = o->scene;
    s.width = o->width;
    s.height = o->height;
    s.max_depth = o->max_depth;
    s.backend = o->backend;
    s.sets = o->settings.sets;
    return run_error_bench(s, o->error);
  };
}

}  // namespace app
