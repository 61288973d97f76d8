// The flattened scene both backends trace: plain arrays linked by uint32 indices, readable from
// host or device memory alike. Ray queries over its geometry are bvh/traverse.h.
#pragma once

#include "bvh/traverse.h"
#include "camera/camera.h"
#include "core/features.h"
#include "materials/material.h"
#include "materials/texture.h"
#include "scene/environment_view.h"
#include "scene/point_light_view.h"
#include "scene/light_tree_view.h"

namespace tracer {

// Cold per-triangle data, read only after a hit.
struct TriangleShading {
  vec3 n0, n1, n2;  // vertex normals; zero when the mesh has none
  uint32_t material;
  uint32_t light;  // index into the light list, kInvalid when not emissive
  uint32_t has_normals;
};

// Per-triangle texture coordinates, apart from TriangleShading: only textured scenes read them.
struct TriangleUv {
  vec2 uv0, uv1, uv2;
};

// Light::kind.
enum LightKind : uint32_t {
  kLightPrimitive = 0,    // an emissive triangle or sphere
  kLightEnvironment = 1,  // SceneView::infinite's environment
  kLightDistant = 2,      // SceneView::infinite->distant[prim]
  kLightPoint = 3,        // SceneView::point_lights[prim], a point light
  kLightSpot = 4,         // SceneView::point_lights[prim], a spot light
};

// Lights at infinity are not in the light tree; they come last in SceneView::lights.
TRACER_HD TRACER_INLINE bool light_at_infinity(uint32_t kind) {
  return kind == kLightEnvironment || kind == kLightDistant;
}

// A light to choose for next-event estimation: an emissive primitive (`prim` a unified primitive
// id, triangles first, then spheres), a light at infinity (kind; `prim` the distant light) or a
// point or spot light (`prim` its index in SceneView::point_lights).
struct Light {
  uint32_t prim;
  float area;
  // How often it is chosen: flux / pi (luminance x area for a one-sided emitter; for lights at
  // infinity the flux through the disc of the scene's bounding sphere, pbrt-v4's estimate; a
  // point light's flux is 4 pi I, a spot light's 2 pi I (1 - (cos start + cos end) / 2), as
  // pbrt-v4's Phi).
  float power;
  uint32_t kind;  // LightKind
};

// A plane of flat smooth reflectors: the scene's triangles of smooth glass (its Fresnel
// reflection), mirrors and smooth conductors (mnee_mirror_reflectance) that lie in one plane and
// face one way, with flat shading. Manifold NEE connects a vertex to a light by one reflection
// off each (integrator/path.h, MneeSolver): the light's mirror image in the plane.
struct ReflectorPlane {
  vec3 a;       // a point on it
  float pad0;
  vec3 n;       // its unit normal, the side its triangles face
  float pad1;
  vec3 lo, hi;  // the bounds of its triangles
  // Whether p lies within the bounds, widened by margin.
  TRACER_HD bool bounds_hold(vec3 p, float margin) const {
    return !glm::any(glm::lessThan(p, lo - margin)) && !glm::any(glm::greaterThan(p, hi + margin));
  }
};
// At most this many planes are listed (CompiledScene): a scene with more (a glass mesh of many
// facets) lists none, since every vertex would try each.
constexpr uint32_t kMaxReflectorPlanes = 16;

// A plane of flat faces of smooth glass of one material (a window: the front of a water tank),
// through which light tracing joins a vertex behind it to the camera by the one refraction
// there (integrator/light_path.h), and whose camera rays' transmissions give the light tracer
// the path's next vertex (shade_path).
struct WindowPlane {
  vec3 a;  // a point on it
  float eta;
  vec3 n;  // its unit normal (the glass's outside)
  uint32_t material;
  vec3 lo, hi;  // the bounds of its triangles
  TRACER_HD bool bounds_hold(vec3 p, float margin) const {
    return !glm::any(glm::lessThan(p, lo - margin)) && !glm::any(glm::greaterThan(p, hi + margin));
  }
  // Whether a hit (point p, unit geometric normal ng, material m) lies on one of its triangles'
  // plane (tol: the offset allowed).
  TRACER_HD bool holds(vec3 p, vec3 ng, uint32_t m, float tol) const {
    return m == material && glm::dot(ng, n) >= 1.0f - 1e-5f && glm::abs(glm::dot(p - a, n)) <= tol &&
           bounds_hold(p, tol);
  }
};
// At most this many are listed, the largest (a box of water is six; light tracing solves a
// refraction through each at every vertex that connects).
constexpr uint32_t kMaxWindowPlanes = 8;

// A bounding sphere of the surfaces where a light path's chain may start (a glass ball, the
// triangles of one caster material): light tracing aims its paths' first directions at the
// cones these subtend (integrator/light_path.h, start_light_path), since a path whose first
// event is elsewhere is not the light tracer's.
struct LightTarget {
  vec3 center;
  float radius;
};
constexpr uint32_t kMaxLightTargets = 16;

// The whole scene as the integrator reads it: the geometry that ray queries read (TraceView) and
// the shading data, materials, lights, textures and camera.
struct SceneView : TraceView {
  const TriangleShading* tri_shading = nullptr;
  const Material* materials = nullptr;
  const Light* lights = nullptr;
  const float* light_cdf = nullptr;       // light_count + 1 entries, 0 .. 1
  // The light tree (scene/light_tree_view.h): nodes (null when it would be one leaf or none),
  // leaves and each light's trail. The lights at infinity, outside the tree, are lights
  // [finite_light_count, light_count).
  LightTreeView light_tree = {nullptr, nullptr, nullptr};
  const TriangleUv* tri_uvs = nullptr;    // tri_count entries, or null when the mesh has none
  // The instanced meshes' triangles' shading data and uvs (or null), indexed like
  // TraceView::inst_tri_verts.
  const TriangleShading* inst_tri_shading = nullptr;
  const TriangleUv* inst_tri_uvs = nullptr;
  const TextureDesc* textures = nullptr;  // texture_count entries
  const uint32_t* texels = nullptr;       // RGBA8 texels of all textures, one after another
  // The environment and the distant lights; null when the scene has neither (its rays that
  // escape see black).
  const InfiniteLights* infinite = nullptr;
  // Point and spot lights (point_light_count entries; null when there are none).
  const PointLight* point_lights = nullptr;
  uint32_t point_light_count = 0;
  // The planes of flat smooth reflectors (reflector_plane_count <= kMaxReflectorPlanes).
  const ReflectorPlane* reflector_planes = nullptr;
  uint32_t reflector_plane_count = 0;
  // The window planes of smooth glass (window_plane_count <= kMaxWindowPlanes) and the offset
  // within which a point lies on one.
  const WindowPlane* window_planes = nullptr;
  uint32_t window_plane_count = 0;
  float window_tol = 0.0f;
  // Light tracing's targets (light_target_count <= kMaxLightTargets; none where the scene has
  // instances, or where no light path can start: light paths then leave by the cosine).
  const LightTarget* light_targets = nullptr;
  uint32_t light_target_count = 0;
  // Whether a ray into the scene's glass from one of its triangles meets something other than
  // that glass (a floor under water, a tank's walls): manifold NEE's one-refraction chain can
  // connect there (path.h); not through a closed glass slab or spheres.
  uint32_t open_glass = 0;
  uint32_t texture_count = 0;
  uint32_t material_count = 0, light_count = 0, finite_light_count = 0;
  uint32_t features = 0;
  Camera camera;
};

// Where the data of triangle hit id `prim` lives: the scene mesh's triangle `index` (instance
// kInvalid), or instance `instance`'s mesh triangle `index` of the inst_tri_* arrays.
struct TriangleRef {
  uint32_t index;
  uint32_t instance;
};
TRACER_HD TRACER_INLINE TriangleRef triangle_ref(const SceneView& s, uint32_t prim) {
  if (prim < s.tri_count) return {prim, kInvalid};
  const uint32_t i = find_instance(s.instances, s.instance_count, prim);
  return {s.instances[i].tri_base + (prim - s.instances[i].prim_base), i};
}
TRACER_HD TRACER_INLINE const TriangleShading& triangle_shading(const SceneView& s,
                                                                TriangleRef r) {
  return r.instance == kInvalid ? s.tri_shading[r.index] : s.inst_tri_shading[r.index];
}
// The triangle's uvs, or null when its mesh has none.
TRACER_HD TRACER_INLINE const TriangleUv* triangle_uvs(const SceneView& s, TriangleRef r) {
  const TriangleUv* uvs = r.instance == kInvalid ? s.tri_uvs : s.inst_tri_uvs;
  return uvs ? uvs + r.index : nullptr;
}
// The triangle's corners in the world.
TRACER_HD TRACER_INLINE TriangleVerts world_triangle(const SceneView& s, TriangleRef r) {
  if (r.instance == kInvalid) return load_triangle(s.tri_verts, r.index);
  TriangleVerts tv = load_triangle(s.inst_tri_verts, r.index);
  const Instance in = load_instance(s.instances, r.instance);
  tv.v0 = affine_point(in.world_from_object, tv.v0);
  tv.v1 = affine_point(in.world_from_object, tv.v1);
  tv.v2 = affine_point(in.world_from_object, tv.v2);
  return tv;
}

// Everything the shading stage needs to know about a hit point.
struct SurfaceHit {
  vec3 p;   // position
  vec3 ng;  // unit geometric normal (triangle winding / sphere outward)
  vec3 ns;  // unit shading normal, on the same side as ng
  vec2 uv;  // texture coordinates (F with kFeatureTextures only; else zero)
  uint32_t material;
  uint32_t light;  // kInvalid when not emissive
  bool front;      // the ray arrived on the ng side
};

template <uint32_t F = kAllFeatures>
TRACER_HD inline SurfaceHit make_surface_hit(const SceneView& s, const Ray& ray, const Hit& hit) {
  SurfaceHit sh;
  if ((F & kFeatureInstances) && hit.prim >= s.tri_count &&
      hit.prim - s.tri_count >= s.sphere_count) {
    // An instanced triangle: interpolated in its mesh's space, then mapped to the world (the
    // normals by the inverse transpose, which keeps them facing out under a mirroring map).
    const TriangleRef r = triangle_ref(s, hit.prim);
    const Instance in = load_instance(s.instances, r.instance);
    const TriangleVerts tv = load_triangle(s.inst_tri_verts, r.index);
    const TriangleShading& ts = s.inst_tri_shading[r.index];
    const float b0 = 1.0f - hit.u - hit.v;
    sh.p = affine_point(in.world_from_object, b0 * tv.v0 + hit.u * tv.v1 + hit.v * tv.v2);
    sh.ng = fast_normalize(instance_normal(in, glm::cross(tv.v1 - tv.v0, tv.v2 - tv.v0)));
    sh.ns = sh.ng;
    if (ts.has_normals) {
      const vec3 n = instance_normal(in, b0 * ts.n0 + hit.u * ts.n1 + hit.v * ts.n2);
      const float len = glm::length(n);
      if (len > 0.0f) sh.ns = n / len;
      if (glm::dot(sh.ns, sh.ng) < 0.0f) sh.ns = -sh.ns;
    }
    sh.material = ts.material;
    sh.light = kInvalid;  // instanced meshes never emit (scene.h)
    sh.uv = vec2(0.0f);
    if ((F & kFeatureTextures) && s.inst_tri_uvs) {
      const TriangleUv tu = s.inst_tri_uvs[r.index];
      sh.uv = b0 * tu.uv0 + hit.u * tu.uv1 + hit.v * tu.uv2;
    }
  } else if (!(F & kFeatureSpheres) || hit.prim < s.tri_count) {
    const TriangleVerts tv = load_triangle(s.tri_verts, hit.prim);
    const TriangleShading& ts = s.tri_shading[hit.prim];
    const float b0 = 1.0f - hit.u - hit.v;
    // Barycentric interpolation is more accurate than o + t d (pbrt-v4 sec. 6.8.5).
    sh.p = b0 * tv.v0 + hit.u * tv.v1 + hit.v * tv.v2;
    sh.ng = fast_normalize(glm::cross(tv.v1 - tv.v0, tv.v2 - tv.v0));
    sh.ns = sh.ng;
    if (ts.has_normals) {
      const vec3 n = b0 * ts.n0 + hit.u * ts.n1 + hit.v * ts.n2;
      const float len = glm::length(n);
      if (len > 0.0f) sh.ns = n / len;
      if (glm::dot(sh.ns, sh.ng) < 0.0f) sh.ns = -sh.ns;
    }
    sh.material = ts.material;
    sh.light = ts.light;
    sh.uv = vec2(0.0f);
    if ((F & kFeatureTextures) && s.tri_uvs) {
      const TriangleUv tu = s.tri_uvs[hit.prim];
      sh.uv = b0 * tu.uv0 + hit.u * tu.uv1 + hit.v * tu.uv2;
    }
  } else {
    const Sphere& sph = s.spheres[hit.prim - s.tri_count];
    const vec3 p = ray.o + hit.t * ray.d;
    // Re-project onto the surface to remove the error of o + t d (pbrt-v4 sec. 6.8.5), in double:
    // in float, centre + radius * n of a radius-1e5 wall is off by ulp(1e5) = 0.008, more than
    // the ray offset at a point 100 units from the origin.
    const double ex = double(p.x) - double(sph.center.x), ey = double(p.y) - double(sph.center.y),
                 ez = double(p.z) - double(sph.center.z);
    const double inv = 1.0 / sqrt(ex * ex + ey * ey + ez * ez);
    sh.ng = vec3(float(ex * inv), float(ey * inv), float(ez * inv));
    const double k = double(sph.radius) * inv;
    sh.p = vec3(float(double(sph.center.x) + k * ex), float(double(sph.center.y) + k * ey),
                float(double(sph.center.z) + k * ez));
    sh.ns = sh.ng;
    sh.uv = vec2(0.0f);  // spheres have no texture coordinates
    sh.material = sph.material;
    sh.light = sph.light;
  }
  sh.front = glm::dot(ray.d, sh.ng) < 0.0f;
  return sh;
}

}  // namespace tracer
