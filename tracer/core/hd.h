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

// The CPU backend's hot loops (the render rows, the SSE traversal) are compiled twice, for
// x86-64-v3 (AVX2, FMA, BMI) and for baseline x86-64, and the loader picks one per machine
// (GCC function multi-versioning, an ifunc), as Cycles compiles its kernel per instruction set.
// `flatten` inlines the whole call tree into each version, so header code runs with the
// version's instructions and no inline function is shared between the two (no ODR clash); the
// files that use it build with -ffp-contract=off, so both versions compute the same numbers.
#if defined(__GNUC__) && !defined(__clang__) && !defined(__CUDACC__) && defined(__x86_64__) && \
    !defined(TRACER_NO_MULTIVERSION)
#define TRACER_CPU_MULTIVERSION __attribute__((target_clones("arch=x86-64-v3", "default"), flatten))
#else
#define TRACER_CPU_MULTIVERSION
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
