// Feature buffers (AOVs: arbitrary output variables) for denoisers and for users who inspect a
// scene: the albedo and shading normal of the first non-specular hit, the distance to the first
// hit, and the material and primitive there. One sample of them follows the same camera ray and
// the same choices at mirrors and glass as the path of the same pixel and sample index (the same
// sampler dimensions), so the features line up with the colour sample by sample. Shared by the
// CPU backend and the CUDA AOV kernel; the renderers run it only while Renderer::set_aovs is
// on.
#pragma once

#include "integrator/path.h"
#include "integrator/textured.h"
#include "materials/fresnel.h"

namespace tracer {

struct AovSample {
  vec3 albedo = vec3(0.0f);  // reflectance of the first non-specular surface (0: escaped)
  vec3 normal = vec3(0.0f);  // its unit shading normal, facing the ray that reached it (world)
  float depth = 0.0f;        // distance along the camera ray to the first hit (0: escaped)
  uint32_t material = kInvalid;  // the first non-specular hit's material (kInvalid: escaped)
  uint32_t prim = kInvalid;      // ... and primitive (the hit id of bvh/traverse.h)
};

// The albedo a denoiser expects of a material: the colour of its diffuse or glossy reflection
// at normal incidence; 1 for rough glass (as Open Image Denoise asks for dielectrics); the
// single-scattering albedo of a subsurface medium (its boundary is not followed: the colour of
// the walk is the medium's).
TRACER_HD TRACER_INLINE vec3 material_aov_albedo(const Material& m, MaterialType type) {
  switch (type) {
    case MaterialType::kConductor:
      return (m.flags & kMaterialConductorIor) ? m.albedo * fresnel_conductor(1.0f, m.eta, m.k)
                                               : m.albedo;
    case MaterialType::kDielectric: return vec3(1.0f);
    case MaterialType::kSubsurface: {
      const vec3 t = m.scattering + m.absorption;
      return vec3(t.x > 0.0f ? m.scattering.x / t.x : 0.0f, t.y > 0.0f ? m.scattering.y / t.y : 0.0f,
                  t.z > 0.0f ? m.scattering.z / t.z : 0.0f);
    }
    case MaterialType::kDiffuseTransmission:
      return glm::min(m.albedo + m.transmittance, vec3(1.0f));
    default: return m.albedo;  // diffuse, coated diffuse (its base), mirror
  }
}

// One AOV sample of `pixel`: the camera ray of trace_path's sample `sample`, followed through
// delta reflections and refractions (the lobe its path chooses there) to the first surface
// that is not a delta scatterer, at most cfg.max_depth segments.
template <uint32_t F = kAllFeatures>
TRACER_HD inline AovSample trace_aov(const SceneView& s, const IntegratorSettings& cfg,
                                     uint32_t pixel, uint32_t sample) {
  AovSample out;
  PathState st;
  generate_path<F>(s, cfg, pixel, sample, st);
  for (;;) {
    const Hit hit = intersect_closest<F>(s, st.ray, st.origin_prim);
    if (!hit.valid()) return out;
    if (st.depth == 1) out.depth = hit.t;
    SurfaceHit sh = make_surface_hit<F>(s, st.ray, hit);
    Material textured;
    const Material& m = *hit_material<F>(s, hit.prim, sh, textured);
    const MaterialType type = (F & kFeatureSpecular) ? m.type : MaterialType::kDiffuse;
    const vec3 wo_world = -st.ray.d;
    const bool delta = bsdf_is_delta(m, type) && type != MaterialType::kSubsurface;
    if (!delta || m.is_emissive() || st.depth >= cfg.max_depth) {
      out.albedo = material_aov_albedo(m, type);
      out.normal = glm::dot(sh.ns, wo_world) < 0.0f ? -sh.ns : sh.ns;
      out.material = sh.material;
      out.prim = hit.prim;
      return out;
    }
    // A delta scatterer: the same lobe as the path's (its vertex's sampler dimensions).
    const VertexSampler u(cfg, st.pixel, st.sample, st.depth);
    const bool transmits = bsdf_transmits(type);
    const Frame frame = bsdf_frame(m, type, transmits || sh.front ? sh.ns : -sh.ns);
    const BsdfSample bs =
        bsdf_sample<F>(m, frame.to_local(wo_world), u.bsdf(), bsdf_chooses_lobe(type) ? u.lobe() : 0.5f);
    if (!bs.valid) return out;
    const vec3 wi_world = fast_normalize(frame.to_world(bs.wi));
    st.ray = spawn_ray(sh.p, sh.ng, wi_world);
    st.origin_prim = kInvalid;
    st.depth += 1;
  }
}

}  // namespace tracer
