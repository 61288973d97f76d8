// The one macro that lets tracer code compile for both the CPU (g++) and CUDA (nvcc),
// plus the GLM configuration every shared header relies on.
#pragma once

#if defined(__CUDACC__)
#define TRACER_HD __host__ __device__
#define TRACER_INLINE __forceinline__
#else
#define TRACER_HD
#define TRACER_INLINE inline
#endif

#if defined(__CUDACC__)
#include <cuda.h>  // GLM reads CUDA_VERSION to accept nvcc
#ifndef GLM_FORCE_CUDA
#define GLM_FORCE_CUDA
#endif
#endif
#define GLM_FORCE_EXPLICIT_CTOR_OFF
#include <glm/glm.hpp>

#include <cstdint>

namespace tracer {
using glm::vec2;
using glm::vec3;
using glm::vec4;
using glm::ivec3;
using glm::uvec3;
using glm::mat3;
using glm::mat4;

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 0.31830988618379067154f;
constexpr float kInfinity = __builtin_huge_valf();
constexpr uint32_t kInvalid = 0xffffffffu;
}  // namespace tracer
