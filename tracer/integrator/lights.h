// Sampling emissive geometry for next-event estimation, and the matching pdf for multiple
// importance sampling when a BSDF-sampled ray hits an emitter. Lights are chosen uniformly, in
// proportion to their power or by the light tree (render.light_sampler, choose_light below);
// triangles are sampled by area, spheres by the cone of directions they subtend, the environment
// by its map's luminance, distant lights by their cone (or their direction), point and spot
// lights by their position.
#pragma once

#include "core/sampling.h"
#include "integrator/textured.h"
#include "materials/bsdf.h"
#include "scene/scene_view.h"

namespace tracer {

struct LightSample {
  vec3 p;     // point on the light; a light at infinity: the unit direction towards it
  vec3 n;     // its geometric normal
  vec3 le;    // radiance emitted towards the reference point (a delta light: its irradiance,
              // for a point light I / d^2)
  // An area light's radiance on the side of its normal (with two-sided emission: on both), for
  // manifold NEE, whose chains may reach the light from the side le was not evaluated for. Set
  // by the area lights' samples only (no initializer: the struct stays trivial for the GPU).
  vec3 emitted;
  float pdf;  // solid-angle pdf at the reference point, including the choice of light (a delta
              // light: the choice alone)
  uint32_t prim;
  bool valid;
  bool infinite;  // a direction, not a point: the shadow ray leaves the scene
  bool delta;     // a delta distribution (a distant light of angular diameter 0, a point or
                  // spot light): no MIS
};

// A light at infinity once chosen (select: the probability of that choice).
template <uint32_t F>
TRACER_HD inline LightSample sample_infinite_light(const SceneView& s, const Light& light,
                                                   float select, vec2 u) {
  LightSample ls;
  ls.valid = false;
  ls.infinite = true;
  ls.delta = false;
  ls.prim = kInvalid;
  const InfiniteLights& inf = *s.infinite;
  float pdf = 0.0f;
  if (light.kind == kLightEnvironment) {
    ls.p = env_sample(inf, u, &pdf);
    ls.le = env_radiance(inf, ls.p);
  } else {
    const DistantLight& dl = inf.distant[light.prim];
    ls.le = dl.radiance;
    if (dl.one_minus_cos > 0.0f) {
      ls.p = distant_sample(dl, u);
      pdf = distant_cone_pdf(dl);
    } else {
      ls.p = dl.dir;
      ls.delta = true;
      pdf = 1.0f;
    }
  }
  ls.n = -ls.p;
  ls.pdf = select * pdf;
  ls.valid = ls.pdf > 0.0f && is_finite(ls.pdf);
  return ls;
}

// ---- Point and spot lights ----------------------------------------------------------------------
// A point or spot light once chosen (select: the probability of that choice): the light's
// position, and its intensity towards ref over the squared distance as the "radiance" (pbrt-v4
// sec. 12.1, PointLight::SampleLi). A delta light: its pdf is the choice alone, no MIS, and no
// BSDF-sampled ray ever hits it.
TRACER_HD inline LightSample sample_point_light(const SceneView& s, const Light& light,
                                                float select, vec3 ref) {
  LightSample ls;
  ls.valid = false;
  ls.infinite = false;
  ls.delta = true;
  ls.prim = kInvalid;  // nothing for the shadow ray to skip
  const PointLight& pl = s.point_lights[light.prim];
  const vec3 to_ref = ref - pl.position;
  const float d2 = glm::dot(to_ref, to_ref);
  if (!(d2 > 0.0f)) return ls;
  const vec3 w = to_ref * fast_rsqrt(d2);
  ls.p = pl.position;
  // No surface there: the shadow ray's far end is offset along n, towards ref (spawn_ray_to).
  ls.n = w;
  ls.le = point_light_intensity(pl, w) * fast_rcp(d2);
  ls.pdf = select;
  ls.valid = ls.pdf > 0.0f && is_finite(ls.le);
  return ls;
}
// ---- end of point and spot lights --------------------------------------------------------------

// Index of the light whose CDF interval holds u (binary search over light_count + 1 entries).
TRACER_HD TRACER_INLINE uint32_t pick_light(const SceneView& s, float u) {
  uint32_t lo = 0, hi = s.light_count;  // invariant: cdf[lo] <= u < cdf[hi]
  while (hi - lo > 1) {
    const uint32_t mid = (lo + hi) / 2;
    if (s.light_cdf[mid] <= u)
      lo = mid;
    else
      hi = mid;
  }
  return lo;
}

// The power sampler's probability of choosing `light`.
TRACER_HD TRACER_INLINE float light_select_pdf(const SceneView& s, uint32_t light) {
  return s.light_cdf[light + 1] - s.light_cdf[light];
}

// ---- Light choice: render.light_sampler (kLightSampler*, scene/light_tree_view.h) ----------
// uniform: 1 / light_count each. power: the CDF above. bvh: the light tree for every light but
// those at infinity, which are chosen apart in proportion to power, as the power sampler would:
// the tree gets the share of power of the lights in it (light_cdf[finite_light_count], the
// lights at infinity being last) and each light at infinity its own share. (pbrt-v4's
// BVHLightSampler gives each light at infinity as much probability as the whole tree; by power,
// a dim sky around a room of lamps does not take half the samples.) Where the tree would be a
// single leaf, whose lights it chooses by power, SceneView has no tree and bvh is the power
// sampler (the Cornell box's one lamp: no cost).

// A chosen light, its probability, and the choosing number rescaled to [0, 1) within the choice
// (reused as the first coordinate of the point on the light, see sample_light_2d).
struct LightChoice {
  uint32_t light;  // kInvalid: none (no light, or none of the tree's can reach ctx)
  float pmf;
  float u;
};

// The context at a surface vertex for the bvh sampler: the point its reflected BSDF rays start
// from (spawn_ray's offset to the viewer's side) and its normal as PathState::prev_normal keeps
// it. The tree's pmf at an emitter such a ray hits, from the ray's origin and that normal, is
// then exactly the probability next-event estimation gave it (for transmitted rays the point
// differs by the two offsets).
TRACER_HD TRACER_INLINE LightContext vertex_light_context(vec3 p, vec3 n_viewer,
                                                          uint32_t normal_code) {
  return LightContext{offset_ray_origin(p, n_viewer), unpack_light_normal(normal_code)};
}

// F without kFeatureLightTree: the scene has no tree (bvh is the power sampler), and the GPU's
// kernels for it compile no descent.
template <uint32_t F = kAllFeatures>
TRACER_HD inline LightChoice choose_light(const SceneView& s, uint32_t sampler,
                                          const LightContext& ctx, float u) {
  LightChoice c;
  c.light = kInvalid;
  c.pmf = 0.0f;
  c.u = u;
  const uint32_t n = s.light_count;
  if (n == 0) return c;
  if (sampler == kLightSamplerUniform) {
    const float x = u * float(n);
    c.light = glm::min(uint32_t(x), n - 1);
    c.pmf = 1.0f / float(n);
    c.u = glm::clamp(x - float(c.light), 0.0f, 0x1.fffffep-1f);
    return c;
  }
  if ((F & kFeatureLightTree) && sampler == kLightSamplerBvh && s.light_tree.nodes) {
    const float p_tree = s.light_cdf[s.finite_light_count];
    if (u < p_tree) {
      const LightTreeChoice t =
          light_tree_choose(s.light_tree, ctx, glm::min(u / p_tree, 0x1.fffffep-1f));
      c.light = t.light;
      c.pmf = t.light == kInvalid ? 0.0f : p_tree * t.pmf;
      c.u = t.u;
      return c;
    }
    // Lights at infinity: u >= light_cdf[finite_light_count] lands on one of them below.
  }
  c.light = pick_light(s, u);
  const float lo = s.light_cdf[c.light], width = s.light_cdf[c.light + 1] - lo;
  c.pmf = width;
  c.u = width > 0.0f ? glm::max(glm::min(fast_div(u - lo, width), 0x1.fffffep-1f), 0.0f) : 0.0f;
  return c;
}

// The probability that choose_light<F>(s, sampler, ctx, .) returns `light`.
template <uint32_t F = kAllFeatures>
TRACER_HD inline float light_choice_pmf(const SceneView& s, uint32_t sampler,
                                        const LightContext& ctx, uint32_t light) {
  if (sampler == kLightSamplerUniform) return 1.0f / float(s.light_count);
  if ((F & kFeatureLightTree) && sampler == kLightSamplerBvh && s.light_tree.nodes &&
      light < s.finite_light_count)
    return s.light_cdf[s.finite_light_count] * light_tree_pmf(s.light_tree, light, ctx);
  return light_select_pdf(s, light);
}
// ---- end of light choice ---------------------------------------------------------------------

// Half-angle cosine of the cone a sphere subtends from ref; returns false when ref is inside.
TRACER_HD TRACER_INLINE bool sphere_cone(const Sphere& sph, vec3 ref, float& cos_max,
                                         float& sin2_max) {
  const float dc2 = glm::dot(ref - sph.center, ref - sph.center);
  const float r2 = sph.radius * sph.radius;
  if (dc2 <= r2) return false;
  sin2_max = r2 / dc2;
  cos_max = safe_sqrt(1.0f - sin2_max);
  return true;
}

// ref_n: the geometric normal at ref (either orientation), used to decide robustly whether ref
// is inside a sphere light even when ref lies on that sphere's own surface.
// select: the probability with which light `li` was chosen.
template <uint32_t F = kAllFeatures>
TRACER_HD inline LightSample sample_chosen_light(const SceneView& s, uint32_t li, float select,
                                                 vec3 ref, vec3 ref_n, vec2 u);

// A light chosen by u_pick (the bvh sampler from the context (ref, ref_n)), then a point on it.
template <uint32_t F = kAllFeatures>
TRACER_HD inline LightSample sample_light(const SceneView& s, vec3 ref, vec3 ref_n, float u_pick,
                                          vec2 u, uint32_t sampler = kLightSamplerPower) {
  const LightChoice c = choose_light<F>(s, sampler, LightContext{ref, ref_n}, u_pick);
  if (!(c.pmf > 0.0f)) {
    LightSample none;
    none.valid = false;
    return none;
  }
  return sample_chosen_light<F>(s, c.light, c.pmf, ref, ref_n, u);
}

// sample_light once light `li` is chosen.
template <uint32_t F>
TRACER_HD inline LightSample sample_chosen_light(const SceneView& s, uint32_t li, float select,
                                                 vec3 ref, vec3 ref_n, vec2 u) {
  LightSample ls;
  ls.valid = false;
  ls.infinite = false;
  ls.delta = false;
  const Light& light = s.lights[li];
  if (select <= 0.0f) return ls;
  if ((F & kFeaturePointLights) && (light.kind == kLightPoint || light.kind == kLightSpot))
    return sample_point_light(s, light, select, ref);
  if ((F & kFeatureInfiniteLights) &&
      (light.kind == kLightEnvironment || light.kind == kLightDistant))
    return sample_infinite_light<F>(s, light, select, u);
  ls.prim = light.prim;
  uint32_t material;
  if (!(F & kFeatureSpheres) || light.prim < s.tri_count) {
    const TriangleVerts tv = load_triangle(s.tri_verts, light.prim);
    const vec2 b = sample_uniform_triangle(u);
    ls.p = b.x * tv.v0 + b.y * tv.v1 + (1.0f - b.x - b.y) * tv.v2;
    ls.n = fast_normalize(glm::cross(tv.v1 - tv.v0, tv.v2 - tv.v0));
    material = s.tri_shading[light.prim].material;
    const vec3 to_ref = ref - ls.p;
    const float d2 = glm::dot(to_ref, to_ref);
    const float cos_l = glm::abs(glm::dot(ls.n, to_ref)) * fast_rsqrt(d2);
    if (cos_l <= 0.0f || d2 <= 0.0f) return ls;
    ls.pdf = fast_div(select * d2, cos_l * light.area);
    const Material& lm = s.materials[material];
    ls.emitted = lm.emission;
    // The same textured radiance a path that hits this point sees (shade_path), or MIS breaks.
    // The light's selection power stays untextured: any positive power is unbiased.
    if ((F & kFeatureTextures) && lm.emissive_tex != kInvalid) {
      const vec2 uv = triangle_uv(s, light.prim, b.y, 1.0f - b.x - b.y);
      ls.emitted *= vec3(lookup_texture(s, lm.emissive_tex, uv));
    }
    ls.le = material_emits(lm, glm::dot(ls.n, to_ref) > 0.0f) ? ls.emitted : vec3(0.0f);
  } else {
    const Sphere& sph = s.spheres[light.prim - s.tri_count];
    material = sph.material;
    float cos_max, sin2_max;
    // Decide inside/outside from ref offset towards the centre, as a ray leaving ref towards the
    // sphere would start (pbrt-v4's SphereSample): a point on the sphere's own inner surface is
    // then inside, and one on its outer surface sees none of it.
    const vec3 to_c = sph.center - ref;
    const vec3 ref_o = offset_ray_origin(ref, glm::dot(ref_n, to_c) > 0.0f ? ref_n : -ref_n);
    if (sphere_cone(sph, ref_o, cos_max, sin2_max)) {
      // Sample the subtended cone and find the point it sees (pbrt-v4 sec. 6.2.4).
      const vec3 wc = glm::normalize(sph.center - ref);
      float cos_t = (cos_max - 1.0f) * u.x + 1.0f;
      float sin2_t = 1.0f - cos_t * cos_t;
      float one_minus_cos_max = 1.0f - cos_max;
      if (sin2_max < 0.00068523f) {  // about 1.5 degrees: use the Taylor expansion
        sin2_t = sin2_max * u.x;
        cos_t = glm::sqrt(1.0f - sin2_t);
        one_minus_cos_max = 0.5f * sin2_max;
      }
      const float sin_max = glm::sqrt(sin2_max);
      const float cos_alpha =
          sin2_t / sin_max + cos_t * safe_sqrt(1.0f - sin2_t / (sin_max * sin_max));
      const float sin_alpha = safe_sqrt(1.0f - cos_alpha * cos_alpha);
      const float phi = 2.0f * kPi * u.y;
      const Frame f = Frame::from_normal(-wc);
      ls.n = f.to_world(vec3(sin_alpha * glm::cos(phi), sin_alpha * glm::sin(phi), cos_alpha));
      ls.p = sph.center + sph.radius * ls.n;
      ls.pdf = select / (2.0f * kPi * one_minus_cos_max);
      ls.le = ls.emitted = material_emission(s.materials[material], true);
    } else {
      // Inside the sphere: sample its area uniformly; only its back face is visible.
      ls.n = sample_uniform_sphere(u);
      ls.p = sph.center + sph.radius * ls.n;
      const vec3 to_ref = ref - ls.p;
      const float d2 = glm::dot(to_ref, to_ref);
      const float cos_l = glm::abs(glm::dot(ls.n, to_ref)) / glm::sqrt(d2);
      if (cos_l <= 0.0f || d2 <= 0.0f) return ls;
      ls.pdf = select * d2 / (cos_l * light.area);
      ls.le = ls.emitted = material_emission(s.materials[material], false);
    }
  }
  ls.valid = ls.pdf > 0.0f && is_finite(ls.pdf);
  return ls;
}

// Next-event estimation from one 2D point: u.x chooses the light (choose_light, by `sampler`
// from ctx) and, rescaled to [0, 1) within that choice, is reused as the first coordinate of the
// point on it. Drawing the choice from a dimension of its own would leave each light with a
// random subset of the 2D points, which loses their stratification; reused, the points that land
// on a light are still a stratified set (the two triangles of a quad light together get the
// stratification of the whole quad). The same reuse as pbrt-v3's SampleDiscrete(u, &pdf,
// &u_remapped), and pbrt-v4's light tree descent.
template <uint32_t F = kAllFeatures>
TRACER_HD inline LightSample sample_light_2d(const SceneView& s, uint32_t sampler,
                                             const LightContext& ctx, vec3 ref, vec3 ref_n,
                                             vec2 u) {
  const LightChoice c = choose_light<F>(s, sampler, ctx, u.x);
  if (!(c.pmf > 0.0f)) {
    LightSample none;
    none.valid = false;
    return none;
  }
  return sample_chosen_light<F>(s, c.light, c.pmf, ref, ref_n, vec2(c.u, u.y));
}

// The solid-angle pdf with which sample_light would have produced point p (normal ng) on
// primitive `light_index`, chosen with probability `select`, as seen from ref, the (already
// offset) origin of the ray that hit p.
template <uint32_t F = kAllFeatures>
TRACER_HD inline float light_pdf(const SceneView& s, uint32_t light_index, float select, vec3 ref,
                                 vec3 p, vec3 ng) {
  const Light& light = s.lights[light_index];
  if ((F & kFeatureSpheres) && light.prim >= s.tri_count) {
    const Sphere& sph = s.spheres[light.prim - s.tri_count];
    float cos_max, sin2_max;
    if (sphere_cone(sph, ref, cos_max, sin2_max)) {
      const float one_minus_cos_max = sin2_max < 0.00068523f ? 0.5f * sin2_max : 1.0f - cos_max;
      return select / (2.0f * kPi * one_minus_cos_max);
    }
  }
  const vec3 to_ref = ref - p;
  const float d2 = glm::dot(to_ref, to_ref);
  const float cos_l = glm::abs(glm::dot(ng, to_ref)) * fast_rsqrt(d2);
  if (cos_l <= 0.0f) return 0.0f;
  return fast_div(select * d2, cos_l * light.area);
}

// The radiance a path gains when its ray (direction d, leaving the scene; st_depth the segments
// traced, counting it) meets no surface: the environment and the distant lights' cones, each
// weighted against the light sampling that could have produced d at the previous vertex (MIS:
// prev_pdf is the BSDF's solid-angle pdf of d; no weight after a delta bounce or for the camera).
// Camera rays see the background instead where the environment is not visible.
// sampler: render.light_sampler (lights at infinity are chosen with no regard to the point).
template <uint32_t F = kAllFeatures>
TRACER_HD inline vec3 escaped_radiance(const SceneView& s, bool nee, bool mis, vec3 d,
                                       float prev_pdf, uint32_t depth, bool prev_specular,
                                       uint32_t sampler = kLightSamplerPower) {
  const InfiniteLights& inf = *s.infinite;
  if (depth == 1 && !inf.visible) return inf.background;
  // Lights that next-event estimation samples are weighted; without MIS BSDF sampling leaves
  // them to next-event estimation entirely.
  const bool weighted = nee && !prev_specular;
  vec3 L(0.0f);
  if (inf.env != kEnvNone) {
    const vec3 le = env_radiance(inf, d);
    if (le.x > 0.0f || le.y > 0.0f || le.z > 0.0f) {
      float w = 1.0f;
      if (weighted)
        w = mis ? power_heuristic(prev_pdf,
                                  light_choice_pmf<F>(s, sampler, LightContext{}, inf.env_light) *
                                      env_pdf(inf, d))
                : 0.0f;
      L += le * w;
    }
  }
  for (uint32_t k = 0; k < inf.distant_count; ++k) {
    const DistantLight& dl = inf.distant[k];
    if (!(dl.one_minus_cos > 0.0f) || !distant_hit(dl, d)) continue;  // delta lights: never hit
    float w = 1.0f;
    if (weighted)
      w = mis ? power_heuristic(prev_pdf,
                                light_choice_pmf<F>(s, sampler, LightContext{}, dl.light) *
                                    distant_cone_pdf(dl))
              : 0.0f;
    L += dl.radiance * w;
  }
  return L;
}

}  // namespace tracer
