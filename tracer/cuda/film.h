// The film's launches beside kernels.h's: path guiding's calibration (integrator/guide_host.h),
// kept apart so that the kernels that never use it do not depend on it.
#pragma once

#include <cuda_runtime.h>

#include <cstdint>

namespace tracer {

// sum = a + b (rgb): the two films' sums over all samples so far.
void launch_sum_films(const float4* a, const float4* b, float4* sum, uint32_t n,
                      cudaStream_t stream);
// *out = guide_block_noise (guide_host.h) of the films a + b now against their sums `then` and
// `base` (from launch_sum_films): the noise of the block's mean.
void launch_block_noise(const float4* a, const float4* b, const float4* then, const float4* base,
                        float inv_block, float inv_base, uint32_t n, double* out,
                        cudaStream_t stream);

}  // namespace tracer
