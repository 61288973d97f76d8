// Fresnel reflectance of a smooth dielectric interface: the exact unpolarised equations and
// Schlick's approximation (Schlick, "An Inexpensive BRDF Model...", 1994).
#pragma once

#include "core/math.h"

namespace tracer {

// cos_i: cosine of the incident angle on the incident side (>= 0); eta = n_transmitted /
// n_incident. Returns 1 under total internal reflection. pbrt-v4 eq. 9.5 and 9.6.
TRACER_HD TRACER_INLINE float fresnel_dielectric(float cos_i, float eta) {
  cos_i = glm::clamp(cos_i, 0.0f, 1.0f);
  const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1.0f) return 1.0f;
  const float cos_t = safe_sqrt(1.0f - sin2_t);
  const float r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  const float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  return 0.5f * (r_parl * r_parl + r_perp * r_perp);
}

// Schlick's approximation, evaluated with the cosine on the optically thinner side so that it is
// symmetric under reversal and reproduces total internal reflection.
TRACER_HD TRACER_INLINE float fresnel_schlick(float cos_i, float eta) {
  cos_i = glm::clamp(cos_i, 0.0f, 1.0f);
  const float r0 = ((eta - 1.0f) / (eta + 1.0f)) * ((eta - 1.0f) / (eta + 1.0f));
  float c = cos_i;
  if (eta < 1.0f) {  // leaving the denser medium: use the transmitted angle
    const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0f) return 1.0f;
    c = safe_sqrt(1.0f - sin2_t);
  }
  const float m = 1.0f - c;
  const float m2 = m * m;
  return r0 + (1.0f - r0) * m2 * m2 * m;
}

// Refracts w (pointing away from the surface, on the side of n) through an interface of relative
// index eta = n_t / n_i. Returns false under total internal reflection.
TRACER_HD TRACER_INLINE bool refract(vec3 w, vec3 n, float eta, vec3& wt) {
  const float cos_i = glm::dot(n, w);
  const float sin2_i = glm::max(0.0f, 1.0f - cos_i * cos_i);
  const float sin2_t = sin2_i / (eta * eta);
  if (sin2_t >= 1.0f) return false;
  const float cos_t = safe_sqrt(1.0f - sin2_t);
  wt = -w / eta + (cos_i / eta - cos_t) * n;
  return true;
}

}  // namespace tracer
