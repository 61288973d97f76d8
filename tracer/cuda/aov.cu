// The feature buffers' kernel (integrator/aov.h): launched after each sample's paths when the
// settings ask for AOVs, never otherwise, so the path kernels carry none of its code. One
// variant for every scene (all features): it traces one camera ray and its specular chain.
#include "cuda/kernel_common.cuh"
#include "integrator/aov.h"

namespace tracer {
namespace {

__global__ void aov_kernel(SceneView s, const __grid_constant__ FlatParams flat,
                           IntegratorSettings cfg, uint32_t sample, bool first, AovFilm film) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= film.n) return;
  const AovSample a = trace_aov<kAllFeatures>(with_flat_params(s, flat), cfg, i, sample);
  const float4 va = make_float4(a.albedo.x, a.albedo.y, a.albedo.z, a.depth);
  const float4 vb = make_float4(a.normal.x, a.normal.y, a.normal.z, 0.0f);
  const uint32_t h = sample & 1u;
  if (first) {
    film.a[h][i] = va;
    film.b[h][i] = vb;
  } else {
    float4 x = film.a[h][i], y = film.b[h][i];
    film.a[h][i] = make_float4(x.x + va.x, x.y + va.y, x.z + va.z, x.w + va.w);
    film.b[h][i] = make_float4(y.x + vb.x, y.y + vb.y, y.z + vb.z, 0.0f);
  }
  if (film.write_ids) film.ids[i] = make_uint2(a.material, a.prim);
}

}  // namespace

void launch_aov(const SceneView& s, const FlatParams& flat, const IntegratorSettings& cfg,
                uint32_t sample, bool first, const AovFilm& film, cudaStream_t stream) {
  aov_kernel<<<blocks(film.n), kBlock, 0, stream>>>(s, flat, cfg, sample, first, film);
  TRACER_CUDA_CHECK_LAUNCH("aov_kernel");
}

}  // namespace tracer
