// The GGX (Trowbridge-Reitz) microfacet distribution, anisotropic with roughnesses alpha.x along
// the frame's tangent (x) and alpha.y along its bitangent (y): normal distribution D, Smith masking
// Lambda/G1, height-correlated masking-shadowing G2 and the sampling of visible normals. The
// isotropic case is alpha.x = alpha.y (the float overloads). Shared by the rough conductor, the
// rough dielectric and the coated diffuse's coat in bsdf.h. Local frame: +z = macro normal.
#pragma once

#include "core/math.h"

namespace tracer {

// Floor on alpha: D peaks at 1/(pi alpha^2), and below ~1e-4 that peak is narrower than the float
// rounding of a half vector, so evaluation stops meaning anything. A roughness of exactly 0 never
// gets here (bsdf.h keeps its smooth delta lobes); the floor only affects roughness < 1e-2.
constexpr float kMinGgxAlpha = 1e-4f;

// alpha = roughness^2, the perceptual mapping of Burley (2012) that glTF also uses.
TRACER_HD TRACER_INLINE float ggx_alpha(float roughness) {
  return glm::max(roughness * roughness, kMinGgxAlpha);
}

// D(m) = 1 / (pi ax ay (m.x^2 / ax^2 + m.y^2 / ay^2 + m.z^2)^2) for m.z > 0: Walter et al. 2007,
// eq. 33 in the isotropic case (1 / (pi a^2 cos^4 (1 + tan^2 / a^2)^2)), written without tangents,
// which stays finite at grazing m and at tiny alpha; the anisotropic form is Heitz 2014's
// ("Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs", JCGT 3(2)).
TRACER_HD TRACER_INLINE float ggx_d(vec3 m, vec2 alpha) {
  if (m.z <= 0.0f) return 0.0f;
  const float x = m.x / alpha.x, y = m.y / alpha.y;
  const float t = x * x + y * y + m.z * m.z;
  return 1.0f / (kPi * alpha.x * alpha.y * t * t);
}
TRACER_HD TRACER_INLINE float ggx_d(vec3 m, float alpha) {
  return ggx_d(m, vec2(alpha));
}

// Smith's Lambda for GGX, Lambda(w) = (-1 + sqrt(1 + alpha(w)^2 tan^2(theta))) / 2, where the
// anisotropic alpha(w)^2 tan^2 = (ax^2 w.x^2 + ay^2 w.y^2) / w.z^2 (Heitz 2014, where alpha(w)
// is the roughness projected onto w's azimuth; the G1 below is Walter et al. 2007, eq. 34).
// Evaluated as x / (2 (1 + sqrt(1 + x))) to avoid cancellation at small x.
// Depends on w only through x, so it is the same for w and -w.
TRACER_HD TRACER_INLINE float ggx_lambda(vec3 w, vec2 alpha) {
  const float z2 = w.z * w.z;
  const float ax = alpha.x * w.x, ay = alpha.y * w.y;
  const float xy2 = ax * ax + ay * ay;
  if (xy2 <= 0.0f) return 0.0f;
  if (z2 <= 0.0f) return kInfinity;
  const float x = xy2 / z2;
  return x / (2.0f * (1.0f + glm::sqrt(1.0f + x)));
}
TRACER_HD TRACER_INLINE float ggx_lambda(vec3 w, float alpha) {
  return ggx_lambda(w, vec2(alpha));
}

// Smith masking G1(w) = 1 / (1 + Lambda(w)) (Heitz 2014), without the chi+(w.m)
// back-facing test, which the callers apply.
TRACER_HD TRACER_INLINE float ggx_g1(vec3 w, vec2 alpha) {
  return 1.0f / (1.0f + ggx_lambda(w, alpha));
}
TRACER_HD TRACER_INLINE float ggx_g1(vec3 w, float alpha) {
  return ggx_g1(w, vec2(alpha));
}

// Height-correlated masking-shadowing G2(wo, wi) = 1 / (1 + Lambda(wo) + Lambda(wi)) (Heitz 2014),
// again without the chi+ tests. For transmission the same form is used, as pbrt-v4 does
// (Heitz derives a Beta-function form for the height-correlated transmissive case); it is
// symmetric in wo and wi, which reciprocity needs.
TRACER_HD TRACER_INLINE float ggx_g2(vec3 wo, vec3 wi, vec2 alpha) {
  return 1.0f / (1.0f + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha));
}
TRACER_HD TRACER_INLINE float ggx_g2(vec3 wo, vec3 wi, float alpha) {
  return ggx_g2(wo, wi, vec2(alpha));
}

// Density of the normals visible from w (w.z > 0), per solid angle of m:
// D_w(m) = G1(w) max(0, w.m) D(m) / w.z (Heitz 2018, "Sampling the GGX Distribution of Visible
// Normals", JCGT 7(4), eq. 1; Heitz & d'Eon 2014). It integrates to 1 over m (the weak white
// furnace test of Heitz 2014).
TRACER_HD TRACER_INLINE float ggx_vndf_pdf(vec3 w, vec3 m, vec2 alpha) {
  if (w.z <= 0.0f) return 0.0f;
  const float wm = glm::dot(w, m);
  if (wm <= 0.0f) return 0.0f;
  return ggx_g1(w, alpha) * wm * ggx_d(m, alpha) / w.z;
}
TRACER_HD TRACER_INLINE float ggx_vndf_pdf(vec3 w, vec3 m, float alpha) {
  return ggx_vndf_pdf(w, m, vec2(alpha));
}

// Draws m with density ggx_vndf_pdf(w, m) for w.z >= 0: Heitz 2018, "Sampling the GGX
// Distribution of Visible Normals", JCGT 7(4), Listing 1 (which is anisotropic). Stretch w to the
// configuration where alpha = 1 (sec. 3.2), sample the projected area of the hemisphere as a disk
// whose upper half is squashed by (1 + w_h.z) / 2 (sec. 4.2), lift the point onto the hemisphere
// (sec. 4.3) and unstretch the normal (sec. 3.4).
TRACER_HD TRACER_INLINE vec3 ggx_sample_vndf(vec3 w, vec2 alpha, vec2 u) {
  const vec3 wh = glm::normalize(vec3(alpha.x * w.x, alpha.y * w.y, w.z));
  const float len2 = wh.x * wh.x + wh.y * wh.y;
  const vec3 t1 = len2 > 0.0f ? vec3(-wh.y, wh.x, 0.0f) / glm::sqrt(len2) : vec3(1.0f, 0.0f, 0.0f);
  const vec3 t2 = glm::cross(wh, t1);
  const float r = glm::sqrt(u.x);
  const float phi = 2.0f * kPi * u.y;
  const float p1 = r * glm::cos(phi);
  float p2 = r * glm::sin(phi);
  const float s = 0.5f * (1.0f + wh.z);
  p2 = (1.0f - s) * safe_sqrt(1.0f - p1 * p1) + s * p2;
  const vec3 nh = p1 * t1 + p2 * t2 + safe_sqrt(1.0f - p1 * p1 - p2 * p2) * wh;
  return glm::normalize(vec3(alpha.x * nh.x, alpha.y * nh.y, glm::max(0.0f, nh.z)));
}
TRACER_HD TRACER_INLINE vec3 ggx_sample_vndf(vec3 w, float alpha, vec2 u) {
  return ggx_sample_vndf(w, vec2(alpha), u);
}

// Mirror reflection of w about the unit normal m.
TRACER_HD TRACER_INLINE vec3 reflect_about(vec3 w, vec3 m) {
  return 2.0f * glm::dot(w, m) * m - w;
}

}  // namespace tracer
