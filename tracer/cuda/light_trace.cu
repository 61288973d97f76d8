// Light tracing of caustics (render.light_tracing; integrator/light_path.h): persistent threads
// with path regeneration (as the megakernel: a lane whose light path ends takes the next, so warps
// stay full while path lengths differ), through the flat list on small scenes; connections added
// to the sample's film by atomics, after the sample's camera paths (which write that film first).
#include "cuda/kernel_common.cuh"
#include "integrator/light_path.h"

namespace tracer {
namespace {

template <uint32_t Spec, bool Flat, bool Windows>
__global__ void __launch_bounds__(kBlock) light_kernel(SceneView view,
                                                       const __grid_constant__ FlatParams flat,
                                                       IntegratorSettings cfg, uint32_t sample,
                                                       FilmView film, float norm,
                                                       unsigned long long* counters,
                                                       uint32_t* next_path, uint32_t paths) {
  constexpr uint32_t F = features_of<Spec>() | (Flat ? kFeatureFlatList : 0u) |
                         (Windows ? kFeatureWindows : 0u);
  const SceneView s = Flat ? with_flat_params(view, flat) : view;
  // Added as the camera paths' radiance is (clamped, counted), never as the first to the film.
  auto splat = [&](uint32_t pixel, vec3 v) {
    add_to_film(film, pixel, v, false, &counters[kCounterNonfinite]);
  };
  LightPathState st;
  bool alive = false, exhausted = false;
  uint32_t segments = 0, connections = 0;
  for (;;) {
    const unsigned active = __activemask();
    const bool want = !alive && !exhausted;
    const unsigned need = __ballot_sync(active, want);
    if (want) {
      const uint32_t k = take_pixel(need, next_path);
      if (k < paths) alive = start_light_path<F>(s, cfg, k, sample, st);
      else exhausted = true;
    }
    if (!alive) {
      if (exhausted) break;
      continue;  // a light path that carries nothing: the next one
    }
    const Hit hit = intersect_closest<F>(s, st.ray, kInvalid);
    ++segments;
    LightConnection c;
    alive = light_path_vertex<F>(s, cfg, paths, norm, st, hit, &c, splat);
    connections += c.window_rays;
    if (c.connect) {
      ++connections;
      if (!intersect_any<F>(s, c.ray, kInvalid, kInvalid))
        splat_film_point(cfg, c.film, c.value, norm, splat);
    }
  }
  warp_add(&counters[kCounterExtension], segments);
  warp_add(&counters[kCounterShadow], connections);
}

template <uint32_t Spec, bool Flat, bool Windows = false>
void launch(const SceneView& s, const FlatParams& flat, const IntegratorSettings& cfg,
            uint32_t sample, const FilmView& film, float norm, unsigned long long* counters,
            uint32_t* next_path, cudaStream_t stream) {
  const uint32_t paths = light_paths_per_sample(s, film.n);
  light_kernel<Spec, Flat, Windows>
      <<<persistent_blocks(light_kernel<Spec, Flat, Windows>, paths), kBlock, 0, stream>>>(
          s, flat, cfg, sample, film, norm, counters, next_path, paths);
}

}  // namespace

void launch_light_trace(uint32_t spec, const SceneView& s, const FlatParams& flat,
                        const IntegratorSettings& cfg, uint32_t sample, const FilmView& film,
                        unsigned long long* counters, uint32_t* next_path, cudaStream_t stream) {
  const float norm = filter_profile_integral(cfg.filter, cfg.filter_radius);
  TRACER_CUDA_CHECK(cudaMemsetAsync(next_path, 0, sizeof(uint32_t), stream));
  // Light paths need delta materials (specular); the general variants carry the lens, the
  // lights beyond emitters and instances (whose scenes have no flat list).
#define CALL(S, FLAT) launch<S, FLAT>(s, flat, cfg, sample, film, norm, counters, next_path, stream)
#define CALLW(S, FLAT) \
  launch<S, FLAT, true>(s, flat, cfg, sample, film, norm, counters, next_path, stream)
  // Scenes with windows (the path tracer leaves the paths behind them to this kernel): the
  // general variants with the window connections.
  if (s.window_plane_count > 0) {
    if (spec & kSpecInstances) CALLW(kInstancesSpec, false);
    else if (s.use_flat) CALLW(kGeneralSpec, true);
    else CALLW(kGeneralSpec, false);
  } else if (spec & kSpecInstances) CALL(kInstancesSpec, false);
  else if (s.use_flat) {
    if (spec & (kSpecLights | kSpecDepthOfField)) CALL(kGeneralSpec, true);
    else if (spec & kSpecSpheres) CALL(kSpecSpecular | kSpecSpheres, true);
    else CALL(kSpecSpecular, true);
  } else {
    if (spec & (kSpecLights | kSpecDepthOfField)) CALL(kGeneralSpec, false);
    else if (spec & kSpecSpheres) CALL(kSpecSpecular | kSpecSpheres, false);
    else CALL(kSpecSpecular, false);
  }
#undef CALL
#undef CALLW
  TRACER_CUDA_CHECK_LAUNCH("light_kernel");
}

}  // namespace tracer
