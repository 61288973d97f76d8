// Backend selection: CUDA when it was built and a device answers, otherwise the CPU.
// Kept out of the `tracer` library so that it can link the optional `tracer_cuda`.
#include <stdexcept>

#include "cpu/cpu_backend.h"

namespace tracer {

#if defined(TRACER_CUDA_BACKEND)
// Defined in tracer/cuda when the CUDA backend is built.
std::unique_ptr<Renderer> make_cuda_renderer(std::string* why_not);
#endif

std::unique_ptr<Renderer> make_renderer(BackendChoice choice, int cpu_threads, std::string* note) {
  if (choice == BackendChoice::kCpu) return std::make_unique<CpuRenderer>(cpu_threads);
  std::string why;
#if defined(TRACER_CUDA_BACKEND)
  if (auto r = make_cuda_renderer(&why)) return r;
#else
  why = "this build has no CUDA backend (nvcc was not found at configure time)";
#endif
  if (choice == BackendChoice::kCuda) throw std::runtime_error("--backend cuda: " + why);
  if (note) *note = "using the CPU backend: " + why;
  return std::make_unique<CpuRenderer>(cpu_threads);
}

}  // namespace tracer
