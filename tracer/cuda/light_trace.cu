// Light tracing of caustics (render.light_tracing; integrator/light_path.h): one thread per light
// path, its connections to the camera added to the sample's film by atomics, after the sample's
// camera paths (which write that film first).
#include "cuda/kernel_common.cuh"
#include "integrator/light_path.h"

namespace tracer {
namespace {

template <uint32_t Spec>
__global__ void __launch_bounds__(kBlock) light_kernel(SceneView s, IntegratorSettings cfg,
                                                       uint32_t sample, FilmView film, float norm,
                                                       unsigned long long* counters) {
  constexpr uint32_t F = features_of<Spec>();
  const uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  LightPathCounts c;
  if (k < film.n) {
    auto splat = [&](uint32_t pixel, vec3 v) {
      float cut;
      v = clamp_radiance(v, film.clamp, &cut);
      if (cut > 0.0f) {  // rare: plain atomics
        atomicAdd(film.clamped, 1ull);
        atomicAdd(film.clamped_luminance, double(cut));
      }
      float4* a = film.accum + pixel;
      atomicAdd(&a->x, v.x);
      atomicAdd(&a->y, v.y);
      atomicAdd(&a->z, v.z);
    };
    c = trace_light_path<F>(s, cfg, k, sample, film.n, norm, splat);
  }
  warp_add(&counters[kCounterExtension], c.segments);
  warp_add(&counters[kCounterShadow], c.connections);
}

}  // namespace

void launch_light_trace(uint32_t spec, const SceneView& s, const IntegratorSettings& cfg,
                        uint32_t sample, const FilmView& film, unsigned long long* counters,
                        cudaStream_t stream) {
  const float norm = filter_profile_integral(cfg.filter, cfg.filter_radius);
#define CALL(S) \
  light_kernel<S><<<blocks(film.n), kBlock, 0, stream>>>(s, cfg, sample, film, norm, counters)
  // Four variants: light paths need delta materials (specular), and the general ones carry the
  // lens, the lights beyond emitters and instances.
  if (spec & kSpecInstances) CALL(kInstancesSpec);
  else if (spec & (kSpecLights | kSpecDepthOfField)) CALL(kGeneralSpec);
  else if (spec & kSpecSpheres) CALL(kSpecSpecular | kSpecSpheres);
  else CALL(kSpecSpecular);
#undef CALL
  TRACER_CUDA_CHECK_LAUNCH("light_kernel");
}

}  // namespace tracer
