// The GPU backend's switches: what a user asks for (GpuOptions), the facts of a scene that limit
// them (GpuSceneTraits), and the one function that resolves a request into what runs
// (EffectiveGpuOptions), with a reason for every value it changes. Host code only (tested on CPU).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "scene/settings.h"

namespace tracer {

class CompiledScene;
struct IntegratorSettings;
struct SceneView;

// The names the settings table gives them (gpu.kernel, gpu.compaction), for messages.
std::string kernel_mode_name(KernelMode k);  // auto, wavefront, megakernel
std::string compaction_name(Compaction c);   // auto, shade, cub, off

// Build variants: the engineering baselines that measurements settled (PERFORMANCE.md) are no
// switches; a bench build compiled with one of these macros (in CMAKE_CXX_FLAGS, as they are read
// by host code: `VARIANT=unfused EXTRA_CXX_FLAGS=-DTRACER_VARIANT_UNFUSED
// scripts/build-device.sh` builds into .devbuild/dist-unfused) runs the baseline instead:
//   TRACER_VARIANT_NO_FETCH      the BVH's wavefront intersect stage runs one thread per queued
//                                ray, not persistent warps whose lanes fetch new rays
//                                (dynamic_fetch off);
//   TRACER_VARIANT_GENERAL_SPEC  every kernel is the one compiled for all features, not the
//                                scene's specialisation (specialize off);
//   TRACER_VARIANT_RAYS_AT_IDS   extension rays and hits stay at their paths' ids also over the
//                                shade kernel's queues (rays_at_slots off, hence no fused trace);
//   TRACER_VARIANT_UNFUSED       each bounce's shadow stage and the next bounce's intersect stage
//                                run as two launches (fused_trace off);
//   TRACER_VARIANT_UNFUSED_TAIL  the tail's first bounce is traced by the tail itself, after a
//                                shadow stage of its own (fused_tail off).
// And one experiment that turns a path on rather than off, so far slower (PERFORMANCE.md, row
// 93); it also needs the macro in the CUDA flags, which compile its walk:
//   TRACER_VARIANT_BVH8          the BVH walks use the 8-wide compressed nodes of bvh/bvh8.h
//                                instead of the 4-wide ones of bvh/bvh.h (bvh8 on).
// Their names: no-fetch, general-spec, rays-at-ids, unfused, unfused-tail, bvh8. The code of each
// baseline stays: rays at ids and the unfused stages also serve sorting, random walks, CUB's
// queues and the BVH. Returns "default", or the names of the build's variants joined by '+'
// (e.g. "no-fetch+unfused"), as the bench labels its rows.
std::string gpu_build_variant();

// What the resolution needs to know about a scene and the integrator's settings.
struct GpuSceneTraits {
  uint32_t features = 0;        // SceneFeature bits (textures, subsurface, spheres, ...)
  bool flat_available = false;  // the scene is small enough for the flat list (FlatList::enabled)
  bool jitter = true;           // the camera jitters samples within pixels
  bool depth_of_field = false;  // the camera's lens radius is above zero
  bool bvh8_available = false;  // the compiled scene has an 8-wide tree (CompiledScene::bvh8)
  bool guiding = false;         // path guiding is asked for (IntegratorSettings::guiding)
  bool mnee = false;            // manifold NEE is asked for (IntegratorSettings::mnee)
  bool mnee_casters = false;    // ... and the scene has what it connects through or reflects off
};
// Whether manifold NEE has something to connect through or reflect off in the scene: smooth
// glass, a plane of flat reflectors, a mirror sphere of those it tries (integrator/path.h). Where
// it has none (rough glass and metals only, say) the GPU runs the usual kernels and the CPU makes
// no requests.
bool mnee_has_casters(const CompiledScene& scene);
// Light tracing's pilot (render.light_tracing): the share of its light paths that reach the
// camera (a free connection that lands on the film), of kLightPilotPaths traced on the host with
// cfg's camera, depth and seed (deterministic); -1 where it can find no path at all (no area
// light, or no material with a delta lobe). A few milliseconds.
float light_path_yield(const CompiledScene& scene, const IntegratorSettings& cfg);
constexpr uint32_t kLightPilotPaths = 8192;
// Below this share light tracing is futile: its cost buys splats almost nowhere (smallpt's lamp,
// a huge sphere of which a sliver pokes into the room, sends none to the camera). Near it the gain
// is small either way; the scenes it helps most lie far above (PERFORMANCE.md rows 131-132).
constexpr float kLightTracingMinYield = 0.002f;
// Whether light tracing has paths worth tracing here: light_path_yield >= kLightTracingMinYield.
// Where not, the renderers trace no light paths (the path tracer then leaves nothing to them).
bool light_tracing_has_paths(const CompiledScene& scene, const IntegratorSettings& cfg);
// Whether light tracing runs: asked for, with jittered pixels (a pixel without jitter is its
// centre's radiance, which no splat gives) and paths worth tracing (light_tracing_has_paths).
// Where not, the renderers clear cfg.light_tracing, so that the path tracer leaves it nothing.
bool light_tracing_runs(const IntegratorSettings& cfg, bool has_paths);
// From a scene's view (its features and camera) and whether it has a flat list (mnee_casters is
// left false: the caller knows it from the compiled scene), or from the compiled scene itself.
GpuSceneTraits gpu_scene_traits(const SceneView& view, bool flat_available,
                                const IntegratorSettings& cfg);
GpuSceneTraits gpu_scene_traits(const CompiledScene& scene, const IntegratorSettings& cfg);

// A value the resolution changed: a user switch (requested: as asked) or a design path of the
// wavefront that is off (path: true; requested: "on", the design the build runs where it can).
struct GpuOverride {
  std::string name;  // the GpuOptions field or EffectiveGpuOptions path, e.g. "first_bounce_cache"
  std::string requested, effective;  // e.g. "on", "off"
  std::string reason;                // e.g. "the camera jitters samples within pixels"
  bool path = false;
};

struct EffectiveGpuOptions {
  // The switches as they run: compaction is never kAuto, the tail is 0 without compaction, the
  // cache is off where camera rays move, the flat list off where the scene has none. (The
  // kernel stays kAuto: the renderer times both designs. With the megakernel the wavefront's
  // switches and paths are resolved all the same; they do not apply.)
  GpuOptions options;
  // The wavefront's design paths, from the switches, the scene and the build variant:
  // Extension rays and hits stored at their paths' slots in each bounce's queue, not at their
  // ids, so the intersect and shade kernels read them in whole sectors (only over the shade
  // kernel's queues, which a sort would reorder, and without random walks, whose rays look up
  // the triangle they leave from by the path's id).
  bool rays_at_slots = false;
  // With rays at their slots and the flat list: each bounce's shadow stage and the next bounce's
  // intersect stage run as one launch (the trace stage).
  bool fused_trace = false;
  // ... also the tail's first bounce (with a tail): its rays are traced with the last staged
  // bounce's shadow rays, and the tail starts by shading their hits.
  bool fused_tail = false;
  // The BVH's intersect stage: persistent warps whose lanes take new rays between rounds.
  bool dynamic_fetch = false;
  // BVH walks (megakernel and wavefront) in the 8-wide compressed tree, not the 4-wide one
  // (bvh8 builds only).
  bool bvh8 = false;
  // Kernels compiled for the scene's features only (spec), or the general ones (kGeneralSpec).
  bool specialize = false;
  uint32_t spec = 7;
  // The shade kernel's variant: spec, with path guiding guided_shade_spec(spec), with manifold
  // NEE caustic_shade_spec(spec).
  uint32_t shade_spec = 7;
  std::string build_variant;  // gpu_build_variant()
  // One entry per changed switch and per path that is off, each with its reason.
  std::vector<GpuOverride> overrides;

  bool compaction() const { return options.compaction != Compaction::kOff; }
  bool queues_in_shade() const { return options.compaction == Compaction::kShade; }
  const GpuOverride* find(const std::string& name) const;  // nullptr: not overridden
  // One line: the design that runs, each override with its reason, the build variant.
  std::string describe() const;
};

// The one place that decides which GPU design runs for a request on a scene.
EffectiveGpuOptions resolve_gpu_options(const GpuOptions& requested, const GpuSceneTraits& scene);

}  // namespace tracer
