// The film's kernels: the mean image of the two accumulators (resolve), the display image
// (exposure, tone map, sRGB), copies of the first-bounce hits and path guiding's calibration.
#include "cuda/film.h"
#include "cuda/kernel_common.cuh"
#include "image/display.h"
#include "integrator/guide_calibration.h"

namespace tracer {
namespace {

__global__ void resolve_kernel(const float4* a, float wa, const float4* b, float wb, uint32_t n,
                               float* rgb) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const float4 x = a[i], y = b[i];
  rgb[3 * i + 0] = x.x * wa + y.x * wb;
  rgb[3 * i + 1] = x.y * wa + y.y * wb;
  rgb[3 * i + 2] = x.z * wa + y.z * wb;
}

__global__ void display_kernel(const float4* a, const float4* b, float inv, uint32_t n,
                               float exposure_scale, int op, uint32_t* rgba) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const float4 x = a[i], y = b[i];
  const vec3 mean = vec3(x.x + y.x, x.y + y.y, x.z + y.z) * inv;
  rgba[i] = display_rgba8(mean, exposure_scale, ToneMap(op));
}

__global__ void copy_kernel(const float4* from, float4* to, uint32_t n) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) to[i] = from[i];
}

__global__ void sum_films_kernel(const float4* a, const float4* b, float4* sum, uint32_t n) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) {
    const float4 x = a[i], y = b[i];
    sum[i] = make_float4(x.x + y.x, x.y + y.y, x.z + y.z, 0.0f);
  }
}

// Path guiding's calibration: a block's mean is the two films' sums now minus `then`, times
// inv_block; the mean it is measured against `base` times inv_base. Each block of threads adds
// its pixels' terms to *out.
__global__ void block_noise_kernel(const float4* a, const float4* b, const float4* then,
                                   const float4* base, float inv_block, float inv_base,
                                   uint32_t n, double* out) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  float term = 0.0f;
  if (i < n) {
    const float4 x = a[i], y = b[i], t = then[i], m = base[i];
    term = guide_moment_term((x.x + y.x - t.x) * inv_block, m.x * inv_base) +
           guide_moment_term((x.y + y.y - t.y) * inv_block, m.y * inv_base) +
           guide_moment_term((x.z + y.z - t.z) * inv_block, m.z * inv_base);
  }
  double sum = term;
  for (int offset = 16; offset > 0; offset >>= 1) sum += __shfl_down_sync(0xffffffffu, sum, offset);
  __shared__ double warps[kBlock / 32];
  if ((threadIdx.x & 31) == 0) warps[threadIdx.x / 32] = sum;
  __syncthreads();
  if (threadIdx.x == 0) {
    double block = 0.0;
    for (uint32_t w = 0; w < kBlock / 32; ++w) block += warps[w];
    atomicAdd(out, block);
  }
}

}  // namespace

void launch_sum_films(const float4* a, const float4* b, float4* sum, uint32_t n,
                      cudaStream_t stream) {
  sum_films_kernel<<<blocks(n), kBlock, 0, stream>>>(a, b, sum, n);
  TRACER_CUDA_CHECK_LAUNCH("sum_films_kernel");
}

void launch_block_noise(const float4* a, const float4* b, const float4* then, const float4* base,
                        float inv_block, float inv_base, uint32_t n, double* out,
                        cudaStream_t stream) {
  TRACER_CUDA_CHECK(cudaMemsetAsync(out, 0, sizeof(double), stream));
  block_noise_kernel<<<blocks(n), kBlock, 0, stream>>>(a, b, then, base, inv_block, inv_base, n,
                                                       out);
  TRACER_CUDA_CHECK_LAUNCH("block_noise_kernel");
}

void launch_copy_hits(const float4* from, float4* to, uint32_t n, cudaStream_t stream) {
  copy_kernel<<<blocks(n), kBlock, 0, stream>>>(from, to, n);
  TRACER_CUDA_CHECK_LAUNCH("copy_kernel");
}

void launch_resolve(const float4* a, float wa, const float4* b, float wb, uint32_t n,
                    float* rgb_out, cudaStream_t stream) {
  resolve_kernel<<<blocks(n), kBlock, 0, stream>>>(a, wa, b, wb, n, rgb_out);
  TRACER_CUDA_CHECK_LAUNCH("resolve_kernel");
}

void launch_display(const float4* a, const float4* b, float inv_samples, uint32_t n,
                    float exposure_scale, int tone_map, uint32_t* rgba, cudaStream_t stream) {
  display_kernel<<<blocks(n), kBlock, 0, stream>>>(a, b, inv_samples, n, exposure_scale,
                                                   tone_map, rgba);
  TRACER_CUDA_CHECK_LAUNCH("display_kernel");
}

}  // namespace tracer
