// Compiles the shared TRACER_HD tracer code with nvcc for sm_90 (+PTX), so that CPU-only changes
// that break device compilation fail the build here and in CI, not on the GPU machine.
#include "integrator/path.h"

namespace tracer {

__global__ void shared_code_compile_check(SceneView scene, IntegratorSettings cfg, float4* out,
                                          uint32_t n) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const vec3 L = trace_path(scene, cfg, i, 0);
  out[i] = make_float4(L.x, L.y, L.z, 1.0f);
}

}  // namespace tracer
