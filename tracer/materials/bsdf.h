// BSDF evaluation and sampling for the tagged Material, in a local shading frame whose +z is the
// surface normal. Directions point away from the surface. Diffuse and mirror are one-sided
// reflectors (the caller flips the frame to the side of wo); a dielectric keeps the frame's +z on
// the outside so that entering and leaving can be told apart.
#pragma once

#include "core/features.h"
#include "core/sampling.h"
#include "materials/fresnel.h"
#include "materials/material.h"

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

// f(wo, wi) for the non-delta part of the material (zero for delta lobes).
TRACER_HD TRACER_INLINE vec3 bsdf_eval(const Material& m, vec3 wo, vec3 wi) {
  switch (m.type) {
    case MaterialType::kDiffuse:
      if (wo.z <= 0.0f || wi.z <= 0.0f) return vec3(0.0f);
      return m.albedo * kInvPi;
    default:
      return vec3(0.0f);
  }
}

TRACER_HD TRACER_INLINE float bsdf_pdf(const Material& m, vec3 wo, vec3 wi) {
  switch (m.type) {
    case MaterialType::kDiffuse:
      if (wo.z <= 0.0f) return 0.0f;
      return cosine_hemisphere_pdf(wi.z);
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
    case MaterialType::kConductor:  // smooth until GGX lands: Fresnel-free tinted reflection
    case MaterialType::kMirror: {
      if (wo.z <= 0.0f) return s;
      s.wi = vec3(-wo.x, -wo.y, wo.z);
      s.pdf = 1.0f;
      s.weight = m.albedo;
      s.specular = true;
      s.valid = true;
      return s;
    }
    case MaterialType::kSubsurface:  // the boundary is a smooth dielectric
    case MaterialType::kDielectric: {
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
