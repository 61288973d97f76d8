// The feature buffers' kernel (integrator/aov.h): launched after each sample's paths while AOVs
// are on, never otherwise, so the path kernels carry none of its code. Specialised like them on
// spheres, depth of field and specular materials (lights play no part: it samples none), plus the
// instances' variant. And their resolve into the 3-float images the denoiser reads.
#include "cuda/kernel_common.cuh"
#include "integrator/aov.h"

namespace tracer {
namespace {

template <uint32_t Spec>
__global__ void aov_kernel(SceneView s, const __grid_constant__ FlatParams flat,
                           IntegratorSettings cfg, uint32_t sample, bool first, AovFilm film) {
  constexpr uint32_t F = features_of<Spec>() | kFeatureFlatList;
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= film.n) return;
  const AovSample a = trace_aov<F>(with_flat_params(s, flat), cfg, i, sample);
  const float4 va = make_float4(a.albedo.x, a.albedo.y, a.albedo.z, a.depth);
  const float4 vb = make_float4(a.normal.x, a.normal.y, a.normal.z, 0.0f);
  const uint32_t h = sample & 1u;
  if (first) {
    film.a[h][i] = va;
    film.b[h][i] = vb;
  } else {
    const float4 x = film.a[h][i], y = film.b[h][i];
    film.a[h][i] = make_float4(x.x + va.x, x.y + va.y, x.z + va.z, x.w + va.w);
    film.b[h][i] = make_float4(y.x + vb.x, y.y + vb.y, y.z + vb.z, 0.0f);
  }
  if (film.write_ids) film.ids[i] = make_uint2(a.material, a.prim);
}

// The mean albedo and normal, 3 floats per pixel: w[h] weighs half h (0 for a half without
// samples, whose memory is stale).
__global__ void aov_resolve_kernel(AovFilm film, float w0, float w1, float* albedo,
                                   float* normal) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= film.n) return;
  float4 a = make_float4(0, 0, 0, 0), b = a;
  if (w0 > 0.0f) {
    const float4 x = film.a[0][i], y = film.b[0][i];
    a = make_float4(x.x * w0, x.y * w0, x.z * w0, 0);
    b = make_float4(y.x * w0, y.y * w0, y.z * w0, 0);
  }
  if (w1 > 0.0f) {
    const float4 x = film.a[1][i], y = film.b[1][i];
    a = make_float4(a.x + x.x * w1, a.y + x.y * w1, a.z + x.z * w1, 0);
    b = make_float4(b.x + y.x * w1, b.y + y.y * w1, b.z + y.z * w1, 0);
  }
  albedo[3 * i + 0] = a.x;
  albedo[3 * i + 1] = a.y;
  albedo[3 * i + 2] = a.z;
  normal[3 * i + 0] = b.x;
  normal[3 * i + 1] = b.y;
  normal[3 * i + 2] = b.z;
}

}  // namespace

void launch_aov(uint32_t spec, const SceneView& s, const FlatParams& flat,
                const IntegratorSettings& cfg, uint32_t sample, bool first, const AovFilm& film,
                cudaStream_t stream) {
#define CALL(S) \
  aov_kernel<S><<<blocks(film.n), kBlock, 0, stream>>>(s, flat, cfg, sample, first, film)
  if (spec & kSpecInstances) {
    CALL(kInstancesSpec);
  } else {
    switch (spec & 7u) {
      case 0: CALL(0); break;
      case 1: CALL(1); break;
      case 2: CALL(2); break;
      case 3: CALL(3); break;
      case 4: CALL(4); break;
      case 5: CALL(5); break;
      case 6: CALL(6); break;
      default: CALL(7); break;
    }
  }
#undef CALL
  TRACER_CUDA_CHECK_LAUNCH("aov_kernel");
}

void launch_aov_resolve(const AovFilm& film, float w0, float w1, float* albedo, float* normal,
                        cudaStream_t stream) {
  aov_resolve_kernel<<<blocks(film.n), kBlock, 0, stream>>>(film, w0, w1, albedo, normal);
  TRACER_CUDA_CHECK_LAUNCH("aov_resolve_kernel");
}

}  // namespace tracer
