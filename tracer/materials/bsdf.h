// BSDF evaluation and sampling for the tagged Material, in a local shading frame whose +z is the
// surface normal. Directions point away from the surface. Diffuse, mirror and conductor are
// one-sided reflectors (the caller flips the frame to the side of wo); a dielectric keeps the
// frame's +z on the outside so that entering and leaving can be told apart. Rough conductors and
// dielectrics use the GGX microfacet model of microfacet.h.
#pragma once

#include "core/features.h"
#include "core/sampling.h"
#include "materials/fresnel.h"
#include "materials/material.h"
#include "materials/microfacet.h"

namespace tracer {

struct BsdfSample {
  vec3 wi = vec3(0.0f);
  vec3 weight = vec3(0.0f);  // f * |cos(wi)| / pdf
  float pdf = 0.0f;          // solid-angle pdf; for delta lobes the discrete probability
  bool specular = false;     // a delta lobe: no MIS, no light sampling
  bool valid = false;
};

// Whether every lobe of the material is a delta distribution: no light sampling and no MIS at
// its vertices. `type` is the material's type as the caller's feature mask sees it.
TRACER_HD TRACER_INLINE bool bsdf_is_delta(const Material& m, MaterialType type) {
  switch (type) {
    case MaterialType::kDiffuse: return false;
    case MaterialType::kConductor:
    case MaterialType::kDielectric: return m.roughness <= 0.0f;
    case MaterialType::kMirror:
    case MaterialType::kSubsurface: return true;
  }
  return true;
}

// Materials whose lobes may cross the surface (their frame keeps +z on the outside).
TRACER_HD TRACER_INLINE bool bsdf_transmits(MaterialType type) {
  return type == MaterialType::kDielectric || type == MaterialType::kSubsurface;
}

TRACER_HD TRACER_INLINE float material_fresnel(const Material& m, float cos_i, float eta) {
  return (m.flags & kMaterialSchlickFresnel) ? fresnel_schlick(cos_i, eta)
                                             : fresnel_dielectric(cos_i, eta);
}

// Schlick's approximation with an RGB reflectance at normal incidence, F0 + (1 - F0)(1 - cos)^5:
// the glTF metallic model's Fresnel term for conductors (Schlick 1994).
TRACER_HD TRACER_INLINE vec3 fresnel_schlick_f0(vec3 f0, float cos_i) {
  const float c = 1.0f - glm::clamp(cos_i, 0.0f, 1.0f);
  const float c2 = c * c;
  return f0 + (vec3(1.0f) - f0) * (c2 * c2 * c);
}

// ---------------------------------------------------------------------------------------------
// Rough conductor: Cook-Torrance with GGX, f = F(wo.m) D(m) G2(wo, wi) / (4 wo.z wi.z), m the
// half vector (Walter et al. 2007, eq. 20), sampled through the visible normals of wo (Heitz
// 2018), so that pdf(wi) = D_wo(m) / (4 wo.m) (the reflection Jacobian, Walter eq. 14).

TRACER_HD TRACER_INLINE vec3 rough_conductor_eval(const Material& mat, vec3 wo, vec3 wi) {
  if (wo.z <= 0.0f || wi.z <= 0.0f) return vec3(0.0f);
  const vec3 h = wo + wi;
  const float len2 = glm::dot(h, h);
  if (!(len2 > 0.0f)) return vec3(0.0f);
  const vec3 m = h / glm::sqrt(len2);
  const float alpha = ggx_alpha(mat.roughness);
  const float dg = ggx_d(m, alpha) * ggx_g2(wo, wi, alpha) / (4.0f * wo.z * wi.z);
  return fresnel_schlick_f0(mat.albedo, glm::dot(wo, m)) * dg;
}

TRACER_HD TRACER_INLINE float rough_conductor_pdf(const Material& mat, vec3 wo, vec3 wi) {
  if (wo.z <= 0.0f || wi.z <= 0.0f) return 0.0f;
  const vec3 h = wo + wi;
  const float len2 = glm::dot(h, h);
  if (!(len2 > 0.0f)) return 0.0f;
  const vec3 m = h / glm::sqrt(len2);
  const float wo_m = glm::dot(wo, m);
  if (wo_m <= 0.0f) return 0.0f;
  return ggx_vndf_pdf(wo, m, ggx_alpha(mat.roughness)) / (4.0f * wo_m);
}

TRACER_HD TRACER_INLINE BsdfSample conductor_sample(const Material& mat, vec3 wo, vec2 u) {
  BsdfSample s;
  if (wo.z <= 0.0f) return s;
  if (mat.roughness <= 0.0f) {  // smooth: a delta reflection weighted by F(cos theta_o)
    s.wi = vec3(-wo.x, -wo.y, wo.z);
    s.pdf = 1.0f;
    s.weight = fresnel_schlick_f0(mat.albedo, wo.z);
    s.specular = true;
    s.valid = true;
    return s;
  }
  const float alpha = ggx_alpha(mat.roughness);
  const vec3 m = ggx_sample_vndf(wo, alpha, u);
  const float wo_m = glm::dot(wo, m);
  if (wo_m <= 0.0f) return s;
  s.wi = reflect_about(wo, m);
  if (s.wi.z <= 0.0f) return s;  // reflected under the surface: single scattering loses it
  s.pdf = ggx_vndf_pdf(wo, m, alpha) / (4.0f * wo_m);
  if (!(s.pdf > 0.0f)) return s;
  // f cos / pdf: D and the Jacobian cancel, leaving F G2 / G1(wo) (Heitz 2018, sec. 2).
  const float g = ggx_g2(wo, s.wi, alpha) / ggx_g1(wo, alpha);
  s.weight = fresnel_schlick_f0(mat.albedo, wo_m) * g;
  s.valid = true;
  return s;
}

// ---------------------------------------------------------------------------------------------
// Rough dielectric: Walter et al. 2007, "Microfacet Models for Refraction through Rough
// Surfaces" (EGSR), with pbrt-v4's DielectricBxDF as the reference design. +z is the outside;
// wo.z < 0 means wo is inside. eta = n(other side) / n(wo's side) as in the smooth dielectric.
// The microfacet normal of a pair (wo, wi) is the generalised half vector m ~ wo + eta' wi with
// eta' = 1 for reflection (Walter eq. 13) and eta' = eta for transmission (eq. 16), turned to +z.
//   reflection:   f = F D G2 / (4 |wo.z| |wi.z|)                                     (eq. 20)
//   transmission: f = albedo / eta^2 * (1 - F) D G2 |wi.m| |wo.m| /
//                     (|wo.z| |wi.z| (wi.m + wo.m / eta)^2)                           (eq. 21)
// where the 1/eta^2 turns Walter's importance-transport form into radiance, as the smooth
// dielectric's weight does (pbrt-v4 eq. 9.8), and F = F(|wo.m|, eta) (material_fresnel). m is
// drawn from the visible normals of wo seen from its own side (the VNDF of -wo when inside), then
// reflection is chosen with probability F, so
//   pdf = D_wo(m) F / (4 |wo.m|)                                   (reflection Jacobian, eq. 14)
//   pdf = D_wo(m) (1 - F) |wi.m| / (wi.m + wo.m / eta)^2         (transmission Jacobian, eq. 17)

// The generalised half vector of (wo, wi), facing +z; false when the pair cannot be connected by
// one microfacet (a direction sees the back of m, or a degenerate pair).
TRACER_HD TRACER_INLINE bool rough_dielectric_half_vector(vec3 wo, vec3 wi, float eta, vec3& m) {
  if (wo.z == 0.0f || wi.z == 0.0f) return false;
  const bool reflect = wo.z * wi.z > 0.0f;
  const vec3 h = reflect ? wo + wi : wo + eta * wi;
  const float len2 = glm::dot(h, h);
  if (!(len2 > 0.0f)) return false;
  m = h / glm::sqrt(len2);
  if (m.z < 0.0f) m = -m;
  // chi+ of G and of D_wo: each direction must lie on the side of m that faces it.
  return glm::dot(wo, m) * wo.z > 0.0f && glm::dot(wi, m) * wi.z > 0.0f;
}

TRACER_HD TRACER_INLINE vec3 rough_dielectric_eval(const Material& mat, vec3 wo, vec3 wi) {
  const float eta = wo.z > 0.0f ? mat.ior : 1.0f / mat.ior;
  vec3 m;
  if (!rough_dielectric_half_vector(wo, wi, eta, m)) return vec3(0.0f);
  const float alpha = ggx_alpha(mat.roughness);
  const float wo_m = glm::dot(wo, m), wi_m = glm::dot(wi, m);
  const float fr = material_fresnel(mat, glm::abs(wo_m), eta);
  const float dg = ggx_d(m, alpha) * ggx_g2(wo, wi, alpha);
  const float cos_oi = glm::abs(wo.z * wi.z);
  if (wo.z * wi.z > 0.0f) return vec3(fr * dg / (4.0f * cos_oi));
  const float denom = wi_m + wo_m / eta;
  const float ft = (1.0f - fr) * dg * glm::abs(wi_m * wo_m) / (cos_oi * denom * denom);
  return mat.albedo * (ft / (eta * eta));
}

TRACER_HD TRACER_INLINE float rough_dielectric_pdf(const Material& mat, vec3 wo, vec3 wi) {
  const float eta = wo.z > 0.0f ? mat.ior : 1.0f / mat.ior;
  vec3 m;
  if (!rough_dielectric_half_vector(wo, wi, eta, m)) return 0.0f;
  const float alpha = ggx_alpha(mat.roughness);
  const float wo_m = glm::dot(wo, m), wi_m = glm::dot(wi, m);
  const float fr = material_fresnel(mat, glm::abs(wo_m), eta);
  const float pdf_m = ggx_vndf_pdf(wo.z > 0.0f ? wo : -wo, m, alpha);
  if (wo.z * wi.z > 0.0f) return pdf_m * fr / (4.0f * glm::abs(wo_m));
  const float denom = wi_m + wo_m / eta;
  return pdf_m * (1.0f - fr) * glm::abs(wi_m) / (denom * denom);
}

TRACER_HD TRACER_INLINE BsdfSample rough_dielectric_sample(const Material& mat, vec3 wo, vec2 u,
                                                           float uc) {
  BsdfSample s;
  if (wo.z == 0.0f) return s;
  const bool entering = wo.z > 0.0f;
  const float eta = entering ? mat.ior : 1.0f / mat.ior;
  const float alpha = ggx_alpha(mat.roughness);
  // Sample in the frame flipped to wo's side: m faces +z and wo sees its front when outside,
  // its back when inside.
  const vec3 wo_up = entering ? wo : -wo;
  const vec3 m = ggx_sample_vndf(wo_up, alpha, u);
  const float wo_m = glm::dot(wo, m);
  const float cos_o = glm::abs(wo_m);
  if (!(cos_o > 0.0f)) return s;
  const float pdf_m = ggx_vndf_pdf(wo_up, m, alpha);
  const float fr = material_fresnel(mat, cos_o, eta);
  // f |cos| / pdf reduces to G2 / G1(wo) per lobe: D, F (or 1 - F) and the Jacobians cancel.
  const float g1 = ggx_g1(wo, alpha);
  if (uc < fr) {
    s.wi = reflect_about(wo, m);
    if (s.wi.z * wo.z <= 0.0f) return s;  // reflected through the surface: lost
    s.pdf = pdf_m * fr / (4.0f * cos_o);
    s.weight = vec3(ggx_g2(wo, s.wi, alpha) / g1);
  } else {
    vec3 wt;
    if (!refract(wo, wo_m > 0.0f ? m : -m, eta, wt)) return s;  // only when F rounds below 1
    s.wi = glm::normalize(wt);
    if (s.wi.z * wo.z >= 0.0f) return s;  // refracted back to wo's side: lost
    const float wi_m = glm::dot(s.wi, m);
    const float denom = wi_m + wo_m / eta;
    s.pdf = pdf_m * (1.0f - fr) * glm::abs(wi_m) / (denom * denom);
    s.weight = mat.albedo * (ggx_g2(wo, s.wi, alpha) / (g1 * eta * eta));
  }
  s.valid = s.pdf > 0.0f && is_finite(s.pdf);
  return s;
}

// ---------------------------------------------------------------------------------------------
// Dispatch on the material type.

// f(wo, wi) for the non-delta part of the material (zero for delta lobes). F is the feature mask
// as in bsdf_sample: pass the same one to all three so that they agree on the material.
template <uint32_t F = kAllFeatures>
TRACER_HD inline vec3 bsdf_eval(const Material& m, vec3 wo, vec3 wi) {
  const MaterialType type = (F & kFeatureSpecular) ? m.type : MaterialType::kDiffuse;
  switch (type) {
    case MaterialType::kDiffuse:
      if (wo.z <= 0.0f || wi.z <= 0.0f) return vec3(0.0f);
      return m.albedo * kInvPi;
    case MaterialType::kConductor:
      return m.roughness > 0.0f ? rough_conductor_eval(m, wo, wi) : vec3(0.0f);
    case MaterialType::kDielectric:
      return m.roughness > 0.0f ? rough_dielectric_eval(m, wo, wi) : vec3(0.0f);
    default:  // mirror, subsurface (its boundary is always smooth): delta lobes only
      return vec3(0.0f);
  }
}

// Solid-angle density with which bsdf_sample<F> returns wi (zero for delta lobes).
template <uint32_t F = kAllFeatures>
TRACER_HD inline float bsdf_pdf(const Material& m, vec3 wo, vec3 wi) {
  const MaterialType type = (F & kFeatureSpecular) ? m.type : MaterialType::kDiffuse;
  switch (type) {
    case MaterialType::kDiffuse:
      if (wo.z <= 0.0f) return 0.0f;
      return cosine_hemisphere_pdf(wi.z);
    case MaterialType::kConductor:
      return m.roughness > 0.0f ? rough_conductor_pdf(m, wo, wi) : 0.0f;
    case MaterialType::kDielectric:
      return m.roughness > 0.0f ? rough_dielectric_pdf(m, wo, wi) : 0.0f;
    default:
      return 0.0f;
  }
}

// u: two uniform numbers for the direction, uc: one for choosing between lobes. Without
// kFeatureSpecular in F every material is taken to be diffuse.
template <uint32_t F = kAllFeatures>
TRACER_HD inline BsdfSample bsdf_sample(const Material& m, vec3 wo, vec2 u, float uc) {
  BsdfSample s;
  const MaterialType type = (F & kFeatureSpecular) ? m.type : MaterialType::kDiffuse;
  switch (type) {
    case MaterialType::kDiffuse: {
      if (wo.z <= 0.0f) return s;
      s.wi = sample_cosine_hemisphere(u);
      s.pdf = cosine_hemisphere_pdf(s.wi.z);
      if (s.pdf <= 0.0f) return s;
      s.weight = m.albedo;  // (albedo/pi) * cos / (cos/pi)
      s.valid = true;
      return s;
    }
    case MaterialType::kConductor:
      return conductor_sample(m, wo, u);
    case MaterialType::kMirror: {
      if (wo.z <= 0.0f) return s;
      s.wi = vec3(-wo.x, -wo.y, wo.z);
      s.pdf = 1.0f;
      s.weight = m.albedo;
      s.specular = true;
      s.valid = true;
      return s;
    }
    case MaterialType::kDielectric:
      if (m.roughness > 0.0f) return rough_dielectric_sample(m, wo, u, uc);
      [[fallthrough]];
    case MaterialType::kSubsurface: {  // the boundary is a smooth dielectric
      // Sample reflection with probability F and refraction with 1 - F, so the weights are the
      // tint alone: R + T = 1 is conserved exactly (pbrt-v4 sec. 9.5.2).
      const bool entering = wo.z > 0.0f;
      const float eta = entering ? m.ior : 1.0f / m.ior;  // n_transmitted / n_incident
      const float cos_o = glm::abs(wo.z);
      const float fr = material_fresnel(m, cos_o, eta);
      s.specular = true;
      s.valid = true;
      if (uc < fr) {
        s.wi = vec3(-wo.x, -wo.y, wo.z);
        s.pdf = fr;
        s.weight = vec3(1.0f);
        return s;
      }
      const vec3 n = vec3(0.0f, 0.0f, entering ? 1.0f : -1.0f);
      vec3 wt;
      if (!refract(wo, n, eta, wt)) {  // cannot happen when fr < 1, but rounding may disagree
        s.wi = vec3(-wo.x, -wo.y, wo.z);
        s.pdf = 1.0f;
        s.weight = vec3(1.0f);
        return s;
      }
      s.wi = glm::normalize(wt);
      s.pdf = 1.0f - fr;
      // Radiance is compressed by eta^2 when it crosses into a denser medium (pbrt-v4 eq. 9.8).
      s.weight = m.albedo / (eta * eta);
      return s;
    }
  }
  return s;
}

// Radiance emitted towards a viewer on the `front` side (geometric normal side) or behind it.
TRACER_HD TRACER_INLINE vec3 material_emission(const Material& m, bool front) {
  if (front || (m.flags & kMaterialTwoSidedEmission)) return m.emission;
  return vec3(0.0f);
}

}  // namespace tracer
