// Light tracing of caustics (render.light_tracing): paths that start on a light and meet a caster
// first (a mirror or smooth glass: a delta event; or a narrow glossy metal or frosted glass: a
// glossy caster, materials/bsdf.h's light_trace_glossy_caster, where as at a delta event the
// path tracer leaves the area lights to it), and are connected to the camera at every vertex after that whose BSDF has a wide
// lobe (light_trace_connects: diffuse, or rough from kGuideMinRoughness up; through a narrow
// glossy lobe a connection is a firefly); each connection is splatted into the pixels whose
// filter covers the point it lands on (Veach 1997 sec. 10.2's t = 1 strategy; pbrt-v4 sec.
// 13.7's light paths). The path tracer leaves exactly these paths to it: a path whose camera
// vertex scatters by a non-delta lobe of such a BSDF (kPathLightTraced, shade_path) and that
// reaches an area light after one or more delta events or glossy casters from its last other
// vertex no longer adds that emission. The two estimators so split the paths between them
// without weights, and the image keeps its mean. Caustics seen directly (a glass ball's on the
// floor, a lamp behind glass lighting a room, a gold ball's highlight on a wall) and the light
// they bounce on converge without the fireflies of BSDF-sampled paths.
//
// A light path's first direction is aimed at the casters (SceneView::light_targets: bounding
// spheres, light_target_choice) where the scene lists them, since a path whose first event is
// elsewhere is not the light tracer's; then a quarter as many light paths as pixels are traced
// per sample (light_paths_per_sample), else one per pixel, leaving by the cosine.
//
// Not light-traced (the path tracer keeps them): paths whose camera vertex is a delta event (a
// caustic seen in a mirror) or a narrow glossy one, light from lights at infinity and point
// lights, and paths through a subsurface material (the light tracer stops there; shade_path
// clears the flag there).
//
// Light path k of sample s draws from its own PCG32 stream, so a sample's splats depend on
// (s, seed) alone, as its camera paths do.
#pragma once

#include "integrator/path.h"

namespace tracer {

// The PCG32 stream of a light path: make_path_rng's "bounce" number, above any a camera path uses
// (its vertices, random-walk steps and the filter's stream 0xfffe).
constexpr uint32_t kLightPathStream = 0xfffffff0u;

// The integral of the filter's 1D profile over [-radius, radius] (its splat weights' normaliser):
// exact for box and tent, a midpoint sum for the others.
TRACER_HD inline float filter_profile_integral(PixelFilter f, float radius) {
  if (f == PixelFilter::kBox) return 2.0f * radius;
  if (f == PixelFilter::kTent) return radius;
  constexpr int kSteps = 256;
  float sum = 0.0f;
  for (int i = 0; i < kSteps; ++i)
    sum += filter_profile(f, radius, radius * ((2.0f * float(i) + 1.0f) / kSteps - 1.0f));
  return sum * (2.0f * radius / kSteps);
}

// Where a point seen from a lens point lands on the film: continuous pixel coordinates (x right,
// y down; pixel (i, j) covers [i, i + 1) x [j, j + 1)), as Camera::generate_ray maps them. false
// when the point is not in front of the camera.
TRACER_HD TRACER_INLINE bool camera_film_point(const Camera& c, vec3 lens, vec3 x, vec2* film) {
  const vec3 d = x - lens;
  const float z = glm::dot(d, c.forward);
  if (!(z > 0.0f)) return false;
  // The ray from the lens point through x meets the plane of focus at lens + d f / z; through the
  // lens centre that point is position + f (sx right + sy up + forward). A pinhole's lens point
  // is the centre, and this is d / z.
  const vec3 on_plane = (lens - c.position) * fast_rcp(c.focus_distance) + d * fast_rcp(z);
  const float sx = glm::dot(on_plane, c.right), sy = glm::dot(on_plane, c.up);
  film->x = 0.5f * (sx / (c.tan_half_fov * c.aspect) + 1.0f) * float(c.width);
  film->y = 0.5f * (1.0f - sy / c.tan_half_fov) * float(c.height);
  return true;
}

// Adds `value` (a connection's contribution to the pixel integral at film point fp) to the pixels
// whose filter covers fp: splat(pixel, weight * value). The filter is separable and normalised
// (norm: filter_profile_integral), as the camera's samples are drawn from it.
template <class Splat>
TRACER_HD inline void splat_film_point(const IntegratorSettings& cfg, vec2 fp, vec3 value,
                                       float norm, Splat&& splat) {
  const float r = cfg.filter_radius;
  const int x0 = int(glm::ceil(fp.x - 0.5f - r)), x1 = int(glm::floor(fp.x - 0.5f + r));
  const int y0 = int(glm::ceil(fp.y - 0.5f - r)), y1 = int(glm::floor(fp.y - 0.5f + r));
  const float inv = 1.0f / (norm * norm);
  for (int y = glm::max(y0, 0); y <= glm::min(y1, int(cfg.height) - 1); ++y) {
    const float wy = filter_profile(cfg.filter, r, fp.y - (float(y) + 0.5f));
    if (wy <= 0.0f) continue;
    for (int x = glm::max(x0, 0); x <= glm::min(x1, int(cfg.width) - 1); ++x) {
      const float w = wy * filter_profile(cfg.filter, r, fp.x - (float(x) + 0.5f)) * inv;
      if (w > 0.0f) splat(uint32_t(y) * cfg.width + uint32_t(x), value * w);
    }
  }
}

// The cone of directions from p that meets target t (its axis, the cosine of its half-angle, its
// solid angle); false where p lies inside the target's sphere.
struct TargetCone {
  vec3 axis;
  float cos_max, solid_angle;
};
TRACER_HD TRACER_INLINE bool light_target_cone(const LightTarget& t, vec3 p, TargetCone* c) {
  const vec3 to = t.center - p;
  const float d2 = glm::dot(to, to), r2 = t.radius * t.radius;
  if (!(d2 > r2)) return false;
  const float sin2 = r2 / d2;
  c->cos_max = glm::sqrt(1.0f - sin2);
  c->solid_angle = 2.0f * kPi * sin2 / (1.0f + c->cos_max);  // 2 pi (1 - cos_max), exactly
  c->axis = to * fast_rsqrt(d2);
  return true;
}
// A target's share of the choice from a light point of normal n: its solid angle times the
// cosine of its nearest direction (0 where the cone lies wholly behind the light).
TRACER_HD TRACER_INLINE float light_target_weight(const TargetCone& c, vec3 n) {
  const float sin_max = glm::sqrt(glm::max(0.0f, 1.0f - c.cos_max * c.cos_max));
  return c.solid_angle * glm::clamp(glm::dot(c.axis, n) + sin_max, 0.0f, 1.0f);
}

// A light path's first direction from light point p (side normal n) aimed at the scene's
// targets (SceneView::light_targets): a target chosen by light_target_weight, a direction
// uniform in its cone (u); *pdf the mixture's density in solid angle (every cone that holds the
// direction). Directions outside every cone meet no surface where a light path may start (the
// targets bound them all), so the light tracer loses nothing by never sampling them. false where
// there are no targets or p lies inside one (the caller samples the cosine), with *pdf = -1
// where no cone lies in front of the light (no path from p is the light tracer's). u_choice:
// a uniform number for the choice.
TRACER_HD inline bool light_target_choice(const SceneView& s, vec3 p, vec3 n, float u_choice,
                                          vec2 u, vec3* d, float* pdf) {
  *pdf = 0.0f;
  if (s.light_target_count == 0) return false;
  float total = 0.0f;
  for (uint32_t j = 0; j < s.light_target_count; ++j) {
    TargetCone c;
    if (!light_target_cone(s.light_targets[j], p, &c)) return false;
    total += light_target_weight(c, n);
  }
  if (!(total > 0.0f)) {
    *pdf = -1.0f;
    return false;
  }
  // The choice, then the direction in the chosen cone.
  float acc = 0.0f;
  uint32_t chosen = s.light_target_count - 1;
  TargetCone cc;
  for (uint32_t j = 0; j < s.light_target_count; ++j) {
    light_target_cone(s.light_targets[j], p, &cc);
    acc += light_target_weight(cc, n);
    if (u_choice * total < acc) {
      chosen = j;
      break;
    }
  }
  light_target_cone(s.light_targets[chosen], p, &cc);
  *d = Frame::from_normal(cc.axis).to_world(sample_uniform_cone(u, cc.cos_max));
  // The mixture's density: the chosen cone's term always (its own test could round the other
  // way at the rim), the others' where they hold d.
  float density = 0.0f;
  for (uint32_t j = 0; j < s.light_target_count; ++j) {
    TargetCone c;
    light_target_cone(s.light_targets[j], p, &c);
    if (j == chosen || glm::dot(*d, c.axis) >= c.cos_max)
      density += light_target_weight(c, n) / c.solid_angle;
  }
  *pdf = density / total;
  return true;
}

// Light paths per sample: one per pixel, or one per kTargetedLightPathPixels pixels where they are
// aimed at targets (most of them then carry a caustic where without targets a few in ten do).
constexpr uint32_t kTargetedLightPathPixels = 4;
TRACER_HD inline uint32_t light_paths_per_sample(const SceneView& s, uint32_t pixels) {
  return s.light_target_count > 0 ? glm::max(1u, pixels / kTargetedLightPathPixels) : pixels;
}

// A light path between its segments: the ray to trace next and what it carries.
struct LightPathState {
  Ray ray;
  vec3 beta;   // flux weight (radiance x area x solid angle over their densities)
  vec3 beta0;  // ... as it left the light (Russian roulette's reference)
  Pcg32 rng;
  uint32_t segments;  // counting `ray`
  bool chain;         // a delta event since the light: the path is the light tracer's
};

// Starts light path `index` of sample `sample`: a light chosen by power (only area lights, the
// triangles and spheres, are light-traced: shade_path keeps the paths to the others), a point on
// it by area and a direction by the cosine; false where it carries nothing.
template <uint32_t F>
TRACER_HD inline bool start_light_path(const SceneView& s, const IntegratorSettings& cfg,
                                       uint32_t index, uint32_t sample, LightPathState& st) {
  if (s.light_count == 0) return false;
  st.rng = make_path_rng(index, sample, kLightPathStream, cfg.seed);
  const uint32_t li = pick_light(s, st.rng.next_float());
  const float select = light_select_pdf(s, li);
  const Light& light = s.lights[li];
  if (light.kind != kLightPrimitive || !(select > 0.0f) || !(light.area > 0.0f)) return false;
  vec3 p, n;
  uint32_t material;
  vec3 le;
  const vec2 u_point = st.rng.next_2d();
  if (!(F & kFeatureSpheres) || light.prim < s.tri_count) {
    const TriangleVerts tv = load_triangle(s.tri_verts, light.prim);
    const vec2 b = sample_uniform_triangle(u_point);
    p = b.x * tv.v0 + b.y * tv.v1 + (1.0f - b.x - b.y) * tv.v2;
    n = fast_normalize(glm::cross(tv.v1 - tv.v0, tv.v2 - tv.v0));
    material = s.tri_shading[light.prim].material;
    le = s.materials[material].emission;
    if ((F & kFeatureTextures) && s.materials[material].emissive_tex != kInvalid) {
      const vec2 uv = triangle_uv(s, light.prim, b.y, 1.0f - b.x - b.y);
      le *= vec3(lookup_texture(s, s.materials[material].emissive_tex, uv));
    }
  } else {
    const Sphere& sph = s.spheres[light.prim - s.tri_count];
    n = sample_uniform_sphere(u_point);
    p = sph.center + sph.radius * n;
    material = sph.material;
    le = s.materials[material].emission;
  }
  const Material& lm = s.materials[material];
  // The side it leaves from: the front, or either (chosen evenly) for two-sided emission; its
  // direction by the cosine. Flux weight: Le cos / (select / area * cos / pi * side's chance).
  const vec2 u_dir = st.rng.next_2d();
  const float u_side = st.rng.next_float();
  const bool two_sided = (lm.flags & kMaterialTwoSidedEmission) != 0;
  const vec3 side_n = two_sided && u_side < 0.5f ? -n : n;
  if (!material_emits(lm, glm::dot(side_n, n) > 0.0f) || is_black(le)) return false;
  const float area_weight = light.area / select * (two_sided ? 2.0f : 1.0f);
  vec3 d;
  float target_pdf = 0.0f;
  const float u_choice = 2.0f * u_side - (u_side < 0.5f ? 0.0f : 1.0f);  // (the side's used)
  if (light_target_choice(s, p, side_n, u_choice, u_dir, &d, &target_pdf)) {
    // Towards a target: Le cos / (select / area * pdf * side's chance).
    const float c = glm::dot(d, side_n);
    if (!(c > 0.0f) || !(target_pdf > 0.0f)) return false;
    st.beta = le * (c / target_pdf * area_weight);
  } else {
    if (target_pdf < 0.0f) return false;  // no target above this side: nothing to cast
    d = Frame::from_normal(side_n).to_world(sample_cosine_hemisphere(u_dir));
    st.beta = le * (kPi * area_weight);
  }
  st.beta0 = st.beta;
  st.ray = spawn_ray(p, n, fast_normalize(d));
  st.segments = 1;
  st.chain = false;
  return true;
}

// What a light path's vertex asks of its caller: the camera connection's ray (connect: whether
// there is one; if it is free, splat `value` at film point `film`); and the rays the vertex
// traced itself for its connections through windows (window_rays).
struct LightConnection {
  Ray ray;
  vec3 value;
  vec2 film;
  bool connect;
  uint32_t window_rays;
};

// The camera connection of vertex x (unit geometric normal ng) through window plane w (one
// refraction, the window's glass on x's side: a floor seen through the front of a water tank):
// the point p on the window where the path from the lens point refracts to x (unique for a
// plane: manifold_walk from the straight line's crossing), checked by rays (from x the first hit
// is the window's glass at p, from p the lens is free). Gives the measurement's factors that
// replace the straight connection's: the generalized geometry term |d omega_lens / d A_x| times
// the window's transmission as the path tracer weighs the camera's ray (Fresnel, tint, 1 /
// eta^2), the film point, the direction from x, the lens's cosine; false where there is no such
// path. *rays counts the rays traced.
struct WindowPath {
  float geometry;
  vec3 transmission, w_x;
  vec2 film;
  float cos_cam;
};
template <uint32_t F>
TRACER_HD inline bool window_path(const SceneView& s, const WindowPlane& w, vec3 lens, vec3 x,
                                  vec3 ng, uint32_t* rays, WindowPath* out) {
  const float hx = glm::dot(x - w.a, w.n), hl = glm::dot(lens - w.a, w.n);
  if (!(hx * hl < 0.0f)) return false;  // on the two sides of its plane
  // The refraction point lies between the feet of x and the lens on the plane (both angles on one
  // side of the normal): no solve where that segment's box misses the window's triangles'.
  const vec3 fx = x - hx * w.n, fl = lens - hl * w.n;
  const vec3 lo = glm::min(fx, fl) - s.window_tol, hi = glm::max(fx, fl) + s.window_tol;
  if (glm::any(glm::lessThan(hi, w.lo)) || glm::any(glm::greaterThan(lo, w.hi))) return false;
  ManifoldChain ch;
  ch.k = 1;
  ch.surface[0].kind = SpecularSurface::kPlane;
  ch.surface[0].a = w.a;
  ch.surface[0].n = w.n;
  ch.surface[0].eta = w.eta;
  ch.p[0] = lens + (hl / (hl - hx)) * (x - lens);  // the straight line's crossing
  if (!manifold_walk(ch, lens, x)) return false;
  const vec3 p = ch.surface[0].project(ch.p[0]);
  if (!w.bounds_hold(p, s.window_tol)) return false;
  const Camera& cam = s.camera;
  if (!camera_film_point(cam, lens, p, &out->film)) return false;
  // From x the first hit is the window at p.
  const vec3 to_p = p - x;
  const float lp = glm::length(to_p);
  if (!(lp > 0.0f)) return false;
  out->w_x = to_p / lp;
  Ray r = spawn_ray(x, ng, out->w_x);
  r.tmax = lp * 1.01f + s.window_tol;
  ++*rays;
  const Hit h = intersect_closest<F>(s, r, kInvalid);
  if (!h.valid() || !prim_is_triangle(s, h.prim)) return false;
  const SurfaceHit sh = make_surface_hit<F>(s, r, h);
  if (!(glm::length(sh.p - p) <= 1e-3f * lp + s.window_tol) ||
      !w.holds(sh.p, sh.ng, sh.material, s.window_tol))
    return false;
  // From the window the lens is free.
  const vec3 dl = lens - p;
  Ray rl = spawn_ray(sh.p, glm::dot(dl, sh.ng) > 0.0f ? sh.ng : -sh.ng, glm::normalize(dl));
  rl.tmax = glm::length(lens - rl.o);
  ++*rays;
  if (intersect_any<F>(s, rl, kInvalid, kInvalid)) return false;
  const float g = manifold_geometry(ch, lens, x, ng);
  if (!(g > 0.0f)) return false;
  // The camera's ray through the window as shade_path weighs it (smooth dielectric: the
  // transmission's Fresnel, tint and 1 / eta^2 on the side it arrives from).
  const vec3 dc = -glm::normalize(dl);  // from the lens towards p
  out->transmission = smooth_transmission(s.materials[w.material], glm::dot(-dc, w.n));
  out->geometry = g;
  out->cos_cam = glm::dot(dc, cam.forward);
  return out->cos_cam > 0.0f;
}

// The vertex st.ray reached (hit): the camera connection it asks for (in *c) and the next
// segment; false when the path ends. paths: the light paths per sample.
template <uint32_t F, class Splat>
TRACER_HD inline bool light_path_vertex(const SceneView& s, const IntegratorSettings& cfg,
                                        uint32_t paths, float norm, LightPathState& st,
                                        const Hit& hit, LightConnection* c, Splat&& splat) {
  c->connect = false;
  c->window_rays = 0;
  if (!hit.valid()) return false;
  SurfaceHit sh = make_surface_hit<F>(s, st.ray, hit);
  Material textured;
  const Material& m = *hit_material<F>(s, hit.prim, sh, textured);
  const MaterialType type = (F & kFeatureSpecular) ? m.type : MaterialType::kDiffuse;
  if ((F & kFeatureSubsurface) && type == MaterialType::kSubsurface) return false;
  if (type == MaterialType::kDielectric && !sh.front && !is_black(m.absorption))
    st.beta *= glm::exp(-m.absorption * hit.t);
  const bool transmits = bsdf_transmits(type);
  const Frame frame = bsdf_frame(m, type, transmits || sh.front ? sh.ns : -sh.ns);
  const vec3 wl_world = -st.ray.d;  // towards the light's side
  const vec3 wl = frame.to_local(wl_world);
  const float cos_l_geo = glm::abs(glm::dot(wl_world, sh.ng));
  const bool delta = bsdf_is_delta(m, type);
  // The path tracer's own rule at a rough transmitter: its BSDF's sample towards the light must
  // lie on the side the true surface says (shade_path); paths against it are in neither.
  if (!delta && transmits && (glm::dot(wl_world, sh.ng) > 0.0f) != (wl.z > 0.0f)) return false;
  const Camera& cam = s.camera;
  if (st.chain && light_trace_connects(m, type) && st.segments + 1 <= cfg.max_depth &&
      cos_l_geo > 0.0f) {
    // The camera connection: a lens point, the film point it sees x through, and whether the
    // segment is free.
    vec3 lens = cam.position;
    const vec2 u_lens = st.rng.next_2d();
    if ((F & kFeatureDepthOfField) && cam.lens_radius > 0.0f) {
      const vec2 l = cam.lens_radius * sample_uniform_disk_concentric(u_lens);
      lens += l.x * cam.right + l.y * cam.up;
    }
    // The measurement's constant: pixels per unit area of the film plane one unit ahead, over
    // the light paths per sample.
    const float film_scale =
        float(cfg.width) * float(cfg.height) /
        (4.0f * cam.tan_half_fov * cam.tan_half_fov * cam.aspect * float(paths));
    const vec3 to_cam = lens - sh.p;
    const float d2 = glm::dot(to_cam, to_cam);
    if (d2 > 0.0f && camera_film_point(cam, lens, sh.p, &c->film)) {
      const vec3 wc_world = to_cam * fast_rsqrt(d2);
      const float geo_c = glm::dot(wc_world, sh.ng);
      // A reflector sends light only to the side it came from.
      const bool usable = transmits || geo_c * glm::dot(wl_world, sh.ng) > 0.0f;
      const vec3 f = usable ? bsdf_eval<F>(m, frame.to_local(wc_world), wl) : vec3(0.0f);
      if (!is_black(f)) {
        const float cos_cam = -glm::dot(wc_world, cam.forward);
        // Radiance towards the camera from the particle's flux (the shading normal's cosine
        // over the geometric one: the adjoint's correction), times the camera's importance per
        // unit area at x: |cos at x| / (d^2 cos^3 at the camera) per film-plane area.
        c->value = st.beta * f *
                   (glm::abs(wl.z) / cos_l_geo * glm::abs(geo_c) /
                    (d2 * cos_cam * cos_cam * cos_cam) * film_scale);
        c->ray = spawn_ray(sh.p, sh.ng, wc_world);
        c->ray.tmax = glm::length(lens - c->ray.o);
        c->connect = is_finite(c->value);
      }
    }
    // Through each window (one refraction, one more segment; the path tracer leaves these paths
    // to the light tracer where its camera ray crossed a window to such a vertex, shade_path).
    for (uint32_t k = 0; (F & kFeatureWindows) && st.segments + 2 <= cfg.max_depth &&
                         k < s.window_plane_count;
         ++k) {
      WindowPath wp;
      if (!window_path<F>(s, s.window_planes[k], lens, sh.p, sh.ng, &c->window_rays, &wp))
        continue;
      const float geo_w = glm::dot(wp.w_x, sh.ng);
      const bool usable = transmits || geo_w * glm::dot(wl_world, sh.ng) > 0.0f;
      const vec3 f = usable ? bsdf_eval<F>(m, frame.to_local(wp.w_x), wl) : vec3(0.0f);
      if (is_black(f)) continue;
      const vec3 value = st.beta * f * wp.transmission *
                         (glm::abs(wl.z) / cos_l_geo * wp.geometry /
                          (wp.cos_cam * wp.cos_cam * wp.cos_cam) * film_scale);
      if (is_finite(value)) splat_film_point(cfg, wp.film, value, norm, splat);
    }
  }
  // Go on while a later vertex could still connect within max_depth.
  if (st.segments + 2 > cfg.max_depth) return false;
  const vec2 u_bsdf = st.rng.next_2d();
  const float u_lobe = st.rng.next_float();
  const BsdfSample bs = bsdf_sample<F>(m, wl, u_bsdf, u_lobe);
  if (!bs.valid) return false;
  // Light -> a wide lobe: next-event estimation's; the chain starts at a delta event or a glossy
  // caster (light_trace_glossy_caster).
  if (!st.chain && !bs.specular && !light_trace_glossy_caster(m, type)) return false;
  st.chain = true;
  const vec3 wg_world = fast_normalize(frame.to_world(bs.wi));
  const float side = glm::dot(wg_world, sh.ng);
  if (!transmits && side * glm::dot(wl_world, sh.ng) <= 0.0f) return false;
  if (transmits && !bs.specular && (side > 0.0f) != (bs.wi.z > 0.0f)) return false;
  const bool refracted = bs.wi.z * wl.z < 0.0f;
  vec3 w;
  if (!bs.specular && refracted) {
    // The path tracer's BSDF with its arguments as the path tracer would pass them (towards
    // the camera's side first), over the density that sampled the direction.
    w = bsdf_eval<F>(m, bs.wi, wl) * (glm::abs(bs.wi.z) / bs.pdf);
  } else if (bs.specular && refracted) {
    // Flux crosses a smooth interface unchanged but for Fresnel (the sample's choice): the
    // radiance weight's 1 / eta^2 (eta = n_transmitted / n_incident) undone.
    const float eta = wl.z > 0.0f ? m.ior : 1.0f / m.ior;
    w = bs.weight * (eta * eta);
  } else {
    w = bs.weight;  // reflection: reciprocal
  }
  // The adjoint's shading-normal correction (Veach 1997 sec. 5.3): |wl.ns| |wg.ng| / (|wl.ng|
  // |wg.ns|); 1 where the shading normal is the true one.
  const float cos_g_shading = glm::abs(bs.wi.z);
  if (cos_l_geo <= 0.0f || cos_g_shading <= 0.0f) return false;
  st.beta *= w * (glm::abs(wl.z) * glm::abs(side) / (cos_l_geo * cos_g_shading));
  if (cfg.russian_roulette && st.segments + 1 >= cfg.rr_start_depth) {
    const float q = glm::min(1.0f, fast_sqrt(max_component(st.beta / st.beta0)));
    if (st.rng.next_float() >= q) return false;
    st.beta *= fast_rcp(q);
  }
  if (is_black(st.beta) || !is_finite(st.beta)) return false;
  st.ray = spawn_ray(sh.p, sh.ng, wg_world);
  st.segments += 1;
  return true;
}

// What one light path traced (for the ray counts).
struct LightPathCounts {
  uint32_t segments = 0, connections = 0;
};

// Light path `index` of sample `sample`, whole (the CPU; the GPU's kernel runs the same steps
// with path regeneration): splat(pixel, rgb) receives each contribution to a pixel's mean for
// this sample (norm: filter_profile_integral of cfg's filter). paths: the light paths per sample.
template <uint32_t F, class Splat>
TRACER_HD inline LightPathCounts trace_light_path(const SceneView& s, const IntegratorSettings& cfg,
                                                  uint32_t index, uint32_t sample, uint32_t paths,
                                                  float norm, Splat&& splat) {
  LightPathCounts counts;
  LightPathState st;
  if (!start_light_path<F>(s, cfg, index, sample, st)) return counts;
  for (;;) {
    const Hit hit = intersect_closest<F>(s, st.ray, kInvalid);
    ++counts.segments;
    LightConnection c;
    const bool go_on = light_path_vertex<F>(s, cfg, paths, norm, st, hit, &c, splat);
    counts.connections += c.window_rays;
    if (c.connect) {
      ++counts.connections;
      if (!intersect_any<F>(s, c.ray, kInvalid, kInvalid))
        splat_film_point(cfg, c.film, c.value, norm, splat);
    }
    if (!go_on) return counts;
  }
}

}  // namespace tracer
