// Warping functions from the unit square to the shapes the integrator samples, each with its pdf.
// Every one is chi-square tested against its pdf in tests/sampling_test.cpp.
#pragma once

#include "core/math.h"

namespace tracer {

// Shirley & Chiu's concentric map from [0,1)^2 to the unit disk (pbrt-v4, sec. A.5.1).
TRACER_HD TRACER_INLINE vec2 sample_uniform_disk_concentric(vec2 u) {
  const vec2 o = 2.0f * u - vec2(1.0f);
  if (o.x == 0.0f && o.y == 0.0f) return vec2(0.0f);
  float r, theta;
  if (glm::abs(o.x) > glm::abs(o.y)) {
    r = o.x;
    theta = 0.25f * kPi * fast_div(o.y, o.x);
  } else {
    r = o.y;
    theta = 0.5f * kPi - 0.25f * kPi * fast_div(o.x, o.y);
  }
  float s, c;
  fast_sincos(theta, &s, &c);
  return r * vec2(c, s);
}
TRACER_HD TRACER_INLINE float uniform_disk_pdf() { return kInvPi; }

// Malley's method: cosine-weighted directions about +z, pdf = cos(theta)/pi.
TRACER_HD TRACER_INLINE vec3 sample_cosine_hemisphere(vec2 u) {
  const vec2 d = sample_uniform_disk_concentric(u);
  const float z = safe_sqrt(1.0f - d.x * d.x - d.y * d.y);
  return vec3(d.x, d.y, z);
}
TRACER_HD TRACER_INLINE float cosine_hemisphere_pdf(float cos_theta) {
  return cos_theta > 0.0f ? cos_theta * kInvPi : 0.0f;
}

TRACER_HD TRACER_INLINE vec3 sample_uniform_sphere(vec2 u) {
  const float z = 1.0f - 2.0f * u.x;
  const float r = safe_sqrt(1.0f - z * z);
  const float phi = 2.0f * kPi * u.y;
  return vec3(r * glm::cos(phi), r * glm::sin(phi), z);
}
TRACER_HD TRACER_INLINE float uniform_sphere_pdf() { return 1.0f / (4.0f * kPi); }

TRACER_HD TRACER_INLINE vec3 sample_uniform_hemisphere(vec2 u) {
  const float z = u.x;
  const float r = safe_sqrt(1.0f - z * z);
  const float phi = 2.0f * kPi * u.y;
  return vec3(r * glm::cos(phi), r * glm::sin(phi), z);
}
TRACER_HD TRACER_INLINE float uniform_hemisphere_pdf() { return 1.0f / (2.0f * kPi); }

// Uniform directions inside the cone of half-angle acos(cos_max) about +z; used to sample the
// solid angle a sphere light subtends (pbrt-v4, sec. 6.2.4).
TRACER_HD TRACER_INLINE vec3 sample_uniform_cone(vec2 u, float cos_max) {
  const float cos_t = (1.0f - u.x) + u.x * cos_max;
  const float sin_t = safe_sqrt(1.0f - cos_t * cos_t);
  const float phi = 2.0f * kPi * u.y;
  return vec3(sin_t * glm::cos(phi), sin_t * glm::sin(phi), cos_t);
}
TRACER_HD TRACER_INLINE float uniform_cone_pdf(float cos_max) {
  return 1.0f / (2.0f * kPi * (1.0f - cos_max));
}

// Uniform barycentrics (b0, b1) over a triangle; b2 = 1 - b0 - b1. Uses the square-root warp
// (Osada et al. 2002, pbrt-v4 sec. A.5.5); pdf = 1/area.
TRACER_HD TRACER_INLINE vec2 sample_uniform_triangle(vec2 u) {
  const float su0 = fast_sqrt(u.x);
  return vec2(1.0f - su0, u.y * su0);
}

// Veach's power heuristic with beta = 2 (Veach 1997, sec. 9.2.4).
TRACER_HD TRACER_INLINE float power_heuristic(float pdf_a, float pdf_b) {
  const float a = pdf_a * pdf_a, b = pdf_b * pdf_b;
  if (a == 0.0f) return 0.0f;
  if (!is_finite(a)) return 1.0f;
  return fast_div(a, a + b);
}

}  // namespace tracer
