// Resolution of the GPU switches (gpu_options.h): every rule that limits a switch or a design
// path of the wavefront, in one place, each with the reason it gives.
#include "integrator/gpu_options.h"

#include <algorithm>
#include <cstdio>

#include "bvh/bvh8.h"
#include "bvh/flat_list.h"
#include "core/features.h"
#include "integrator/light_path.h"
#include "scene/compiled_scene.h"
#include "scene/scene.h"

namespace tracer {
namespace {

// The build variants (gpu_options.h): each turns one design path off for the whole build.
#ifdef TRACER_VARIANT_NO_FETCH
constexpr bool kNoFetchOn = true;
#else
constexpr bool kNoFetchOn = false;
#endif
#ifdef TRACER_VARIANT_GENERAL_SPEC
constexpr bool kGeneralSpecOn = true;
#else
constexpr bool kGeneralSpecOn = false;
#endif
#ifdef TRACER_VARIANT_RAYS_AT_IDS
constexpr bool kRaysAtIdsOn = true;
#else
constexpr bool kRaysAtIdsOn = false;
#endif
#ifdef TRACER_VARIANT_UNFUSED
constexpr bool kUnfusedOn = true;
#else
constexpr bool kUnfusedOn = false;
#endif
#ifdef TRACER_VARIANT_UNFUSED_TAIL
constexpr bool kUnfusedTailOn = true;
#else
constexpr bool kUnfusedTailOn = false;
#endif

struct BuildVariant {
  bool on;
  const char* name;  // as gpu_build_variant() joins them
  const char* macro;
};
constexpr BuildVariant kNoFetch = {kNoFetchOn, "no-fetch", "TRACER_VARIANT_NO_FETCH"};
constexpr BuildVariant kGeneralSpecVariant = {kGeneralSpecOn, "general-spec",
                                              "TRACER_VARIANT_GENERAL_SPEC"};
constexpr BuildVariant kRaysAtIds = {kRaysAtIdsOn, "rays-at-ids", "TRACER_VARIANT_RAYS_AT_IDS"};
constexpr BuildVariant kUnfused = {kUnfusedOn, "unfused", "TRACER_VARIANT_UNFUSED"};
constexpr BuildVariant kUnfusedTail = {kUnfusedTailOn, "unfused-tail",
                                       "TRACER_VARIANT_UNFUSED_TAIL"};
constexpr BuildVariant kBvh8 = {kBvh8Build, "bvh8", "TRACER_VARIANT_BVH8"};
constexpr const BuildVariant* kVariants[] = {&kNoFetch,  &kGeneralSpecVariant, &kRaysAtIds,
                                             &kUnfused,  &kUnfusedTail,        &kBvh8};

std::string variant_reason(const BuildVariant& v) {
  return std::string("build variant ") + v.name + " (" + v.macro + ")";
}

const char* on_off(bool b) {
  return b ? "on" : "off";
}

std::string fraction_text(float f) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", double(f));
  return buf;
}

}  // namespace

// The names are the settings table's (gpu.kernel, gpu.compaction), read back through it.
std::string kernel_mode_name(KernelMode k) {
  Scene s;
  s.gpu.kernel = k;
  return setting_text(s, *find_setting("gpu.kernel"));
}

std::string compaction_name(Compaction c) {
  Scene s;
  s.gpu.compaction = c;
  return setting_text(s, *find_setting("gpu.compaction"));
}

std::string gpu_build_variant() {
  std::string s;
  for (const BuildVariant* v : kVariants)
    if (v->on) s += (s.empty() ? "" : "+") + std::string(v->name);
  return s.empty() ? "default" : s;
}

GpuSceneTraits gpu_scene_traits(const SceneView& view, bool flat_available,
                                const IntegratorSettings& cfg) {
  GpuSceneTraits t;
  t.features = view.features;
  t.flat_available = flat_available;
  t.jitter = cfg.jitter != 0;
  t.depth_of_field = view.camera.lens_radius > 0.0f;
  t.guiding = cfg.guiding != 0;
  t.mnee = cfg.mnee != 0;
  return t;
}

bool mnee_has_casters(const CompiledScene& scene) {
  // Smooth glass (rough glass, the dielectric feature's other half, it does not connect
  // through), or the planes of flat smooth reflectors.
  for (const Material& m : scene.materials())
    if (mnee_glass(m)) return true;
  if (!scene.reflector_planes().empty()) return true;
  const size_t spheres = std::min<size_t>(scene.spheres().size(), kMneeMaxSpheres);
  for (size_t i = 0; i < spheres; ++i)
    if (mnee_flat_reflector(scene.materials()[scene.spheres()[i].material])) return true;
  return false;
}

namespace {
// Whether light tracing can find any path: an area light and a material with a delta lobe.
bool light_tracing_can_find(const CompiledScene& scene) {
  bool area_light = false;
  for (uint32_t i = 0; i < scene.view().light_count; ++i)
    area_light = area_light || scene.view().lights[i].kind == kLightPrimitive;
  if (!area_light) return false;
  for (const Material& m : scene.materials())
    if (light_path_may_start_at(m)) return true;
  return false;
}
}  // namespace

float light_path_yield(const CompiledScene& scene, const IntegratorSettings& cfg) {
  if (!light_tracing_can_find(scene)) return -1.0f;
  IntegratorSettings c = cfg;
  c.light_tracing = 1;
  uint32_t reached = 0;
  for (uint32_t i = 0; i < kLightPilotPaths; ++i) {
    bool any = false;
    trace_light_path<kAllFeatures>(scene.view(), c, i, 0x7fffffffu, kLightPilotPaths, 1.0f,
                                   [&any](uint32_t, vec3) { any = true; });
    reached += any ? 1u : 0u;
  }
  return float(reached) / float(kLightPilotPaths);
}

bool light_tracing_has_paths(const CompiledScene& scene, const IntegratorSettings& cfg) {
  return light_path_yield(scene, cfg) >= kLightTracingMinYield;
}

bool light_tracing_runs(const IntegratorSettings& cfg, bool has_paths) {
  return cfg.light_tracing && cfg.jitter && has_paths;
}

GpuSceneTraits gpu_scene_traits(const CompiledScene& scene, const IntegratorSettings& cfg) {
  GpuSceneTraits t = gpu_scene_traits(scene.view(), scene.flat_list().enabled, cfg);
  t.bvh8_available = !scene.bvh8().nodes.empty();
  t.mnee_casters = mnee_has_casters(scene);
  return t;
}

const GpuOverride* EffectiveGpuOptions::find(const std::string& name) const {
  for (const GpuOverride& o : overrides)
    if (o.name == name) return &o;
  return nullptr;
}

std::string EffectiveGpuOptions::describe() const {
  const GpuOptions& o = options;
  std::string s = std::string("kernel ") + kernel_mode_name(o.kernel) + ", compaction " +
                  compaction_name(o.compaction) + ", sorting " + on_off(o.sort_materials) +
                  ", first-bounce cache " + on_off(o.first_bounce_cache) + ", flat list " +
                  on_off(o.flat_list) + ", tail " + fraction_text(o.tail_fraction) +
                  "; wavefront paths: rays at slots " + on_off(rays_at_slots) + ", fused trace " +
                  on_off(fused_trace) + ", fused tail " + on_off(fused_tail) + ", dynamic fetch " +
                  on_off(dynamic_fetch) + ", specialised " + on_off(specialize) +
                  ", 8-wide BVH " + on_off(bvh8) + "; build " +
                  build_variant;
  if (o.kernel == KernelMode::kMegakernel) s += " (the megakernel runs no wavefront stages)";
  for (const GpuOverride& v : overrides)
    s += "; " + v.name + " " + v.requested + " -> " + v.effective + ": " + v.reason;
  return s;
}

EffectiveGpuOptions resolve_gpu_options(const GpuOptions& requested, const GpuSceneTraits& scene) {
  EffectiveGpuOptions e;
  e.options = requested;
  e.build_variant = gpu_build_variant();
  GpuOptions& o = e.options;
  auto changed = [&](const char* name, const std::string& from, const std::string& to,
                     const std::string& reason) {
    e.overrides.push_back({name, from, to, reason, false});
  };
  // A design path: on unless `why` names what turns it off.
  auto path = [&](const char* name, const std::string& why) {
    if (!why.empty()) e.overrides.push_back({name, "on", "off", why, true});
    return why.empty();
  };

  // The user's switches.
  if (o.compaction == Compaction::kAuto) {
    // The shade kernel's queues except on textured scenes, whose long, divergent shading (96
    // registers, 2 blocks per SM) waits at the block's barrier, where CUB's separate pass is
    // the faster (PERFORMANCE.md, decision log, rows 67 and 74).
    const bool textured = (scene.features & kFeatureTextures) != 0;
    o.compaction = textured ? Compaction::kCub : Compaction::kShade;
    changed("compaction", "auto", compaction_name(o.compaction),
            textured ? "auto on a textured scene: CUB's select (the shade kernel's queues wait "
                       "at the block's barrier after the long shading)"
                     : "auto on an untextured scene: the shade kernel's queues");
  }
  // Path guiding trains from the stages' paths (guide_train_kernel after each sample) and
  // guides in the guided shade kernel: the megakernel and the tail (a megakernel) have neither.
  if (scene.guiding && o.kernel != KernelMode::kWavefront) {
    changed("kernel", kernel_mode_name(o.kernel), "wavefront",
            "path guiding trains and guides in the wavefront's stages");
    o.kernel = KernelMode::kWavefront;
  }
  if (scene.guiding && o.tail_fraction != 0.0f) {
    changed("tail_fraction", fraction_text(o.tail_fraction), "0",
            "path guiding: the tail is a megakernel, which neither guides nor trains");
    o.tail_fraction = 0.0f;
  }
  // Manifold NEE runs in the caustic shade kernels only (features.h), where a scene has glass or
  // smooth reflectors to connect through or off (elsewhere the usual kernels run).
  const bool mnee = scene.mnee && scene.mnee_casters;
  if (mnee && o.kernel != KernelMode::kWavefront) {
    changed("kernel", kernel_mode_name(o.kernel), "wavefront",
            "manifold NEE runs in the wavefront's caustic shade kernels");
    o.kernel = KernelMode::kWavefront;
  }
  if (mnee && o.tail_fraction != 0.0f) {
    changed("tail_fraction", fraction_text(o.tail_fraction), "0",
            "manifold NEE: the tail is a megakernel, which does not compile it");
    o.tail_fraction = 0.0f;
  }
  if (o.compaction == Compaction::kOff && o.tail_fraction != 0.0f) {
    changed("tail_fraction", fraction_text(o.tail_fraction), "0",
            "the tail takes its paths from compaction's queues (compaction off)");
    o.tail_fraction = 0.0f;
  }
  if (o.first_bounce_cache && (scene.jitter || scene.depth_of_field)) {
    o.first_bounce_cache = false;
    changed("first_bounce_cache", "on", "off",
            scene.jitter ? "the camera jitters samples within pixels"
                         : "depth of field moves camera rays");
  }
  if (o.flat_list && !scene.flat_available) {
    o.flat_list = false;
    changed("flat_list", "on", "off",
            "the scene is too large for the flat list (its entries cost more than " +
                std::to_string(kFlatMaxCost) + " triangle tests)");
  }

  // The wavefront's design paths, each off for exactly one reason (the first that applies).
  const bool walks = (scene.features & kFeatureSubsurface) != 0;
  std::string why;
  if (kRaysAtIds.on)
    why = variant_reason(kRaysAtIds);
  else if (o.compaction == Compaction::kOff)
    why = "no compaction: the stages pass over the paths by id";
  else if (!e.queues_in_shade())
    why = "CUB's queues hold path ids, in id order";
  else if (o.sort_materials)
    why = "material sorting reorders the queues";
  else if (walks)
    why = "random walks look up the triangle a ray leaves from by the path's id";
  e.rays_at_slots = path("rays_at_slots", why);

  why.clear();
  if (kUnfused.on)
    why = variant_reason(kUnfused);
  else if (!e.rays_at_slots)
    why = "the rays are at their paths' ids";
  else if (!o.flat_list)
    why = "the BVH's intersect stage is not fused";
  e.fused_trace = path("fused_trace", why);

  why.clear();
  if (kUnfusedTail.on)
    why = variant_reason(kUnfusedTail);
  else if (!e.fused_trace)
    why = "no fused trace stage";
  else if (!(o.tail_fraction > 0.0f))
    why = "no tail";
  e.fused_tail = path("fused_tail", why);

  why.clear();
  if (kNoFetch.on)
    why = variant_reason(kNoFetch);
  else if (o.flat_list)
    why = "the flat list's loop ends for a whole warp at once: no lane waits for a new ray";
  e.dynamic_fetch = path("dynamic_fetch", why);

  // The 8-wide tree: only a bvh8 build walks it (no override is listed elsewhere), there where
  // the BVH is walked and the scene has one.
  why.clear();
  if (kBvh8.on && o.flat_list)
    why = "the flat list replaces the BVH";
  else if (kBvh8.on && !scene.bvh8_available)
    why = "a leaf of the scene's tree is too large for the 8-wide nodes to address";
  e.bvh8 = kBvh8.on && path("bvh8", why);

  e.specialize =
      path("specialize", kGeneralSpecVariant.on ? variant_reason(kGeneralSpecVariant) : "");
  // The general kernels leave out instances (features.h): a scene with some needs them added.
  e.spec = e.specialize                              ? spec_for_features(scene.features)
           : (scene.features & kFeatureInstances) ? kInstancesSpec
                                                   : kGeneralSpec;
  e.shade_spec = mnee ? caustic_shade_spec(e.spec)
                 : scene.guiding ? guided_shade_spec(e.spec)
                                 : e.spec;
  return e;
}

}  // namespace tracer
