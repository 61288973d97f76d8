// Checked CUDA calls: every runtime call and kernel launch reports the expression, file:line and
// the error's name, as an exception the front end can show.
#pragma once

#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

namespace tracer {

class CudaError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline void cuda_check(cudaError_t err, const char* expr, const char* file, int line) {
  if (err == cudaSuccess) return;
  throw CudaError(std::string(file) + ":" + std::to_string(line) + ": " + expr + " failed: " +
                  cudaGetErrorName(err) + " (" + cudaGetErrorString(err) + ")");
}

}  // namespace tracer

#define TRACER_CUDA_CHECK(expr) ::tracer::cuda_check((expr), #expr, __FILE__, __LINE__)
// After a <<<...>>> launch: catches bad configurations at once (not asynchronous faults).
#define TRACER_CUDA_CHECK_LAUNCH(name) \
  ::tracer::cuda_check(cudaGetLastError(), "launch of " name, __FILE__, __LINE__)
