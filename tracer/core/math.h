// Small numeric helpers shared by CPU and CUDA: bit casts, error bounds, orthonormal bases and
// the scale-independent ray-origin offset.
#pragma once

#include <cmath>
#include <cstring>

#include "core/hd.h"

namespace tracer {

TRACER_HD TRACER_INLINE int32_t float_as_int(float f) {
#if defined(__CUDA_ARCH__)
  return __float_as_int(f);
#else
  int32_t i;
  std::memcpy(&i, &f, sizeof(f));
  return i;
#endif
}

TRACER_HD TRACER_INLINE float int_as_float(int32_t i) {
#if defined(__CUDA_ARCH__)
  return __int_as_float(i);
#else
  float f;
  std::memcpy(&f, &i, sizeof(f));
  return f;
#endif
}

// Bound on the relative rounding error of n floating-point operations (pbrt-v4, sec. 6.8.1).
TRACER_HD TRACER_INLINE constexpr float gamma_bound(int n) {
  constexpr float kMachineEpsilon = 5.96046448e-08f;  // 2^-24
  return (n * kMachineEpsilon) / (1.0f - n * kMachineEpsilon);
}

TRACER_HD TRACER_INLINE float max_component(vec3 v) { return glm::max(v.x, glm::max(v.y, v.z)); }
TRACER_HD TRACER_INLINE float luminance(vec3 c) {
  return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z;
}
// Square roots, normalisations and sines in the shading and sampling code: on the GPU the
// hardware's approximations (one MUFU instruction each, relative error below 2^-21) instead of
// the correctly rounded library versions, whose Newton refinements and slow-path branches are
// many instructions each (docs/PERFORMANCE.md, decision log). The CPU keeps the exact functions.
// Not used where a bound depends on correct rounding (ray-box and ray-triangle tests, offsets).
TRACER_HD TRACER_INLINE float fast_sqrt(float x) {  // x >= 0
#if defined(__CUDA_ARCH__)
  float r;
  asm("sqrt.approx.f32 %0, %1;" : "=f"(r) : "f"(x));
  return r;
#else
  return std::sqrt(x);
#endif
}
TRACER_HD TRACER_INLINE vec3 fast_normalize(vec3 v) {
#if defined(__CUDA_ARCH__)
  return v * rsqrtf(v.x * v.x + v.y * v.y + v.z * v.z);
#else
  return glm::normalize(v);
#endif
}
TRACER_HD TRACER_INLINE void fast_sincos(float x, float* s, float* c) {  // |x| <= 2 pi
#if defined(__CUDA_ARCH__)
  __sincosf(x, s, c);
#else
  *s = std::sin(x);
  *c = std::cos(x);
#endif
}
// 1 / x: on the GPU the hardware's approximate reciprocal (one MUFU.RCP, 1 ulp, denormals
// flushed; __fdividef's denormal handling would add four instructions). x = 0 gives an infinity,
// x = infinity gives 0.
TRACER_HD TRACER_INLINE float fast_rcp(float x) {
#if defined(__CUDA_ARCH__)
  float r;
  asm("rcp.approx.ftz.f32 %0, %1;" : "=f"(r) : "f"(x));
  return r;
#else
  return 1.0f / x;
#endif
}
// a / b from fast_rcp and one multiply: 2 instructions instead of the correctly rounded
// division's 8 and its slow-path branch. b = 0 gives an infinity (a NaN for a = 0), b = infinity
// gives 0, as a / b does.
TRACER_HD TRACER_INLINE float fast_div(float a, float b) {
#if defined(__CUDA_ARCH__)
  return a * fast_rcp(b);
#else
  return a / b;
#endif
}
TRACER_HD TRACER_INLINE float fast_rsqrt(float x) {  // 1 / sqrt(x), x >= 0
#if defined(__CUDA_ARCH__)
  return rsqrtf(x);
#else
  return 1.0f / std::sqrt(x);
#endif
}
// n / d for quotients below 2^16 (a pixel's row: pixel / width): a float estimate, off by at most
// one (relative error a few 2^-24), then corrected; about a third of the GPU's 32-bit integer
// division.
TRACER_HD TRACER_INLINE uint32_t divide_small(uint32_t n, uint32_t d) {
  uint32_t q = uint32_t(float(n) * fast_rcp(float(d)));
  const int32_t r = int32_t(n - q * d);
  if (r < 0) --q;
  else if (r >= int32_t(d)) ++q;
  return q;
}
TRACER_HD TRACER_INLINE float safe_sqrt(float x) { return fast_sqrt(glm::max(x, 0.0f)); }
TRACER_HD TRACER_INLINE bool is_finite(float x) { return x - x == 0.0f; }
TRACER_HD TRACER_INLINE bool is_finite(vec3 v) {
  return is_finite(v.x) && is_finite(v.y) && is_finite(v.z);
}

// Offsets a ray origin off a surface along the geometric normal n so that the new ray cannot
// re-hit the surface it leaves. The offset is a fixed number of ulps of the position, so it scales
// with the position's magnitude and holds at any scene scale; near the origin, where ulps vanish,
// a tiny absolute offset takes over. Wächter & Binder, "A Fast and Robust Method for Avoiding
// Self-Intersection", Ray Tracing Gems (2019), ch. 6.
TRACER_HD TRACER_INLINE vec3 offset_ray_origin(vec3 p, vec3 n) {
  constexpr float kOrigin = 1.0f / 32.0f;
  constexpr float kFloatScale = 1.0f / 65536.0f;
  constexpr float kIntScale = 256.0f;
  const int32_t ox = int32_t(kIntScale * n.x), oy = int32_t(kIntScale * n.y),
                oz = int32_t(kIntScale * n.z);
  const vec3 pi(int_as_float(float_as_int(p.x) + (p.x < 0 ? -ox : ox)),
                int_as_float(float_as_int(p.y) + (p.y < 0 ? -oy : oy)),
                int_as_float(float_as_int(p.z) + (p.z < 0 ? -oz : oz)));
  return vec3(glm::abs(p.x) < kOrigin ? p.x + kFloatScale * n.x : pi.x,
              glm::abs(p.y) < kOrigin ? p.y + kFloatScale * n.y : pi.y,
              glm::abs(p.z) < kOrigin ? p.z + kFloatScale * n.z : pi.z);
}

// Orthonormal basis from a unit vector without branches on its direction.
// Duff et al., "Building an Orthonormal Basis, Revisited", JCGT 6(1), 2017.
struct Frame {
  vec3 t, b, n;
  TRACER_HD static Frame from_normal(vec3 n) {
    const float sign = glm::sign(n.z) == 0.0f ? 1.0f : glm::sign(n.z);
    const float a = -1.0f / (sign + n.z);
    const float b = n.x * n.y * a;
    Frame f;
    f.t = vec3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    f.b = vec3(b, sign + n.y * n.y * a, -n.y);
    f.n = n;
    return f;
  }
  // A frame whose tangent is `axis` projected onto the plane of n (a field of tangents that is
  // smooth wherever n is, e.g. along the meridians of a sphere about `axis`); from_normal's
  // frame where n is (nearly) parallel to the axis.
  TRACER_HD static Frame from_normal_and_axis(vec3 n, vec3 axis) {
    const vec3 t = axis - glm::dot(axis, n) * n;
    const float len2 = glm::dot(t, t);
    if (!(len2 > 1e-8f)) return from_normal(n);
    Frame f;
    f.t = t / glm::sqrt(len2);
    f.b = glm::cross(n, f.t);
    f.n = n;
    return f;
  }
  TRACER_HD vec3 to_local(vec3 v) const { return vec3(glm::dot(v, t), glm::dot(v, b), glm::dot(v, n)); }
  TRACER_HD vec3 to_world(vec3 v) const { return v.x * t + v.y * b + v.z * n; }
};

}  // namespace tracer
