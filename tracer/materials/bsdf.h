// BSDF evaluation and sampling for the tagged Material, in a local shading frame whose +z is the
// surface normal. Directions point away from the surface. Diffuse, mirror, conductor and coated
// diffuse are one-sided reflectors (the caller flips the frame to the side of wo); a dielectric
// keeps the frame's +z on the outside so that entering and leaving can be told apart, and a
// diffuse transmitter does too (it is the same from both sides). Rough conductors, dielectrics and
// coats use the GGX microfacet model of microfacet.h.
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
    case MaterialType::kDiffuse:
    case MaterialType::kCoatedDiffuse:  // a smooth coat's delta lobe sits over a diffuse one
    case MaterialType::kDiffuseTransmission: return false;
    case MaterialType::kConductor: return m.roughness <= 0.0f && m.roughness_v <= 0.0f;
    case MaterialType::kDielectric: return m.roughness <= 0.0f;
    case MaterialType::kMirror:
    case MaterialType::kSubsurface: return true;
  }
  return true;
}

// Materials whose lobes may cross the surface (their frame keeps +z on the outside).
TRACER_HD TRACER_INLINE bool bsdf_transmits(MaterialType type) {
  return type == MaterialType::kDielectric || type == MaterialType::kSubsurface ||
         type == MaterialType::kDiffuseTransmission;
}

// Materials whose bsdf_sample chooses between lobes with its third random number `uc` (the
// others ignore it, and the integrator does not draw it for them).
TRACER_HD TRACER_INLINE bool bsdf_chooses_lobe(MaterialType type) {
  return type == MaterialType::kDielectric || type == MaterialType::kSubsurface ||
         type == MaterialType::kCoatedDiffuse || type == MaterialType::kDiffuseTransmission;
}

// The world +y axis: anisotropic roughness runs its u (tangent) direction along this axis
// projected onto the surface, and v around it (on a sphere about y: u along the meridians, v
// along the parallels). Meshes carry no tangents yet, so this is the one convention for all.
constexpr vec3 kAnisotropyAxis = vec3(0.0f, 1.0f, 0.0f);

// The local shading frame at unit normal n: any orthonormal frame for isotropic lobes, the frame
// whose tangent follows kAnisotropyAxis for anisotropic ones (with it, eval, pdf and sample
// agree between light sampling and BSDF sampling, which share the frame).
TRACER_HD TRACER_INLINE Frame bsdf_frame(const Material& m, MaterialType type, vec3 n) {
  if (type == MaterialType::kConductor && m.is_anisotropic())
    return Frame::from_normal_and_axis(n, kAnisotropyAxis);
  return Frame::from_normal(n);
}

// Light tracing's glossy casters: narrow glossy metals (roughness below
// kLightTraceMetalRoughness, where the path tracer's wide lobes begin) and rough glass below
// kLightTraceGlassRoughness. A gold ball's highlight and a frosted ball's blurred focus light the
// walls through a small spot that a wall's BSDF samples find only by chance; light paths find it
// from the light. A light path may start its chain there as at a delta event, and on the camera's
// side such a vertex past the camera's leaves the area lights to the light tracer
// (integrator/path.h, shade_path: no area-light sampling there, and the area light its sample
// reaches is not added; the other lights as anywhere). Neither kind joins the camera
// (light_trace_connects): a connection through a narrow lobe is a firefly.
constexpr float kLightTraceMetalRoughness = 0.3f;  // = kGuideMinRoughness (integrator/guide.h)
constexpr float kLightTraceGlassRoughness = 0.5f;
TRACER_HD TRACER_INLINE bool light_trace_glossy_caster(const Material& m, MaterialType type) {
  if (type == MaterialType::kConductor)
    return glm::max(m.roughness, m.roughness_bitangent()) > 0.0f &&
           glm::min(m.roughness, m.roughness_bitangent()) < kLightTraceMetalRoughness;
  return type == MaterialType::kDielectric && m.roughness > 0.0f &&
         m.roughness < kLightTraceGlassRoughness;
}

// Whether a light path's chain may start at a surface of material m (its first event, which must
// be a delta event or a glossy caster): a delta BSDF but a subsurface material's boundary (which
// stops light paths), a smooth coat's lobe, a glossy caster, or any textured material (textures
// may make it smooth metal per texel).
TRACER_HD TRACER_INLINE bool light_path_may_start_at(const Material& m) {
  return m.has_textures() || (bsdf_is_delta(m, m.type) && m.type != MaterialType::kSubsurface) ||
         (m.type == MaterialType::kCoatedDiffuse && m.roughness <= 0.0f) ||
         light_trace_glossy_caster(m, m.type);
}

TRACER_HD TRACER_INLINE float material_fresnel(const Material& m, float cos_i, float eta) {
  return (m.flags & kMaterialSchlickFresnel) ? fresnel_schlick(cos_i, eta)
                                             : fresnel_dielectric(cos_i, eta);
}

// What a smooth dielectric's refraction carries, as its BSDF samples it (the tint, 1 - F and
// 1 / eta^2 on the side the ray arrives from), for a ray whose cosine with the outward normal is
// c_out (positive: from outside). Manifold NEE's checks and light tracing's windows weigh the
// refractions they find by it, so that they and the path tracer split paths on equal terms.
TRACER_HD TRACER_INLINE vec3 smooth_transmission(const Material& m, float c_out) {
  const float eta = c_out > 0.0f ? m.ior : 1.0f / m.ior;
  return m.albedo * ((1.0f - material_fresnel(m, glm::abs(c_out), eta)) / (eta * eta));
}

// Schlick's approximation with an RGB reflectance at normal incidence, F0 + (1 - F0)(1 - cos)^5:
// the glTF metallic model's Fresnel term for conductors (Schlick 1994).
TRACER_HD TRACER_INLINE vec3 fresnel_schlick_f0(vec3 f0, float cos_i) {
  const float c = 1.0f - glm::clamp(cos_i, 0.0f, 1.0f);
  const float c2 = c * c;
  return f0 + (vec3(1.0f) - f0) * (c2 * c2 * c);
}

// ---------------------------------------------------------------------------------------------
// Conductor: Fresnel either Schlick's with F0 = albedo (the glTF metallic model) or the exact
// equations of a complex index eta + i k per channel (kMaterialConductorIor, tinted by albedo).
// Rough: Cook-Torrance with anisotropic GGX (alpha.x from roughness along the frame's tangent,
// alpha.y from roughness_v along its bitangent), f = F(wo.m) D(m) G2(wo, wi) / (4 wo.z wi.z), m the
// half vector (Walter et al. 2007, eq. 20), sampled through the visible normals of wo (Heitz
// 2018), so that pdf(wi) = D_wo(m) / (4 wo.m) (the reflection Jacobian, Walter eq. 14).

TRACER_HD TRACER_INLINE vec3 conductor_fresnel(const Material& mat, float cos_i) {
  if (mat.flags & kMaterialConductorIor)
    return mat.albedo * fresnel_conductor(cos_i, mat.eta, mat.k);
  return fresnel_schlick_f0(mat.albedo, cos_i);
}

// The materials manifold NEE connects through (integrator/path.h) and the scene lists as flat
// reflectors (scene/compiled_scene.cpp): smooth glass without textures, which refracts and
// reflects by Fresnel alone; and smooth reflectors (a mirror, a smooth conductor), whose
// reflectance at cosine c is mnee_mirror_reflectance's (black for any other material).
TRACER_HD TRACER_INLINE bool mnee_glass(const Material& m) {
  return m.type == MaterialType::kDielectric && m.roughness <= 0.0f && !m.has_textures();
}
TRACER_HD TRACER_INLINE vec3 mnee_mirror_reflectance(const Material& m, float c) {
  if (m.has_textures()) return vec3(0.0f);
  if (m.type == MaterialType::kMirror) return m.albedo;
  if (m.type == MaterialType::kConductor && bsdf_is_delta(m, m.type))
    return conductor_fresnel(m, c);
  return vec3(0.0f);
}
// What manifold NEE reflects off as a flat reflector: smooth glass (its Fresnel reflection) or a
// smooth reflector.
TRACER_HD TRACER_INLINE bool mnee_flat_reflector(const Material& m) {
  return mnee_glass(m) || max_component(mnee_mirror_reflectance(m, 1.0f)) > 0.0f;
}

TRACER_HD TRACER_INLINE vec2 conductor_alpha(const Material& mat) {
  return vec2(ggx_alpha(mat.roughness), ggx_alpha(mat.roughness_bitangent()));
}

TRACER_HD TRACER_INLINE vec3 rough_conductor_eval(const Material& mat, vec3 wo, vec3 wi) {
  if (wo.z <= 0.0f || wi.z <= 0.0f) return vec3(0.0f);
  const vec3 h = wo + wi;
  const float len2 = glm::dot(h, h);
  if (!(len2 > 0.0f)) return vec3(0.0f);
  const vec3 m = h / glm::sqrt(len2);
  const vec2 alpha = conductor_alpha(mat);
  const float dg = ggx_d(m, alpha) * ggx_g2(wo, wi, alpha) / (4.0f * wo.z * wi.z);
  return conductor_fresnel(mat, glm::dot(wo, m)) * dg;
}

TRACER_HD TRACER_INLINE float rough_conductor_pdf(const Material& mat, vec3 wo, vec3 wi) {
  if (wo.z <= 0.0f || wi.z <= 0.0f) return 0.0f;
  const vec3 h = wo + wi;
  const float len2 = glm::dot(h, h);
  if (!(len2 > 0.0f)) return 0.0f;
  const vec3 m = h / glm::sqrt(len2);
  const float wo_m = glm::dot(wo, m);
  if (wo_m <= 0.0f) return 0.0f;
  return ggx_vndf_pdf(wo, m, conductor_alpha(mat)) / (4.0f * wo_m);
}

TRACER_HD TRACER_INLINE BsdfSample conductor_sample(const Material& mat, vec3 wo, vec2 u) {
  BsdfSample s;
  if (wo.z <= 0.0f) return s;
  if (mat.roughness <= 0.0f && mat.roughness_v <= 0.0f) {  // smooth: a delta reflection, F(cos)
    s.wi = vec3(-wo.x, -wo.y, wo.z);
    s.pdf = 1.0f;
    s.weight = conductor_fresnel(mat, wo.z);
    s.specular = true;
    s.valid = true;
    return s;
  }
  const vec2 alpha = conductor_alpha(mat);
  const vec3 m = ggx_sample_vndf(wo, alpha, u);
  const float wo_m = glm::dot(wo, m);
  if (wo_m <= 0.0f) return s;
  s.wi = reflect_about(wo, m);
  if (s.wi.z <= 0.0f) return s;  // reflected under the surface: single scattering loses it
  s.pdf = ggx_vndf_pdf(wo, m, alpha) / (4.0f * wo_m);
  if (!(s.pdf > 0.0f)) return s;
  // f cos / pdf: D and the Jacobian cancel, leaving F G2 / G1(wo) (Heitz 2018, sec. 2).
  const float g = ggx_g2(wo, s.wi, alpha) / ggx_g1(wo, alpha);
  s.weight = conductor_fresnel(mat, wo_m) * g;
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
// Coated diffuse ("plastic"): a dielectric coat of index eta = ior over a Lambertian base of
// reflectance rho = albedo, in the closed form of Tungsten's plastic and rough_plastic (Bitterli;
// the renderer of the shared scenes' references) and of Mitsuba 0.5's plastic with its
// "nonlinear" term (cf. Weidlich & Wilkie 2007, "Arbitrarily layered micro-facet surfaces", for
// layers in general). Two lobes:
//   coat: the interface's reflection, F(wo.z) as a delta lobe when smooth, or the rough
//         dielectric's reflection F(wo.m) D G2 / (4 wo.z wi.z) with isotropic GGX roughness;
//   base: f = rho (1 - F(wo.z)) (1 - F(wi.z)) T(wo) T(wi) / (pi eta^2 (1 - rho F_in)),
// where F_in = fresnel_average_inside(eta) is the share of the base's diffuse light that the coat
// reflects back down, so 1 / (1 - rho F_in) sums the bounces between base and coat, and
// T(w) = exp(-absorption thickness / cos_t(w)) is the coat's Beer-Lambert transmittance along the
// refracted direction (cos_t = sqrt(1 - (1 - w.z^2) / eta^2); Tungsten divides by the outside
// cosines instead, which blackens grazing angles). 1 / eta^2 is the radiance compression across
// the interface.
// Error: for a smooth, clear coat the base term is exact, since a Lambertian base re-emits
// uniformly whatever the coat sends back: with rho = 1 the directional albedo is
// F + (1 - F) (1 - F_avg,outside) / (eta^2 (1 - F_in)) = F + (1 - F) = 1, energy conserved (the
// thin-layer idealisation: no lateral offset, no scattering in the coat). Two approximations:
// (1) with absorption, the light the coat reflects back to the base is not attenuated on its extra
// passes, so the base term is slightly too bright (the loss is exact for a single pass);
// (2) a rough coat transmits 1 - F(wo.z) of the smooth interface into the base while its own lobe
// reflects the rough dielectric's directional albedo, which masking and directions under the
// horizon reduce toward grazing, so a white base loses energy there (it never gains more than
// 0.02%): at roughness 0.3, 0.3% up to 60 degrees, 5% at 75, 27% at 85, 1.2% averaged over the
// hemisphere; at roughness 1, 2.7% at normal incidence and 7% averaged (coated_diffuse_test
// prints the table). The model is reciprocal (symmetric in wo and wi).
// Sampling: the coat lobe with probability P = F / (F + (1 - F) B), B the base's albedo
// (1 - F_in) rho / (1 - rho F_in) averaged over the channels and attenuated by T(wo)^2; the base
// by the cosine. pdf is the mixture, so a rough coat's samples carry f cos / pdf of both lobes.

TRACER_HD TRACER_INLINE vec3 coat_transmittance(const Material& mat, float cos_w) {
  if (!(max_component(mat.absorption) > 0.0f)) return vec3(1.0f);
  const float sin2_t = (1.0f - cos_w * cos_w) / (mat.ior * mat.ior);
  const float cos_t = safe_sqrt(1.0f - sin2_t);
  return glm::exp(-mat.absorption * (mat.thickness / glm::max(cos_t, 1e-4f)));
}

// What a coated diffuse's eval, pdf and sample share at one wo: the inside average F_in, the
// coat's Fresnel F(wo.z) and transmittance T(wo), and the probability P of the coat lobe.
struct CoatAtWo {
  float f_in, f_o, p;
  vec3 t_o;
};

TRACER_HD TRACER_INLINE CoatAtWo coat_at_wo(const Material& mat, vec3 wo) {
  CoatAtWo c;
  c.f_in = fresnel_average_inside(mat.ior, (mat.flags & kMaterialSchlickFresnel) != 0);
  c.f_o = material_fresnel(mat, wo.z, mat.ior);
  c.t_o = coat_transmittance(mat, wo.z);
  const vec3 base =
      mat.albedo * (1.0f - c.f_in) / (vec3(1.0f) - mat.albedo * c.f_in) * c.t_o * c.t_o;
  const float b = (1.0f - c.f_o) * (base.x + base.y + base.z) * (1.0f / 3.0f);
  c.p = c.f_o + b > 0.0f ? c.f_o / (c.f_o + b) : 1.0f;
  return c;
}

// f(wo, wi) of the non-delta lobes (both above the surface) and the density of sampling wi.
TRACER_HD TRACER_INLINE vec3 coated_diffuse_eval_pdf(const Material& mat, const CoatAtWo& c,
                                                     vec3 wo, vec3 wi, float* pdf) {
  *pdf = 0.0f;
  if (wo.z <= 0.0f || wi.z <= 0.0f) return vec3(0.0f);
  const float f_i = material_fresnel(mat, wi.z, mat.ior);
  const vec3 bounces = mat.albedo / (vec3(1.0f) - mat.albedo * c.f_in);
  vec3 f = bounces * ((1.0f - c.f_o) * (1.0f - f_i) * kInvPi / (mat.ior * mat.ior)) * c.t_o *
           coat_transmittance(mat, wi.z);
  *pdf = (1.0f - c.p) * cosine_hemisphere_pdf(wi.z);
  if (mat.roughness > 0.0f) {  // the rough coat's reflection, sampled through wo's visible normals
    const vec3 h = wo + wi;
    const float len2 = glm::dot(h, h);
    if (!(len2 > 0.0f)) return f;
    const vec3 m = h / glm::sqrt(len2);
    const float wo_m = glm::dot(wo, m);
    if (wo_m <= 0.0f) return f;
    const float alpha = ggx_alpha(mat.roughness);
    *pdf += c.p * ggx_vndf_pdf(wo, m, alpha) / (4.0f * wo_m);
    f += vec3(material_fresnel(mat, wo_m, mat.ior) * ggx_d(m, alpha) * ggx_g2(wo, wi, alpha) /
              (4.0f * wo.z * wi.z));
  }
  return f;
}

TRACER_HD TRACER_INLINE vec3 coated_diffuse_eval(const Material& mat, vec3 wo, vec3 wi) {
  if (wo.z <= 0.0f || wi.z <= 0.0f) return vec3(0.0f);
  float pdf;
  return coated_diffuse_eval_pdf(mat, coat_at_wo(mat, wo), wo, wi, &pdf);
}

TRACER_HD TRACER_INLINE float coated_diffuse_pdf(const Material& mat, vec3 wo, vec3 wi) {
  if (wo.z <= 0.0f || wi.z <= 0.0f) return 0.0f;
  float pdf;
  coated_diffuse_eval_pdf(mat, coat_at_wo(mat, wo), wo, wi, &pdf);
  return pdf;
}

TRACER_HD TRACER_INLINE BsdfSample coated_diffuse_sample(const Material& mat, vec3 wo, vec2 u,
                                                         float uc) {
  BsdfSample s;
  if (wo.z <= 0.0f) return s;
  const CoatAtWo c = coat_at_wo(mat, wo);
  const bool coat = uc < c.p;
  if (coat && mat.roughness <= 0.0f) {  // the smooth coat's mirror reflection, weight F / P
    s.wi = vec3(-wo.x, -wo.y, wo.z);
    s.pdf = c.p;
    s.weight = vec3(c.f_o / c.p);
    s.specular = true;
    s.valid = true;
    return s;
  }
  if (coat) {
    s.wi = reflect_about(wo, ggx_sample_vndf(wo, ggx_alpha(mat.roughness), u));
  } else {
    s.wi = sample_cosine_hemisphere(u);
  }
  if (s.wi.z <= 0.0f) return s;
  const vec3 f = coated_diffuse_eval_pdf(mat, c, wo, s.wi, &s.pdf);
  if (!(s.pdf > 0.0f)) return s;
  s.weight = f * (s.wi.z / s.pdf);
  s.valid = is_finite(s.weight);
  return s;
}

// ---------------------------------------------------------------------------------------------
// Diffuse transmission (thin sheets, lampshades, leaves): Lambertian on both sides,
// f = albedo / pi for wi on wo's side and transmittance / pi on the other (pbrt-v4's
// DiffuseTransmissionBxDF). Reciprocal; conserves energy when albedo + transmittance <= 1 per
// channel. The side is chosen with probability proportional to the mean of each colour, then the
// direction by the cosine on that side.

TRACER_HD TRACER_INLINE float diffuse_reflect_probability(const Material& mat) {
  const float r = mat.albedo.x + mat.albedo.y + mat.albedo.z;
  const float t = mat.transmittance.x + mat.transmittance.y + mat.transmittance.z;
  return r + t > 0.0f ? r / (r + t) : 1.0f;
}

TRACER_HD TRACER_INLINE vec3 diffuse_transmission_eval(const Material& mat, vec3 wo, vec3 wi) {
  if (wo.z == 0.0f || wi.z == 0.0f) return vec3(0.0f);
  return (wo.z * wi.z > 0.0f ? mat.albedo : mat.transmittance) * kInvPi;
}

TRACER_HD TRACER_INLINE float diffuse_transmission_pdf(const Material& mat, vec3 wo, vec3 wi) {
  if (wo.z == 0.0f || wi.z == 0.0f) return 0.0f;
  const float pr = diffuse_reflect_probability(mat);
  return (wo.z * wi.z > 0.0f ? pr : 1.0f - pr) * glm::abs(wi.z) * kInvPi;
}

TRACER_HD TRACER_INLINE BsdfSample diffuse_transmission_sample(const Material& mat, vec3 wo, vec2 u,
                                                               float uc) {
  BsdfSample s;
  if (wo.z == 0.0f) return s;
  const float pr = diffuse_reflect_probability(mat);
  const bool reflect = uc < pr;
  s.wi = sample_cosine_hemisphere(u);
  if ((wo.z > 0.0f) != reflect) s.wi.z = -s.wi.z;  // onto wo's side to reflect, else across
  const float lobe = reflect ? pr : 1.0f - pr;
  s.pdf = lobe * glm::abs(s.wi.z) * kInvPi;
  if (!(s.pdf > 0.0f)) return s;
  s.weight = (reflect ? mat.albedo : mat.transmittance) / lobe;  // (c / pi) |cos| / pdf
  s.valid = true;
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
      return bsdf_is_delta(m, type) ? vec3(0.0f) : rough_conductor_eval(m, wo, wi);
    case MaterialType::kDielectric:
      return m.roughness > 0.0f ? rough_dielectric_eval(m, wo, wi) : vec3(0.0f);
    case MaterialType::kCoatedDiffuse:
      return coated_diffuse_eval(m, wo, wi);
    case MaterialType::kDiffuseTransmission:
      return diffuse_transmission_eval(m, wo, wi);
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
      return bsdf_is_delta(m, type) ? 0.0f : rough_conductor_pdf(m, wo, wi);
    case MaterialType::kDielectric:
      return m.roughness > 0.0f ? rough_dielectric_pdf(m, wo, wi) : 0.0f;
    case MaterialType::kCoatedDiffuse:
      return coated_diffuse_pdf(m, wo, wi);
    case MaterialType::kDiffuseTransmission:
      return diffuse_transmission_pdf(m, wo, wi);
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
    case MaterialType::kCoatedDiffuse:
      return coated_diffuse_sample(m, wo, u, uc);
    case MaterialType::kDiffuseTransmission:
      return diffuse_transmission_sample(m, wo, u, uc);
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

// Whether m emits towards a viewer on the `front` side (geometric normal side) or behind it, and
// the radiance it emits there.
TRACER_HD TRACER_INLINE bool material_emits(const Material& m, bool front) {
  return front || (m.flags & kMaterialTwoSidedEmission);
}

TRACER_HD TRACER_INLINE vec3 material_emission(const Material& m, bool front) {
  return material_emits(m, front) ? m.emission : vec3(0.0f);
}

}  // namespace tracer
