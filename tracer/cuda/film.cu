// The film's kernels: the mean image of the two accumulators (resolve), the display image
// (exposure, tone map, sRGB) and copies of the first-bounce hits.
#include "cuda/kernel_common.cuh"
#include "image/display.h"

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

}  // namespace

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
