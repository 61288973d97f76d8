// Fresnel reflectance of smooth interfaces: a dielectric (the exact unpolarised equations and
// Schlick's approximation, Schlick, "An Inexpensive BRDF Model...", 1994), a conductor with a
// complex index of refraction, and the hemispherical averages the coated diffuse model needs.
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

// Unpolarised reflectance of a conductor of complex index eta + i k (relative to the outside
// medium) at incidence cosine cos_i: the exact Fresnel equations written with real numbers (Born
// & Wolf, Principles of Optics, sec. 14.2), where a^2 + b^2 = |eta_c^2 - sin^2| and
// a = Re sqrt(eta_c^2 - sin^2):
//   R_s = (a^2 + b^2 - 2 a cos + cos^2) / (a^2 + b^2 + 2 a cos + cos^2)
//   R_p = R_s ((a^2 + b^2) cos^2 - 2 a cos sin^2 + sin^4) / ((a^2 + b^2) cos^2 + 2 a cos sin^2 +
//   sin^4)
// as pbrt-v3's FrConductor and Mitsuba's fresnelConductorExact evaluate them. With k = 0 this is
// fresnel_dielectric (eta < 1 gives a = 0 beyond the critical angle: total reflection).
TRACER_HD TRACER_INLINE float fresnel_conductor(float cos_i, float eta, float k) {
  cos_i = glm::clamp(cos_i, 0.0f, 1.0f);
  const float cos2 = cos_i * cos_i, sin2 = 1.0f - cos2;
  const float t0 = eta * eta - k * k - sin2;
  const float a2b2 = glm::sqrt(t0 * t0 + 4.0f * eta * eta * k * k);
  const float a = safe_sqrt(0.5f * (a2b2 + t0));
  const float t1 = a2b2 + cos2, t2 = 2.0f * a * cos_i;
  const float rs = t1 + t2 > 0.0f ? (t1 - t2) / (t1 + t2) : 1.0f;
  const float t3 = a2b2 * cos2 + sin2 * sin2, t4 = t2 * sin2;
  const float rp = t3 + t4 > 0.0f ? rs * (t3 - t4) / (t3 + t4) : rs;
  return glm::clamp(0.5f * (rs + rp), 0.0f, 1.0f);
}

TRACER_HD TRACER_INLINE vec3 fresnel_conductor(float cos_i, vec3 eta, vec3 k) {
  return vec3(fresnel_conductor(cos_i, eta.x, k.x), fresnel_conductor(cos_i, eta.y, k.y),
              fresnel_conductor(cos_i, eta.z, k.z));
}

// Hemispherical-cosine average of a dielectric's Fresnel reflectance seen from outside,
// F_avg = int_0^1 F(mu, eta) 2 mu dmu, for eta = n_inside / n_outside > 1, in the classical closed
// form of the integral for unpolarised light (bsdf_test checks it against quadrature). Its terms
// cancel near eta = 1, so it is evaluated in double below eta = 1.1 (float holds 1e-5 above). With
// `schlick`, the average of Schlick's approximation: R0 + (1 - R0) 2 B(2, 6) = R0 + (1 - R0) / 21.
template <typename T>
TRACER_HD TRACER_INLINE T fresnel_average_closed_form(T n) {
  const T one(1), n2 = n * n, n4 = n2 * n2, np = n + one, nm = n - one, n2p = n2 + one;
  const T n4m = n4 - one;
  return T(0.5) + nm * (T(3) * n + one) / (T(6) * np * np) +
         n2 * (n2 - one) * (n2 - one) / (n2p * n2p * n2p) * glm::log(nm / np) -
         T(2) * n * n2 * (n2 + T(2) * n - one) / (n2p * n4m) +
         T(8) * n4 * (n4 + one) / (n2p * n4m * n4m) * glm::log(n);
}

TRACER_HD TRACER_INLINE float fresnel_average(float eta, bool schlick) {
  if (!(eta > 1.0f)) return 0.0f;
  if (schlick) {
    const float r0 = ((eta - 1.0f) / (eta + 1.0f)) * ((eta - 1.0f) / (eta + 1.0f));
    return r0 + (1.0f - r0) * (1.0f / 21.0f);
  }
  return eta < 1.1f ? float(fresnel_average_closed_form(double(eta)))
                    : fresnel_average_closed_form(eta);
}

// The same average seen from inside (diffuse light in a medium of relative index eta > 1 meeting
// its boundary). Energy balance across the interface gives it from the outside one: in
// equilibrium as much flux crosses each way, and radiance inside is eta^2 times that outside, so
// 1 - F_avg,inside = (1 - F_avg,outside) / eta^2. It is 0.596 for eta = 1.5 (mostly total
// internal reflection). Holds for Schlick's variant too, which keeps F equal on both sides.
TRACER_HD TRACER_INLINE float fresnel_average_inside(float eta, bool schlick) {
  if (!(eta > 1.0f)) return 0.0f;
  return 1.0f - (1.0f - fresnel_average(eta, schlick)) / (eta * eta);
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
