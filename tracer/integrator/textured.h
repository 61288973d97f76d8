// Applies a material's image textures at a surface point: base colour, metallic-roughness,
// emission and tangent-space normal maps with glTF semantics. Triangles only: spheres carry no
// texture coordinates and stay untextured (also for light sampling, so MIS stays consistent).
#pragma once

#include "scene/scene_view.h"

namespace tracer {

TRACER_HD TRACER_INLINE vec4 lookup_texture(const SceneView& s, uint32_t tex, vec2 uv) {
  return sample_texture(s.textures, s.texels, tex, uv);
}

// Texture coordinates at barycentrics (b1, b2) of triangle `prim` (zero without uvs).
TRACER_HD TRACER_INLINE vec2 triangle_uv(const SceneView& s, uint32_t prim, float b1, float b2) {
  const TriangleUv* tu = triangle_uvs(s, triangle_ref(s, prim));
  if (!tu) return vec2(0.0f);
  return (1.0f - b1 - b2) * tu->uv0 + b1 * tu->uv1 + b2 * tu->uv2;
}

// Tangent-space normal mapping (glTF 2.0 spec sec. 3.9.3; pbrt-v4 sec. 10.5.3): the tangent is
// dp/du of the triangle, Gram-Schmidt orthogonalised against the shading normal; the bitangent
// is n x t, flipped where the uv mapping is mirrored so that it follows -dp/dv (texture +Y points
// up the image, and glTF's v runs down it). The derivatives are those of the normal texture's
// own coordinates (its uv_transform applied), so a rotated or mirrored normal map turns its frame
// with it. The result is kept on the geometric normal's side.
TRACER_HD inline vec3 normal_mapped(const SceneView& s, uint32_t prim, const SurfaceHit& sh,
                                    uint32_t tex, vec3 texel, float scale) {
  const TriangleRef r = triangle_ref(s, prim);
  const TriangleVerts tv = world_triangle(s, r);
  const TriangleUv tu = *triangle_uvs(s, r);
  const vec3 dp1 = tv.v1 - tv.v0, dp2 = tv.v2 - tv.v0;
  const glm::mat2 linear(s.textures[tex].uv_transform);  // the offset drops out of derivatives
  const vec2 duv1 = linear * (tu.uv1 - tu.uv0), duv2 = linear * (tu.uv2 - tu.uv0);
  const float det = duv1.x * duv2.y - duv1.y * duv2.x;
  if (!(glm::abs(det) > 1e-12f)) return sh.ns;  // degenerate uv mapping: no tangent frame
  const vec3 dpdu = (duv2.y * dp1 - duv1.y * dp2) / det;
  const vec3 dpdv = (duv1.x * dp2 - duv2.x * dp1) / det;
  const vec3 n = sh.ns;
  vec3 t = dpdu - glm::dot(dpdu, n) * n;
  const float tl = glm::length(t);
  if (!(tl > 0.0f)) return sh.ns;
  t /= tl;
  vec3 b = glm::cross(n, t);
  if (glm::dot(b, dpdv) > 0.0f) b = -b;
  vec3 c = texel * 2.0f - 1.0f;
  c.x *= scale;
  c.y *= scale;
  const vec3 m = c.x * t + c.y * b + c.z * n;
  const float ml = glm::length(m);
  if (!(ml > 0.0f)) return sh.ns;
  const vec3 mn = m / ml;
  // A perturbed normal below the surface would make the two-sided BSDF frame flip.
  return glm::dot(mn, sh.ng) > 1e-4f ? mn : sh.ns;
}

// Fills `m` (a copy of the hit's material) with its texel values at sh.uv and perturbs sh.ns.
template <uint32_t F>
TRACER_HD inline void apply_textures(const SceneView& s, uint32_t prim, SurfaceHit& sh,
                                     Material& m) {
  if (!prim_is_triangle(s, prim)) return;
  if (m.base_color_tex != kInvalid) m.albedo *= vec3(lookup_texture(s, m.base_color_tex, sh.uv));
  if (m.metal_rough_tex != kInvalid) {
    const vec4 mr = lookup_texture(s, m.metal_rough_tex, sh.uv);
    m.roughness *= mr.y;
    // glTF metallic-roughness without a blend of lobes: metal (F0 = base colour) or diffuse.
    if (m.type == MaterialType::kDiffuse || m.type == MaterialType::kConductor)
      m.type = m.metallic * mr.z >= 0.5f ? MaterialType::kConductor : MaterialType::kDiffuse;
  }
  if (m.emissive_tex != kInvalid) m.emission *= vec3(lookup_texture(s, m.emissive_tex, sh.uv));
  if (m.normal_tex != kInvalid && triangle_uvs(s, triangle_ref(s, prim))) {
    sh.ns = normal_mapped(s, prim, sh, m.normal_tex, vec3(lookup_texture(s, m.normal_tex, sh.uv)),
                          m.normal_scale);
  }
}

// The material at a hit: textured materials are evaluated on `scratch`, a copy holding this
// point's texel values (sh.ns perturbed by a normal map); scenes without textures (F without
// kFeatureTextures) read the material in place.
template <uint32_t F>
TRACER_HD TRACER_INLINE const Material* hit_material(const SceneView& s, uint32_t prim,
                                                    SurfaceHit& sh, Material& scratch) {
  const Material* mp = &s.materials[sh.material];
  if ((F & kFeatureTextures) && mp->has_textures()) {
    scratch = *mp;
    apply_textures<F>(s, prim, sh, scratch);
    mp = &scratch;
  }
  return mp;
}

}  // namespace tracer
