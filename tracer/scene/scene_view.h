// The flattened scene both backends trace: plain arrays linked by uint32 indices, readable from
// host or device memory alike, plus BVH traversal over them.
#pragma once

#include "bvh/bvh.h"
#include "bvh/geometry.h"
#include "camera/camera.h"
#include "core/features.h"
#include "materials/material.h"
#include "materials/texture.h"

namespace tracer {

// Cold per-triangle data, read only after a hit.
struct TriangleShading {
  vec3 n0, n1, n2;     // vertex normals; zero when the mesh has none
  uint32_t material;
  uint32_t light;      // index into the light list, kInvalid when not emissive
  uint32_t has_normals;
};

// Per-triangle texture coordinates, apart from TriangleShading: only textured scenes read them.
struct TriangleUv {
  vec2 uv0, uv1, uv2;
};

// An emissive primitive. `prim` is a unified primitive id (triangles first, then spheres).
struct Light {
  uint32_t prim;
  float area;
  float power;  // luminance of the emission times area: how often it is chosen
  uint32_t pad;
};

struct SceneView {
  const BvhNode* nodes = nullptr;
  const uint32_t* prim_indices = nullptr;
  const TriangleVerts* tri_verts = nullptr;
  const TriangleShading* tri_shading = nullptr;
  const Sphere* spheres = nullptr;
  const Material* materials = nullptr;
  const Light* lights = nullptr;
  const float* light_cdf = nullptr;  // light_count + 1 entries, 0 .. 1
  const TriangleUv* tri_uvs = nullptr;    // tri_count entries, or null when the mesh has none
  const TextureDesc* textures = nullptr;  // texture_count entries
  const uint32_t* texels = nullptr;       // RGBA8 texels of all textures, one after another
  uint32_t texture_count = 0;
  uint32_t node_count = 0, tri_count = 0, sphere_count = 0, material_count = 0, light_count = 0;
  uint32_t features = 0;
  Camera camera;
};

// True when `pred` holds for every active lane of the warp (on the CPU: for this thread).
TRACER_HD TRACER_INLINE bool warp_all(bool pred) {
#if defined(__CUDA_ARCH__)
  return __all_sync(__activemask(), pred);
#else
  return pred;
#endif
}

// Tests the primitives of one leaf; returns true when an any-hit query may stop.
template <uint32_t F, bool kAnyHit>
TRACER_HD TRACER_INLINE bool intersect_leaf(const SceneView& s, const Ray& ray,
                                            const RayTriSetup& setup, const BvhNode& leaf,
                                            uint32_t skip, uint32_t skip2, float& tmax,
                                            Hit& hit) {
  for (uint32_t i = 0; i < leaf.count; ++i) {
    const uint32_t prim = s.prim_indices[leaf.left_first + i];
    if (prim == skip || prim == skip2) continue;
    float t, b1 = 0.0f, b2 = 0.0f;
    bool h;
    if (!(F & kFeatureSpheres) || prim < s.tri_count) {
      const TriangleVerts tv = load_triangle(s.tri_verts, prim);
      h = intersect_triangle(ray, setup, tv.v0, tv.v1, tv.v2, tmax, t, b1, b2);
    } else {
      const Sphere sph = load_sphere(s.spheres, prim - s.tri_count);
      h = intersect_sphere(ray, sph.center, sph.radius, tmax, t);
    }
    if (h) {
      tmax = t;
      hit.t = t;
      hit.prim = prim;
      hit.u = b1;
      hit.v = b2;
      if (kAnyHit) return true;
    }
  }
  return false;
}

// BVH traversal in the "while-while" form with postponed leaves of Aila & Laine, "Understanding
// the Efficiency of Ray Traversal on GPUs" (HPG 2009): a lane that reaches a leaf parks it and
// keeps descending inner nodes until every lane of the warp holds a leaf, then all test their
// leaves together. This keeps the lanes of a warp on the same kind of work. Children are visited
// near-first. kAnyHit stops at the first hit in (0, ray.tmax). Primitives `skip` and `skip2` are
// ignored: the light a shadow ray aims at, and the triangle a ray leaves from (a ray cannot
// re-enter the plane it left; this backs up the origin offset where a triangle is much larger
// than the distances involved).
template <uint32_t F, bool kAnyHit>
TRACER_HD inline Hit traverse(const SceneView& s, const Ray& ray, uint32_t skip, uint32_t skip2) {
  Hit hit;
  if (s.node_count == 0) return hit;
  const RayTriSetup setup(ray.d);
  const vec3 inv_d = 1.0f / ray.d;  // infinities are handled by intersect_aabb
  float tmax = ray.tmax;
  uint32_t stack[kBvhStackSize];
  int sp = 0;
  BvhNode node = load_node(s.nodes, 0);
  bool have_node = intersect_aabb(node.lo, node.hi, ray.o, inv_d, tmax) != kInfinity;
  BvhNode leaf;
  bool have_leaf = false;
  while (have_node || have_leaf) {
    // Descend inner nodes; park the first leaf found and go on until the whole warp has one.
    while (have_node && !node.is_leaf()) {
      const uint32_t c0 = node.left_first, c1 = node.left_first + 1;
      const BvhNode n0 = load_node(s.nodes, c0), n1 = load_node(s.nodes, c1);
      const float d0 = intersect_aabb(n0.lo, n0.hi, ray.o, inv_d, tmax);
      const float d1 = intersect_aabb(n1.lo, n1.hi, ray.o, inv_d, tmax);
      const bool swap = d1 < d0;
      if ((swap ? d1 : d0) == kInfinity) {
        have_node = sp > 0;
        if (have_node) node = load_node(s.nodes, stack[--sp]);
      } else {
        if ((swap ? d0 : d1) != kInfinity) stack[sp++] = swap ? c0 : c1;
        node = swap ? n1 : n0;
      }
      if (have_node && node.is_leaf() && !have_leaf) {
        leaf = node;
        have_leaf = true;
        have_node = sp > 0;
        if (have_node) node = load_node(s.nodes, stack[--sp]);
      }
      if (warp_all(have_leaf)) break;
    }
    if (!have_leaf && have_node && node.is_leaf()) {
      leaf = node;
      have_leaf = true;
      have_node = sp > 0;
      if (have_node) node = load_node(s.nodes, stack[--sp]);
    }
    // Test the parked leaf, then any leaf that is next in line.
    while (have_leaf) {
      if (intersect_leaf<F, kAnyHit>(s, ray, setup, leaf, skip, skip2, tmax, hit)) return hit;
      have_leaf = have_node && node.is_leaf();
      if (have_leaf) {
        leaf = node;
        have_node = sp > 0;
        if (have_node) node = load_node(s.nodes, stack[--sp]);
      }
    }
  }
  return hit;
}

// Nearest hit along the ray in (0, ray.tmax), ignoring primitive `skip` (the triangle the ray
// leaves from, or kInvalid). F without kFeatureSpheres: the scene has none.
template <uint32_t F = kAllFeatures>
TRACER_HD inline Hit intersect_closest(const SceneView& s, const Ray& ray,
                                       uint32_t skip = kInvalid) {
  return traverse<F, false>(s, ray, skip, kInvalid);
}

// True when anything blocks the ray in (0, ray.tmax), ignoring primitive `skip` (the light the
// shadow ray aims at, so that reaching it is never mistaken for being blocked).
template <uint32_t F = kAllFeatures>
TRACER_HD inline bool intersect_any(const SceneView& s, const Ray& ray, uint32_t skip,
                                    uint32_t skip2 = kInvalid) {
  return traverse<F, true>(s, ray, skip, skip2).valid();
}

// Everything the shading stage needs to know about a hit point.
struct SurfaceHit {
  vec3 p;         // position
  vec3 ng;        // unit geometric normal (triangle winding / sphere outward)
  vec3 ns;        // unit shading normal, on the same side as ng
  vec2 uv;        // texture coordinates (F with kFeatureTextures only; else zero)
  uint32_t material;
  uint32_t light;  // kInvalid when not emissive
  bool front;      // the ray arrived on the ng side
};

template <uint32_t F = kAllFeatures>
TRACER_HD inline SurfaceHit make_surface_hit(const SceneView& s, const Ray& ray, const Hit& hit) {
  SurfaceHit sh;
  if (!(F & kFeatureSpheres) || hit.prim < s.tri_count) {
    const TriangleVerts tv = load_triangle(s.tri_verts, hit.prim);
    const TriangleShading& ts = s.tri_shading[hit.prim];
    const float b0 = 1.0f - hit.u - hit.v;
    // Barycentric interpolation is more accurate than o + t d (pbrt-v4 sec. 6.8.5).
    sh.p = b0 * tv.v0 + hit.u * tv.v1 + hit.v * tv.v2;
    sh.ng = glm::normalize(glm::cross(tv.v1 - tv.v0, tv.v2 - tv.v0));
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
    sh.ng = glm::normalize(p - sph.center);
    // Re-project onto the surface to remove the error of o + t d (pbrt-v4 sec. 6.8.5).
    sh.p = sph.center + sph.radius * sh.ng;
    sh.ns = sh.ng;
    sh.uv = vec2(0.0f);  // spheres have no texture coordinates
    sh.material = sph.material;
    sh.light = sph.light;
  }
  sh.front = glm::dot(ray.d, sh.ng) < 0.0f;
  return sh;
}

}  // namespace tracer
