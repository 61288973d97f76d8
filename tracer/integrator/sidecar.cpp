// The one sidecar writer (see sidecar.h).
#include "integrator/sidecar.h"

#include <algorithm>
#include <nlohmann/json.hpp>

#include "image/image.h"

namespace tracer {

nlohmann::json effective_gpu_json(const EffectiveGpuOptions& e) {
  Scene as_run;
  as_run.gpu = e.options;
  nlohmann::json j;
  j["effective"] = settings_to_json(as_run)["gpu"];
  j["wavefront_paths"] = {{"rays_at_slots", e.rays_at_slots},
                          {"fused_trace", e.fused_trace},
                          {"fused_tail", e.fused_tail},
                          {"dynamic_fetch", e.dynamic_fetch},
                          {"specialize", e.specialize}};
  j["build_variant"] = e.build_variant;
  nlohmann::json overrides = nlohmann::json::array();
  for (const GpuOverride& o : e.overrides) {
    overrides.push_back({{"name", o.name},
                         {"requested", o.requested},
                         {"effective", o.effective},
                         {"reason", o.reason},
                         {"design_path", o.path}});
  }
  j["overrides"] = overrides;
  return j;
}

double clamp_removed_fraction(const SidecarRun& run) {
  return run.clamped_luminance / std::max(1e-30, run.kept_luminance + run.clamped_luminance);
}

nlohmann::json make_sidecar(const Scene& scene, const SidecarRun& run) {
  nlohmann::json j;
  j["scene"] = scene.source.empty() ? "<built-in>" : scene.source;
  j["output"] = run.output;
  j["version"] = TRACER_VERSION;
  j["backend"] = run.backend;
  j["device"] = run.device;
  // Every setting, in the scene format: these sections load back as a scene file's.
  const nlohmann::json settings = settings_to_json(scene);
  for (auto it = settings.begin(); it != settings.end(); ++it) j[it.key()] = it.value();
  nlohmann::json mats = nlohmann::json::object();
  for (const auto& m : scene.materials) mats[m.name] = material_to_json(m.material);
  j["materials"] = mats;
  if (!scene.distant_lights.empty() || !scene.point_lights.empty())
    j["lights"] = lights_to_json(scene.distant_lights, scene.point_lights);
  if (scene.environment_image) {  // the map as it was read (the mapping "auto" chose)
    const EnvironmentImage& img = *scene.environment_image;
    j["environment_map"] = {{"file", img.path},
                            {"width", img.width},
                            {"height", img.height},
                            {"mapping", env_mapping_name(resolve_env_mapping(
                                            scene.environment.mapping, img.width, img.height))},
                            {"negative_texels_clamped", img.negative}};
  }
  j["spp"] = run.spp;
  j["wall_time_s"] = run.wall_time_s;
  if (run.setup_time_s >= 0) j["setup_time_s"] = run.setup_time_s;
  j["rays"] = {
      {"camera", run.rays.camera}, {"extension", run.rays.extension}, {"shadow", run.rays.shadow}};
  const double total = double(run.rays.camera + run.rays.extension + run.rays.shadow);
  j["mrays_per_s"] = run.wall_time_s > 0 ? total / run.wall_time_s / 1e6 : 0.0;
  j["nonfinite_samples"] = run.nonfinite;
  j["random_walks_capped"] = run.rays.walk_capped;
  j["medium_leaks"] = run.rays.medium_leaks;
  if (scene.settings.clamp > 0.0f) {
    j["clamp"] = {{"value", scene.settings.clamp},
                  {"samples_clamped", run.clamped},
                  {"luminance_removed_fraction", clamp_removed_fraction(run)}};
  }
  if (run.backend == "cuda") {
    j["gpu_run"] = {{"kernel", run.last.kernel},
                    {"specialization", run.last.specialization},
                    {"note", run.last.note}};
    if (run.last.gpu) j["gpu_run"].update(effective_gpu_json(*run.last.gpu));
  }
  j["features"] = run.features;
  if (!run.ranks.empty()) {
    nlohmann::json ranks = nlohmann::json::array();
    for (const RankShare& r : run.ranks)
      ranks.push_back({{"rank", r.rank},
                       {"host", r.host},
                       {"backend", r.backend},
                       {"device", r.device},
                       {"samples", r.samples},
                       {"batches", r.batches},
                       {"render_s", r.render_s},
                       {"ms_per_spp", r.ms_per_spp},
                       {"idle_s", r.idle_s}});
    j["mpi"] = {{"ranks", ranks}, {"reduce_s", run.reduce_s}};
  }
  if (run.relmse_halves >= 0) j["relmse_halves"] = run.relmse_halves;
  if (!run.aovs.empty()) j["aovs"] = {{"layers", run.aovs}, {"samples", run.aov_samples}};
  if (run.guide.on)
    j["guiding"] = {{"status", run.guide.describe()},
                    {"trained_samples", run.guide.trained_samples},
                    {"builds", run.guide.builds},
                    {"learned_cells", run.guide.learned_cells},
                    {"guiding_cells", run.guide.guiding_cells},
                    {"cells", run.guide.cells}};
  if (run.guide.on && run.guide.calibration.done()) {
    const GuideCalibration& c = run.guide.calibration;
    j["guiding"]["decision"] = c.keeps() ? "kept" : "retired";
    j["guiding"]["variance_ratio"] = c.variance_ratio();
    j["guiding"]["time_ratio"] = c.time_ratio();
  }
  if (!run.denoise.denoiser.empty()) {
    // The denoised image is biased: the sidecar says what made it from what.
    j["denoise"] = {{"denoiser", run.denoise.denoiser},
                    {"device", run.denoise.device},
                    {"inputs", run.denoise.inputs},
                    {"ms", run.denoise.ms},
                    {"output", run.denoised_output}};
  }
  j["warnings"] = scene.diagnostics.warnings;
  return j;
}

void write_sidecar(const Scene& scene, const SidecarRun& run) {
  write_text_atomic(run.output + ".json", json_text(make_sidecar(scene, run)));
}

}  // namespace tracer
