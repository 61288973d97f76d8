// `pathtracer info`: what a scene holds (primitives, materials by type, lights), how its BVH came
// out, and which renderer features it needs.
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "integrator/sidecar.h"
#include "scene/compiled_scene.h"
#include "settings_cli.h"
#include "scene/loader.h"

namespace app {
namespace {

// A share as a percentage with two decimals ("0.10%").
std::string percent(float share) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2f%%", 100.0 * share);
  return buf;
}

struct InfoOptions {
  std::string scene;
  bool json = false;
  SettingArgs settings;  // e.g. --compaction cub: what the GPU would run with it
};

// describe()'s switches and design paths, without the overrides (printed a line each).
// "6012 8-wide compressed nodes (5100 leaves, 470.00 KiB), depth 6, stack 21, built in ...".
std::string bvh8_text(const tracer::Bvh8& b) {
  if (b.nodes.empty()) return "none (the 4-wide tree serves: a leaf too large to address)";
  char buf[200];
  std::snprintf(buf, sizeof buf,
                "%u %d-wide compressed nodes (%u leaves, %.2f KiB), depth %u, stack %u, built "
                "in %.2f ms from the 4-wide tree",
                b.stats.node_count, tracer::kBvh8Width, b.stats.leaf_count,
                b.nodes.size() * sizeof(tracer::Bvh8Node) / 1024.0, b.stats.max_depth,
                b.stats.max_stack, b.stats.build_ms);
  return buf;
}

std::string gpu_design_head(const tracer::EffectiveGpuOptions& e) {
  const std::string d = e.describe();
  const size_t build = d.find("; build ");
  if (build == std::string::npos) return d;
  const size_t end = d.find(';', build + 2);
  return end == std::string::npos ? d : d.substr(0, end);
}

// True when the loader chose the camera (a mesh file without one); its note says why.
bool framed(const tracer::Scene& scene) {
  for (const std::string& n : scene.diagnostics.notes)
    if (n.find("camera at") != std::string::npos) return true;
  return false;
}

int run_info(const InfoOptions& o) {
  tracer::Scene scene;
  if (!load_scene_or_report(o.scene, &scene)) return kExitInputError;
  std::string problem;
  if (!apply_setting_args(o.settings, &scene, &problem)) {
    std::cerr << "error: " << problem << "\n";
    return kExitUsage;
  }
  if (!report_scene_messages(scene, false)) return kExitInputError;
  const tracer::CompiledScene cs(scene, scene.settings.width, scene.settings.height);
  const tracer::SceneView& v = cs.view();
  int by_type[tracer::kMaterialTypeCount] = {};
  int emissive = 0;
  for (const auto& m : scene.materials) {
    by_type[int(m.material.type)]++;
    if (m.material.is_emissive()) ++emissive;
  }
  const auto& st = cs.bvh_stats();
  nlohmann::json j;
  j["scene"] = scene.source;
  j["objects"] = scene.objects.size();
  j["primitives"] = v.tri_count + v.sphere_count;
  j["triangles"] = v.tri_count;
  j["spheres"] = v.sphere_count;
  // The planes of flat mirrors and glass faces manifold NEE reflects off (scene_view.h).
  j["reflector_planes"] = v.reflector_plane_count;
  j["too_many_reflector_planes"] = cs.too_many_reflector_planes();
  // The planes of flat glass faces light tracing joins the camera through (a tank's front).
  j["window_planes"] = v.window_plane_count;
  // The bounding spheres light tracing aims its paths' first directions at (its casters).
  j["light_targets"] = v.light_target_count;
  // Whether manifold NEE has anything to connect through or off (smooth glass or reflectors).
  const bool casters = tracer::mnee_has_casters(cs);
  j["mnee_casters"] = casters;
  // Light tracing's pilot: the share of its light paths that reach the camera (-1: none can),
  // and whether that is enough for the renderers to trace them.
  const float light_yield =
      tracer::light_path_yield(cs, tracer::make_integrator_settings(scene.settings));
  const bool light_paths = light_yield >= tracer::kLightTracingMinYield;
  j["light_paths"] = light_paths;
  j["light_path_yield"] = light_yield;
  // Instanced meshes are stored once and placed by every instance: the triangles the instances
  // place, and those stored.
  uint64_t stored = 0;
  for (const tracer::InstancedMesh& m : scene.instanced_meshes) stored += m.mesh.indices.size();
  j["instanced_meshes"] = scene.instanced_meshes.size();
  j["instances"] = scene.instances.size();
  j["instanced_triangles"] = scene.instanced_triangle_count();
  j["instanced_triangles_stored"] = stored;
  // Every type, named as the scene format names it, so the counts add up to the total.
  std::string by_type_text;
  j["materials"] = {{"total", scene.materials.size()}, {"emissive", emissive}};
  for (int t = 0; t < tracer::kMaterialTypeCount; ++t) {
    const char* name = tracer::material_type_name(tracer::MaterialType(t));
    j["materials"][name] = by_type[t];
    by_type_text += (t ? ", " : "") + std::to_string(by_type[t]) + " " + name;
  }
  uint32_t emitters = 0;  // the light list also holds the lights at infinity
  for (const tracer::Light& l : cs.lights()) emitters += l.kind == tracer::kLightPrimitive;
  j["lights"] = emitters;
  uint32_t points = 0, spots = 0;  // those the light list holds (black ones are left out)
  for (const tracer::Light& l : cs.lights()) {
    points += l.kind == tracer::kLightPoint;
    spots += l.kind == tracer::kLightSpot;
  }
  j["point_lights"] = points;
  j["spot_lights"] = spots;
  j["environment"] = tracer::describe_environment(scene);
  const tracer::CameraDesc& cam = scene.camera;
  auto vec = [](tracer::vec3 p) { return nlohmann::json::array({p.x, p.y, p.z}); };
  j["camera"] = {{"position", vec(cam.position)}, {"look_at", vec(cam.look_at)},
                 {"up", vec(cam.up)}, {"vfov", cam.vfov_deg}};
  j["warnings"] = scene.diagnostics.warnings;
  j["notes"] = scene.diagnostics.notes;  // e.g. why a mesh file got this camera and light
  const tracer::Bvh8& b8 = cs.bvh8();
  if (tracer::kBvh8Build)
    j["bvh8"] = {{"nodes", b8.stats.node_count},
               {"leaves", b8.stats.leaf_count},
               {"max_stack", b8.stats.max_stack},
               {"depth", b8.stats.max_depth},
               {"build_ms", b8.stats.build_ms},
               {"bytes", b8.nodes.size() * sizeof(tracer::Bvh8Node)}};
  j["bvh"] = {{"nodes", st.node_count},
              {"width", tracer::kBvhWidth},
              {"binary_nodes", st.binary_node_count},
              {"leaves", st.leaf_count},
              {"max_stack", st.max_stack},
              {"depth", st.max_depth},
              {"sah_cost", st.sah_cost},
              {"build_ms", st.build_ms},
              {"bytes", st.node_count * sizeof(tracer::BvhNode)}};
  const tracer::FlatList& fl = cs.flat_list();
  const std::string flat_text =
      fl.enabled ? tracer::describe_flat_list(fl, v.sphere_count) +
                       ": the GPU tests them in one uniform loop (box faces and solid boxes "
                       "by slab tests) instead of the BVH"
                 : "none (more than " + std::to_string(tracer::kFlatMaxCost) +
                       " entries): the GPU walks the BVH";
  const tracer::LightTree& lt = cs.light_tree();
  j["light_tree"] = {{"nodes", lt.nodes.size()},
                     {"leaves", lt.leaf_count},
                     {"lights", lt.leaves.size()},
                     {"depth", lt.depth},
                     {"build_ms", lt.build_ms},
                     {"bytes", lt.nodes.size() * sizeof(tracer::LightTreeNode) +
                                   lt.leaves.size() * sizeof(tracer::LightLeafEntry) +
                                   lt.trails.size() * sizeof(uint64_t)}};
  j["flat_list"] = {{"enabled", fl.enabled},
                    {"entries", fl.prims.size()},
                    {"quads", fl.quad_count},
                    {"box_faces", fl.box_faces},
                    {"solid_boxes", fl.solids.size()},
                    {"degenerate_triangles", fl.degenerate},
                    {"max_cost", tracer::kFlatMaxCost}};
  j["features"] = tracer::describe_features(cs.features());
  j["gpu_specialization"] = tracer::spec_name_for_features(cs.features());
  const nlohmann::json settings = tracer::settings_to_json(scene);
  j["render"] = settings["render"];
  j["gpu"] = settings["gpu"];
  // What the GPU would run for these settings on this scene, and why each switch that is
  // overridden is (resolve_gpu_options, the one place that decides it).
  const tracer::EffectiveGpuOptions gpu = tracer::resolve_gpu_options(
      scene.gpu, tracer::gpu_scene_traits(cs, tracer::make_integrator_settings(scene.settings)));
  j["gpu_design"] = tracer::effective_gpu_json(gpu);
  if (o.json) {
    std::cout << tracer::json_text(j);
    return 0;
  }
  std::cout << "scene       " << scene.source << "\n"
            << "objects     " << scene.objects.size() << "\n"
            << "primitives  " << v.tri_count + v.sphere_count << " (" << v.tri_count
            << " triangles, " << v.sphere_count << " spheres)\n"
            << (scene.instances.empty()
                    ? std::string()
                    : "instances   " + std::to_string(scene.instances.size()) + " of " +
                          std::to_string(scene.instanced_meshes.size()) + " meshes (" +
                          std::to_string(scene.instanced_triangle_count()) +
                          " instanced triangles, " + std::to_string(stored) + " stored)\n")
            << "materials   " << scene.materials.size() << " (" << by_type_text << "; " << emissive
            << " emissive)\n"
            << "lights      " << emitters << " emissive primitives"
            << (scene.point_lights.empty()
                    ? std::string()
                    : "; " + tracer::describe_point_lights(scene.point_lights))
            << "\n"
            << "environment " << tracer::describe_environment(scene) << "\n"
            << "camera      " << tracer::vec3_str(cam.position, 4) << " looking at "
            << tracer::vec3_str(cam.look_at, 4) << ", " << cam.vfov_deg << " degree field of view"
            << (framed(scene) ? " (framed; the note above says why)" : "") << "\n"
            << "bvh         " << st.node_count << " " << tracer::kBvhWidth << "-wide nodes ("
            << st.leaf_count << " leaves, " << st.node_count * sizeof(tracer::BvhNode) / 1024.0
            << " KiB), depth " << st.max_depth << ", SAH cost " << std::fixed
            << std::setprecision(2) << st.sah_cost << ", built in " << std::setprecision(2)
            << st.build_ms << " ms\n"
            << (tracer::kBvh8Build ? "bvh8        " + bvh8_text(cs.bvh8()) + "\n" : "")
            << "light tree  " << lt.nodes.size() << " nodes over " << lt.leaves.size()
            << " lights (" << lt.leaf_count << " leaves), depth " << lt.depth << ", built in "
            << std::setprecision(2) << lt.build_ms << " ms\n"
            << "flat list   " << flat_text << "\n"
            << (v.reflector_plane_count > 0
                    ? "reflectors  " + std::to_string(v.reflector_plane_count) +
                          " planes of flat mirrors and glass faces (manifold NEE reflects off "
                          "each)\n"
                    : cs.too_many_reflector_planes()
                          ? "reflectors  none listed: flat mirrors and glass faces in more than " +
                                std::to_string(tracer::kMaxReflectorPlanes) +
                                " planes (manifold NEE does not reflect off them)\n"
                          : std::string())
            << (v.window_plane_count > 0
                    ? "windows     " + std::to_string(v.window_plane_count) +
                          " planes of flat glass faces (light tracing joins the camera through "
                          "each)\n"
                    : std::string())
            << (v.light_target_count > 0
                    ? "targets     " + std::to_string(v.light_target_count) +
                          (v.light_target_count == 1 ? " sphere" : " spheres") +
                          " around the mirrors, glass and glossy metals (light tracing aims its "
                          "paths at them)\n"
                    : std::string())
            << (scene.settings.mnee && !casters
                    ? "mnee        on, but nothing here to connect through or reflect off (no "
                      "smooth glass, flat mirrors or mirror spheres): the image is as without "
                      "it, and the GPU runs its usual kernels\n"
                    : std::string())
            << (scene.settings.light_tracing && light_yield < 0.0f
                    ? "light       tracing on, but no light path to find here (no area light, or "
                      "no mirror, glass or glossy metal): the image is as without it\n"
                    : scene.settings.light_tracing && !light_paths
                    ? "light       tracing on, but only " + percent(light_yield) +
                          " of its light paths reach the camera through a mirror, glass or metal "
                          "(below " + percent(tracer::kLightTracingMinYield) +
                          "): the path tracer renders alone\n"
                    : scene.settings.light_tracing && !scene.settings.jitter
                          ? "light       tracing on, but off while jitter is off (splats need "
                            "jittered pixels)\n"
                          : std::string())
            << "features    " << tracer::describe_features(cs.features()) << "\n"
            << "GPU kernels " << tracer::spec_name_for_features(cs.features())
            << (gpu.shade_spec != gpu.spec
                    ? std::string("; shade: ") + tracer::spec_label(gpu.shade_spec)
                    : std::string())
            << "\n"
            << "GPU design  " << gpu_design_head(gpu) << "\n"
            << "render      " << scene.settings.width << "x" << scene.settings.height << ", "
            << scene.settings.spp << " spp, max depth " << scene.settings.max_depth << "\n";
  for (const tracer::GpuOverride& ov : gpu.overrides)
    std::cout << "  GPU " << (ov.path ? "path " : "switch ") << ov.name << " " << ov.requested
              << " -> " << ov.effective << ": " << ov.reason << "\n";
  return 0;
}

}  // namespace

Runner add_info_command(CLI::App& cmd) {
  auto o = std::make_shared<InfoOptions>();
  cmd.add_option("scene", o->scene, "Scene file (.json, .pbrt, .obj, .gltf, .glb, .ply); default: built-in")
      ->check(CLI::ExistingFile);
  cmd.add_flag("--json", o->json, "Print JSON instead of text");
  add_setting_options(cmd, &o->settings, {"render", "gpu", "environment"},
                      {"render.spp", "render.time_limit_s", "render.threads", "render.backend",
                       "render.samples_per_frame"});
  return [o] { return run_info(*o); };
}

}  // namespace app
