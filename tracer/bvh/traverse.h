// Ray queries over the flattened geometry both backends trace: the BVH walk, the loops over the
// flat primitive list of small scenes and their slab tests. TraceView holds the plain arrays they
// read (uint32 indices, host or device memory); scene/scene_view.h adds the shading data to it.
#pragma once

#include "bvh/bvh.h"
#include "bvh/bvh8.h"
#include "bvh/cpu_bvh.h"
#include "bvh/flat_list.h"
#include "bvh/geometry.h"
#include "bvh/instance.h"
#include "core/features.h"

namespace tracer {

// The arrays a ray query reads.
struct TraceView {
  const BvhNode* nodes = nullptr;
  const uint32_t* prim_indices = nullptr;
  // The 8-wide compressed tree (bvh/bvh8.h) and its primitive order: when set, the BVH walk of a
  // bvh8 build (TRACER_VARIANT_BVH8) uses it instead of `nodes` and `prim_indices`; node_count
  // is then its node count. Other builds compile no 8-wide walk and ignore them.
  const Bvh8Node* nodes8 = nullptr;
  const uint32_t* prim_indices8 = nullptr;
  const TriangleVerts* tri_verts = nullptr;
  const Sphere* spheres = nullptr;
  uint32_t node_count = 0, tri_count = 0, sphere_count = 0;
  // The CPU backend's SSE layout of the same BVH (bvh/cpu_bvh.h); empty on the GPU, in tests
  // that build views by hand, and where the CPU backend is told to use the shared traversal.
  CpuBvhView cpu_bvh;
  // The flat primitive list of a small scene (bvh/flat_list.h). With use_flat set, queries test
  // its flat_count entries (the first flat_quads of them parallelograms) and every sphere in a
  // warp-uniform loop instead of walking the BVH. The GPU sets it by default where the scene has
  // a list; the CPU keeps its SSE BVH unless told otherwise.
  const FlatPrim* flat = nullptr;
  // The same entries as the loops over the list read them: `flat` itself on the CPU; on the GPU
  // a copy among the kernel's parameters (cuda/kernels.h, FlatParams), so that each warp's
  // uniform loads come from the constant bank instead of the L1 data pipe.
  const FlatPrim* flat_loop = nullptr;
  const FlatPrimInfo* flat_info = nullptr;
  const uint32_t* tri_to_flat = nullptr;  // tri_count entries
  uint32_t flat_count = 0, flat_quads = 0;
  // Entries [0, flat_quad_blockers) and [flat_quads, flat_triangle_blockers_end) can block a ray
  // between two points of the scene; the others lie on its hull (FlatList).
  uint32_t flat_quad_blockers = 0, flat_triangle_blockers_end = 0;
  // The last flat_box_faces quads cover faces of the scene's box (FlatList::box_entry): queries
  // find them with one slab test (flat_box_hit) and loop over the quads before them.
  uint32_t flat_box_faces = 0;
  vec3 flat_box_lo = vec3(0.0f), flat_box_hi = vec3(0.0f);
  uint32_t flat_box_entry[6] = {kInvalid, kInvalid, kInvalid, kInvalid, kInvalid, kInvalid};
  // Solid boxes (FlatList::solids): each a map onto the centred unit cube, its six faces
  // entries [6 g, 6 g + 6); the quad loops start after them (flat_quads_begin). On the GPU the
  // maps too come from the kernel's parameters where it has them.
  const FlatPrim* flat_solids = nullptr;
  uint32_t flat_solid_count = 0;
  uint32_t use_flat = 0;
  // Instances of meshes (bvh/instance.h; F with kFeatureInstances). Entries from
  // tri_count + sphere_count on of the tree's leaves are instances; each walks its mesh's tree,
  // which starts at its root in inst_nodes (the meshes' trees, one after another; leaves index
  // inst_prim_indices, whose entries index inst_tri_verts). A hit on an instanced triangle has
  // the id Instance::prim_base + its index in its mesh: ids from tri_count + sphere_count on,
  // unique over all instances.
  const Instance* instances = nullptr;
  const BvhNode* inst_nodes = nullptr;
  const uint32_t* inst_prim_indices = nullptr;
  const TriangleVerts* inst_tri_verts = nullptr;
  uint32_t instance_count = 0;
};

// Whether hit id `prim` is a triangle (of the scene's mesh or of an instance), not a sphere.
TRACER_HD TRACER_INLINE bool prim_is_triangle(const TraceView& s, uint32_t prim) {
  return prim < s.tri_count || prim - s.tri_count >= s.sphere_count;
}

// The first quad that the loops over the flat list test (the solids' faces come before it).
TRACER_HD TRACER_INLINE uint32_t flat_quads_begin(const TraceView& s) {
  return 6 * s.flat_solid_count;
}

// True when `pred` holds for every active lane of the warp (on the CPU: for this thread).
TRACER_HD TRACER_INLINE bool warp_all(bool pred) {
#if defined(__CUDA_ARCH__)
  return __all_sync(__activemask(), pred);
#else
  return pred;
#endif
}

// Orders two (distance, reference) pairs nearest first.
TRACER_HD TRACER_INLINE void order_pair(float& da, uint32_t& ra, float& db, uint32_t& rb) {
  const bool swap = db < da;
  const float d = swap ? db : da;
  const uint32_t r = swap ? rb : ra;
  db = swap ? da : db;
  rb = swap ? ra : rb;
  da = d;
  ra = r;
}

// The children of 4-wide node `node`: their entry distances (kInfinity where the ray misses
// the box) and references, nearest first when kSorted (a five-comparator network; any-hit
// queries leave them in slot order). Both levels of the BVH walk test their nodes with it.
template <bool kSorted>
TRACER_HD TRACER_INLINE void test_children(const BvhNode* nodes, uint32_t node, const Ray& ray,
                                           vec3 inv_d, float tmax, float (&d)[kBvhWidth],
                                           uint32_t (&r)[kBvhWidth]) {
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (int i = 0; i < kBvhWidth; ++i) {
    const BvhSlot slot = load_slot(nodes, node, i);
    d[i] = intersect_aabb(slot.lo, slot.hi, ray.o, inv_d, tmax);
    r[i] = slot.ref;
  }
  if (kSorted) {
    order_pair(d[0], r[0], d[1], r[1]);
    order_pair(d[2], r[2], d[3], r[3]);
    order_pair(d[0], r[0], d[2], r[2]);
    order_pair(d[1], r[1], d[3], r[3]);
    order_pair(d[1], r[1], d[2], r[2]);
  }
}

// The ray against instance `i`'s mesh: the ray mapped into the mesh's space walks the mesh's
// tree (a plain depth-first walk with its own stack, near child first for closest hits). Hits
// update tmax and hit as intersect_leaf does; returns true when an any-hit query may stop. Not
// inlined on the GPU, so that the walk of the first level keeps its registers.
template <bool kAnyHit>
#if defined(__CUDA_ARCH__)
__device__ __noinline__
#else
inline
#endif
bool intersect_instance(const TraceView& s, uint32_t i, const Ray& world_ray, uint32_t skip,
                        uint32_t skip2, float& tmax, Hit& hit) {
  const Instance in = load_instance(s.instances, i);
  Ray ray;
  ray.o = affine_point(in.object_from_world, world_ray.o);
  ray.d = affine_vector(in.object_from_world, world_ray.d);
  ray.tmax = tmax;
  ray.pad = 0.0f;
  if (!(is_finite(ray.o) && is_finite(ray.d))) return false;
  const vec3 inv_d = 1.0f / ray.d;
  const RayTriSetup setup(ray, inv_d);
  uint32_t stack[kBvhStackSize];
  int sp = 0;
  uint32_t next = in.root;
  for (;;) {
    if (!is_leaf_ref(next)) {
      float d[kBvhWidth];
      uint32_t r[kBvhWidth];
      test_children<!kAnyHit>(s.inst_nodes, next, ray, inv_d, tmax, d, r);
      for (int k = kBvhWidth - 1; k > 0; --k)
        if (d[k] != kInfinity) stack[sp++] = r[k];
      if (d[0] != kInfinity) {
        next = r[0];
        continue;
      }
    } else {
      for (uint32_t e = next & ~kBvhLeafBit;; ++e) {
        const uint32_t entry = s.inst_prim_indices[e];
        const uint32_t tri = entry & ~kBvhLastPrimBit;
        const uint32_t prim = in.prim_base + (tri - in.tri_base);
        float t, b1, b2;
        if (prim != skip && prim != skip2) {
          const TriangleVerts tv = load_triangle(s.inst_tri_verts, tri);
          if (intersect_triangle(setup, tv.v0, tv.v1, tv.v2, tmax, t, b1, b2)) {
            tmax = t;
            hit.t = t;
            hit.prim = prim;
            hit.u = b1;
            hit.v = b2;
            if (kAnyHit) return true;
          }
        }
        if (entry & kBvhLastPrimBit) break;
      }
    }
    if (sp == 0) return false;
    next = stack[--sp];
  }
}

// Tests the primitives of the leaf `ref` (a leaf reference, see bvh.h); returns true when an
// any-hit query may stop.
template <uint32_t F, bool kAnyHit>
TRACER_HD TRACER_INLINE bool intersect_leaf(const TraceView& s, const uint32_t* prim_indices,
                                            const Ray& ray, const RayTriSetup& setup,
                                            uint32_t ref, uint32_t skip, uint32_t skip2,
                                            float& tmax, Hit& hit) {
  for (uint32_t i = ref & ~kBvhLeafBit;; ++i) {
    const uint32_t entry = prim_indices[i];
    const uint32_t prim = entry & ~kBvhLastPrimBit;
    if ((F & kFeatureInstances) && prim - s.tri_count >= s.sphere_count &&
        prim >= s.tri_count) {
      if (intersect_instance<kAnyHit>(s, prim - s.tri_count - s.sphere_count, ray, skip, skip2,
                                      tmax, hit))
        return true;
    } else if (prim != skip && prim != skip2) {
      float t, b1 = 0.0f, b2 = 0.0f;
      bool h;
      if (!(F & kFeatureSpheres) || prim < s.tri_count) {
        const TriangleVerts tv = load_triangle(s.tri_verts, prim);
        h = intersect_triangle(setup, tv.v0, tv.v1, tv.v2, tmax, t, b1, b2);
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
    if (entry & kBvhLastPrimBit) return false;
  }
}

// The traversal's state besides the ray: the stack of child references and where the walk is.
// Kept as separate locals by the callers and passed by reference to the force-inlined round
// below, so that nvcc keeps all but the stack in registers (a struct holding the stack array
// would go to local memory whole: docs/PERFORMANCE.md, decision log, row 31).
struct TraversalCursor {
  int sp;
  uint32_t next;  // the next child reference to visit; the root is an inner node
  uint32_t leaf;
  bool have_next;
  bool have_leaf;
};

// Takes the reference next in line (a leaf) as the leaf to test and pops the one after it (the
// caller sets have_leaf).
TRACER_HD TRACER_INLINE void take_next_leaf(TraversalCursor& c, const uint32_t* stack) {
  c.leaf = c.next;
  c.have_next = c.sp > 0;
  if (c.have_next) c.next = stack[--c.sp];
}

// One step of the walk in the 8-wide tree: tests the eight child boxes of inner node `node`
// (decoded from their 8-bit planes, then the slab test of bvh.h), goes on with the first child
// hit in the ray's octant order and pushes the others hit, so that they pop in that order (the
// builder put the child nearest to where rays of octant o come from in slot o, and the order
// i ^ o for i = 0..7 visits near children first without sorting). With none hit it pops.
TRACER_HD TRACER_INLINE void expand_node8(const Bvh8Node* nodes, uint32_t node, const Ray& ray,
                                          vec3 inv_d, float tmax, uint32_t* stack,
                                          TraversalCursor& c) {
  const Bvh8Node n = load_node8(nodes, node);
  const float sx = bvh8_scale(n.exps, 0), sy = bvh8_scale(n.exps, 1),
              sz = bvh8_scale(n.exps, 2);
  uint32_t hits = 0;
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (uint32_t slot = 0; slot < kBvh8Width; ++slot) {
    const vec3 lo(bvh8_plane(n.origin.x, bvh8_byte(n.q[0], slot), sx),
                  bvh8_plane(n.origin.y, bvh8_byte(n.q[1], slot), sy),
                  bvh8_plane(n.origin.z, bvh8_byte(n.q[2], slot), sz));
    const vec3 hi(bvh8_plane(n.origin.x, bvh8_byte(n.q[3], slot), sx),
                  bvh8_plane(n.origin.y, bvh8_byte(n.q[4], slot), sy),
                  bvh8_plane(n.origin.z, bvh8_byte(n.q[5], slot), sz));
    const bool hit = intersect_aabb(lo, hi, ray.o, inv_d, tmax) != kInfinity;
    hits |= (hit && bvh8_byte(n.meta, slot) != 0) ? (1u << slot) : 0u;
  }
  const uint32_t oct = (inv_d.x < 0.0f ? 1u : 0u) | (inv_d.y < 0.0f ? 2u : 0u) |
                       (inv_d.z < 0.0f ? 4u : 0u);
  bool have = false;
  uint32_t first = 0;
  // The slots' meta bytes as one 64-bit value: the order below picks slots by a run-time index,
  // which a shift of a register can follow where an array index would send the node to local
  // memory.
  const uint64_t metas = uint64_t(n.meta[0]) | uint64_t(n.meta[1]) << 32;
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (int i = kBvh8Width - 1; i >= 0; --i) {
    const uint32_t slot = uint32_t(i) ^ oct;
    if (!((hits >> slot) & 1u)) continue;
    const uint32_t meta = uint32_t(metas >> (8u * slot)) & 0xffu;
    const uint32_t ref = (meta & 0x80u) ? n.child_base + (meta & 0x7fu)
                                        : kBvhLeafBit | (n.prim_base + meta - 1u);
    if (have) stack[c.sp++] = first;
    first = ref;
    have = true;
  }
  if (have) {
    c.next = first;
  } else {
    c.have_next = c.sp > 0;
    if (c.have_next) c.next = stack[--c.sp];
  }
}

// One round of the traversal below: descend inner nodes, parking the first leaf found, until
// the whole warp holds a leaf; then test the parked leaf and any leaf next in line. True when
// the ray is done (the result in `hit`). traverse() runs rounds to the end for one ray; the
// wavefront's dynamic-fetch intersect kernel gives a lane whose ray is done a new ray between
// rounds while the rest of its warp goes on.
template <uint32_t F, bool kAnyHit>
TRACER_HD TRACER_INLINE bool traverse_round(const TraceView& s, const Ray& ray, vec3 inv_d,
                                            const RayTriSetup& setup, uint32_t skip,
                                            uint32_t skip2, float& tmax, Hit& hit,
                                            uint32_t* stack, TraversalCursor& c) {
  if (!(c.have_next || c.have_leaf)) return true;
  while (c.have_next && !is_leaf_ref(c.next)) {
#if defined(TRACER_VARIANT_BVH8)
    if (s.nodes8)
      expand_node8(s.nodes8, c.next, ray, inv_d, tmax, stack, c);
    else
#endif
    {
      float d[kBvhWidth];
      uint32_t r[kBvhWidth];
      test_children<!kAnyHit>(s.nodes, c.next, ray, inv_d, tmax, d, r);
      // Push the farther children that were hit, farthest first; go on with the nearest.
#if defined(__CUDACC__)
#pragma unroll
#endif
      for (int i = kBvhWidth - 1; i > 0; --i)
        if (d[i] != kInfinity) stack[c.sp++] = r[i];
      if (d[0] != kInfinity) {
        c.next = r[0];
      } else {
        c.have_next = c.sp > 0;
        if (c.have_next) c.next = stack[--c.sp];
      }
    }
    if (c.have_next && is_leaf_ref(c.next) && !c.have_leaf) {
      c.have_leaf = true;
      take_next_leaf(c, stack);
    }
    if (warp_all(c.have_leaf)) break;
  }
  if (!c.have_leaf && c.have_next && is_leaf_ref(c.next)) {
    c.have_leaf = true;
    take_next_leaf(c, stack);
  }
  // Test the parked leaf, then any leaf that is next in line.
#if defined(TRACER_VARIANT_BVH8)
  const uint32_t* prims = s.nodes8 ? s.prim_indices8 : s.prim_indices;
#else
  const uint32_t* prims = s.prim_indices;
#endif
  while (c.have_leaf) {
    if (intersect_leaf<F, kAnyHit>(s, prims, ray, setup, c.leaf, skip, skip2, tmax, hit))
      return true;
    c.have_leaf = c.have_next && is_leaf_ref(c.next);
    if (c.have_leaf) take_next_leaf(c, stack);
  }
  return !(c.have_next || c.have_leaf);
}

// Whether a ray can be traced at all. The slab test ignores NaN on purpose (a ray lying in a
// slab's plane), so a ray with a NaN or infinite origin or direction passes every slab test, the
// empty slots' too, whose reference is the root: it would push without end and overflow the
// stack. validate_scene keeps scenes in the range where spawned rays stay finite; this check
// protects callers that skip it, once per ray rather than in the loop.
TRACER_HD TRACER_INLINE bool ray_is_traceable(const Ray& ray) {
  return is_finite(ray.o) && is_finite(ray.d);
}

TRACER_HD TRACER_INLINE TraversalCursor traversal_start(const TraceView& s, const Ray& ray) {
  TraversalCursor c;
  c.sp = 0;
  c.next = 0;
  c.leaf = 0;
  c.have_next = s.node_count != 0 && ray_is_traceable(ray);
  c.have_leaf = false;
  return c;
}

// Entry i of the flat list. kLoop (the loops over the list, TraceView::flat_loop): plain loads,
// so that the device compiler reads a list among the kernel parameters from the constant bank
// (LDC); otherwise (the one entry a lane hit, in global memory) through the read-only cache,
// whose __ldg would force a global load of a parameter.
template <bool kLoop>
TRACER_HD TRACER_INLINE FlatPrim load_flat_entry(const FlatPrim* prims, uint32_t i) {
#if defined(__CUDA_ARCH__)
  const float4* p = reinterpret_cast<const float4*>(prims + i);
  const float4 a = kLoop ? p[0] : __ldg(p), b = kLoop ? p[1] : __ldg(p + 1),
               c = kLoop ? p[2] : __ldg(p + 2);
  FlatPrim f;
  f.row_u = vec4(a.x, a.y, a.z, a.w);
  f.row_v = vec4(b.x, b.y, b.z, b.w);
  f.row_w = vec4(c.x, c.y, c.z, c.w);
  return f;
#else
  return prims[i];
#endif
}
TRACER_HD TRACER_INLINE FlatPrim load_flat(const FlatPrim* prims, uint32_t i) {
  return load_flat_entry<false>(prims, i);
}
TRACER_HD TRACER_INLINE FlatPrim load_flat_loop(const FlatPrim* prims, uint32_t i) {
  return load_flat_entry<true>(prims, i);
}

// a * b + c: fused on the GPU; on the CPU two operations (a baseline x86-64 build has no FMA
// instruction, and fmaf would be a library call).
TRACER_HD TRACER_INLINE float flat_fma(float a, float b, float c) {
#if defined(__CUDA_ARCH__)
  return fmaf(a, b, c);
#else
  return a * b + c;
#endif
}

// dot(row.xyz, p) + row.w as one chain of multiply-adds (three instructions on the GPU).
TRACER_HD TRACER_INLINE float flat_affine(vec4 row, vec3 p) {
  return flat_fma(row.x, p.x, flat_fma(row.y, p.y, flat_fma(row.z, p.z, row.w)));
}

// The ray's distance to an entry's plane and the local coordinates of the crossing point:
// w(o + t d) = 0 gives t = -w(o) / (w(d) - w(0)); u and v are read at the point itself, so the
// point is made once for both. The reciprocal is the approximate one (fast_rcp): a correctly
// rounded division per primitive would add a third to the test. A ray parallel to the plane
// gets an infinite or NaN t, which every comparison of flat_accept rejects.
TRACER_HD TRACER_INLINE void flat_hit(const FlatPrim& p, vec3 o, vec3 d, float& t, float& u,
                                      float& v) {
  const float dw = flat_fma(p.row_w.x, d.x, flat_fma(p.row_w.y, d.y, p.row_w.z * d.z));
  t = -flat_affine(p.row_w, o) * fast_rcp(dw);
  const vec3 x(flat_fma(t, d.x, o.x), flat_fma(t, d.y, o.y), flat_fma(t, d.z, o.z));
  u = flat_affine(p.row_u, x);
  v = flat_affine(p.row_v, x);
}

// Whether a crossing at distance t and local (u, v) is a hit in (0, tmax): (u, v) in the unit
// square (kQuads: centred, |u|, |v| <= 1/2) or the unit triangle, edges widened by
// kFlatEdgeTolerance. Written with & rather than &&, so that the GPU chains the comparisons in
// predicates (one instruction each) instead of branching and keeping booleans in registers.
// NaN coordinates (a ray in the plane) fail every comparison.
template <bool kQuads>
TRACER_HD TRACER_INLINE bool flat_accept(float u, float v, float t, float tmax) {
  constexpr float e = kFlatEdgeTolerance;
  const bool inside = kQuads ? (glm::abs(u) <= 0.5f + e) & (glm::abs(v) <= 0.5f + e)
                             : (u >= -e) & (v >= -e) & (u + v <= 1.0f + e);
  return inside & (t > 0.0f) & (t < tmax);
}

// Entries [begin, end) of the flat list against one ray: every lane runs the same iterations
// (no branch depends on the ray), so a warp stays converged. Keeps the nearest hit in
// (0, tbest) in best; entries fa and fb are skipped. An any-hit query leaves the loop once
// every active lane of the warp has a hit.
template <bool kQuads, bool kAnyHit>
TRACER_HD TRACER_INLINE void flat_range(const FlatPrim* prims, uint32_t begin, uint32_t end,
                                        vec3 o, vec3 d, uint32_t fa, uint32_t fb, float& tbest,
                                        uint32_t& best) {
#if defined(__CUDACC__)
#pragma unroll 2
#endif
  for (uint32_t i = begin; i < end; ++i) {
    float t, u, v;
    flat_hit(load_flat_loop(prims, i), o, d, t, u, v);
    if (flat_accept<kQuads>(u, v, t, tbest) & (i != fa) & (i != fb)) {
      tbest = t;
      best = i;
    }
    if (kAnyHit && warp_all(best != kInvalid)) return;
  }
}

// The hit of entry `best` at distance t (none when best is kInvalid), as the triangle and its
// barycentrics: the loops keep only t and the entry, and the same arithmetic again gives the
// entry's (u, v), which its map turns into the barycentrics of the half they fall in.
TRACER_HD TRACER_INLINE Hit flat_entry_hit(const TraceView& s, const Ray& ray, uint32_t best,
                                           float t) {
  Hit hit;
  if (best == kInvalid) return hit;
  float t_again, u, v;
  flat_hit(load_flat(s.flat, best), ray.o, ray.d, t_again, u, v);
  if (best < s.flat_quads) {  // centred parallelogram coordinates
    u += 0.5f;
    v += 0.5f;
  }
  const FlatPrimInfo& info = s.flat_info[best];
  const bool second = info.tri1 != kInvalid && u + v > 1.0f;
  const float* m = second ? info.map1 : info.map0;
  hit.t = t;
  hit.prim = second ? info.tri1 : info.tri0;
  hit.u = m[0] * u + m[1] * v + m[2];
  hit.v = m[3] * u + m[4] * v + m[5];
  return hit;
}

// The face of the scene's box (TraceView::flat_box_entry) that a ray meets first, if that is in
// (0, tbest) and the face is not entry fa or fb: then tbest and best become its distance and
// entry. The slab test (Kay & Kajiya 1986) gives where the ray enters the box (tn, through
// entry en) and leaves it (tf, ef). A ray from inside meets the face it leaves by; one from
// outside the face it enters by, or, where that face is open, the one it leaves by. Nothing lies
// outside the box, so no other entry can come first, and entries inside are tested as usual. A
// ray parallel to a slab gets infinite distances there (or NaN exactly in a face's plane, which
// leaves that slab out).
// The slab test shared by the scene's box and the solid boxes: o and d in the box's own
// coordinates, lo[a] / hi[a] its faces' planes, entry(f) the entry of face f = 2 * axis + side
// (kOpen: kInvalid where a face is open). A ray from inside meets the face it leaves by; one
// from outside the face it enters by, or, where that face is open or skipped, the one it leaves
// by. A ray parallel to a slab gets infinite distances there (or NaN exactly in a face's plane,
// which leaves that slab out).
template <bool kOpen, typename Entry>
TRACER_HD TRACER_INLINE void slab_faces(const float* o, const float* d, const float* lo,
                                        const float* hi, Entry entry, uint32_t fa, uint32_t fb,
                                        float& tbest, uint32_t& best) {
  float tn = -kInfinity, tf = kInfinity;
  uint32_t en = kInvalid, ef = kInvalid;
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (int a = 0; a < 3; ++a) {
    const float inv = fast_rcp(d[a]);
    const float t_lo = (lo[a] - o[a]) * inv, t_hi = (hi[a] - o[a]) * inv;
    const bool up = inv >= 0.0f;
    const float near = up ? t_lo : t_hi, far = up ? t_hi : t_lo;
    const uint32_t e_lo = entry(2 * a), e_hi = entry(2 * a + 1);
    if (near > tn) {
      tn = near;
      en = up ? e_lo : e_hi;
    }
    if (far < tf) {
      tf = far;
      ef = up ? e_hi : e_lo;
    }
  }
  const bool enter = (tn > 0.0f) & (!kOpen || en != kInvalid) & (en != fa) & (en != fb);
  const float t = enter ? tn : tf;
  const uint32_t e = enter ? en : ef;
  if ((tn <= tf) & (!kOpen || e != kInvalid) & (e != fa) & (e != fb) & (t > 0.0f) & (t < tbest)) {
    tbest = t;
    best = e;
  }
}

TRACER_HD TRACER_INLINE void flat_box_hit(const TraceView& s, vec3 o, vec3 d, uint32_t fa,
                                          uint32_t fb, float& tbest, uint32_t& best) {
  const float oc[3] = {o.x, o.y, o.z}, dc[3] = {d.x, d.y, d.z};
  const float lo[3] = {s.flat_box_lo.x, s.flat_box_lo.y, s.flat_box_lo.z};
  const float hi[3] = {s.flat_box_hi.x, s.flat_box_hi.y, s.flat_box_hi.z};
  slab_faces<true>(oc, dc, lo, hi, [&](int f) { return s.flat_box_entry[f]; }, fa, fb, tbest,
                   best);
}

// Solid g (its map m, TraceView::flat_solids): the face a ray meets first, if that is in
// (0, tbest) and not entry fa or fb: then tbest and best become its distance and entry. In the
// solid's coordinates the box is the centred unit cube, the same slab test as the scene's box
// (one affine map of the ray instead of six quad tests). The distance t is the same along the
// ray in both spaces (the map is affine).
TRACER_HD TRACER_INLINE void flat_solid_hit(const FlatPrim& m, uint32_t g, vec3 o, vec3 d,
                                            uint32_t fa, uint32_t fb, float& tbest,
                                            uint32_t& best) {
  const float oc[3] = {flat_affine(m.row_u, o), flat_affine(m.row_v, o), flat_affine(m.row_w, o)};
  const float dc[3] = {flat_fma(m.row_u.x, d.x, flat_fma(m.row_u.y, d.y, m.row_u.z * d.z)),
                       flat_fma(m.row_v.x, d.x, flat_fma(m.row_v.y, d.y, m.row_v.z * d.z)),
                       flat_fma(m.row_w.x, d.x, flat_fma(m.row_w.y, d.y, m.row_w.z * d.z))};
  const float lo[3] = {-0.5f, -0.5f, -0.5f}, hi[3] = {0.5f, 0.5f, 0.5f};
  const uint32_t first = 6 * g;
  slab_faces<false>(oc, dc, lo, hi, [first](int f) { return first + uint32_t(f); }, fa, fb,
                    tbest, best);
}

// Solids [0, s.flat_solid_count) against one ray (kAnyHit: until every active lane of the warp
// has a hit).
template <bool kAnyHit>
TRACER_HD TRACER_INLINE void flat_solids(const TraceView& s, vec3 o, vec3 d, uint32_t fa,
                                         uint32_t fb, float& tbest, uint32_t& best) {
  for (uint32_t g = 0; g < s.flat_solid_count; ++g) {
    if (kAnyHit && warp_all(best != kInvalid)) return;
    flat_solid_hit(load_flat_loop(s.flat_solids, g), g, o, d, fa, fb, tbest, best);
  }
}

// The query over the flat list and the spheres (TraceView::use_flat): the same contract as
// traverse() below. The entry hit is mapped back to its triangle and barycentrics once, at the
// end, so that a hit reads the same to shading as one found through the BVH. kSkipHull leaves
// out the entries on the scene's hull, for rays between two points of the scene.
template <uint32_t F, bool kAnyHit, bool kSkipHull = false>
TRACER_HD inline Hit flat_traverse(const TraceView& s, const Ray& ray, uint32_t skip,
                                   uint32_t skip2) {
  const uint32_t fa = skip < s.tri_count ? s.tri_to_flat[skip] : kInvalid;
  const uint32_t fb = skip2 < s.tri_count ? s.tri_to_flat[skip2] : kInvalid;
  float tbest = ray.tmax;
  uint32_t best = kInvalid;
  const uint32_t quad_end = kSkipHull ? s.flat_quad_blockers : s.flat_quads - s.flat_box_faces;
  const uint32_t tri_end = kSkipHull ? s.flat_triangle_blockers_end : s.flat_count;
  // The solids first (blockers: also for rays between two points of the scene).
  flat_solids<kAnyHit>(s, ray.o, ray.d, fa, fb, tbest, best);
  if (!kAnyHit || !warp_all(best != kInvalid))
    flat_range<true, kAnyHit>(s.flat_loop, flat_quads_begin(s), quad_end, ray.o, ray.d, fa, fb,
                              tbest, best);
  // The box faces after the other quads, as in flat_closest_and_any (ties go to the first).
  if (!kSkipHull && s.flat_box_faces && (!kAnyHit || !warp_all(best != kInvalid)))
    flat_box_hit(s, ray.o, ray.d, fa, fb, tbest, best);
  if (!kAnyHit || !warp_all(best != kInvalid))
    flat_range<false, kAnyHit>(s.flat_loop, s.flat_quads, tri_end, ray.o, ray.d, fa, fb, tbest,
                               best);
  Hit hit;
  if (!kAnyHit) {
    hit = flat_entry_hit(s, ray, best, tbest);
  } else if (best != kInvalid) {
    hit.t = tbest;
    hit.prim = s.flat_info[best].tri0;
  }
  if (F & kFeatureSpheres) {
    for (uint32_t k = 0; k < s.sphere_count; ++k) {
      if (kAnyHit && warp_all(hit.valid())) break;
      const uint32_t prim = s.tri_count + k;
      if (prim == skip || prim == skip2) continue;
      const Sphere sph = load_sphere(s.spheres, k);
      float t;
      if (intersect_sphere(ray, sph.center, sph.radius, tbest, t)) {
        tbest = t;
        hit.t = t;
        hit.prim = prim;
        hit.u = hit.v = 0.0f;
      }
    }
  }
  return hit;
}

// Entries [begin, end) against K rays at once, the nearest hit of each in (0, tbest[k]) kept in
// tbest[k] and best[k] (entry fa[k] skipped): each entry is loaded once for all K rays, so the
// loads and the loop's own instructions are shared (the wavefront's intersect kernel, where each
// lane traces K queued rays). Per ray the same arithmetic and order as flat_range. Without
// kSkips no entry is skipped (fa is not read).
template <bool kQuads, int K, bool kSkips>
TRACER_HD TRACER_INLINE void flat_range_multi(const FlatPrim* prims, uint32_t begin, uint32_t end,
                                              const vec3* o, const vec3* d, const uint32_t* fa,
                                              float* tbest, uint32_t* best) {
  for (uint32_t i = begin; i < end; ++i) {
    const FlatPrim p = load_flat_loop(prims, i);
#if defined(__CUDACC__)
#pragma unroll
#endif
    for (int k = 0; k < K; ++k) {
      float t, u, v;
      flat_hit(p, o[k], d[k], t, u, v);
      if (flat_accept<kQuads>(u, v, t, tbest[k]) & (!kSkips || i != fa[k])) {
        tbest[k] = t;
        best[k] = i;
      }
    }
  }
}

// The nearest hits of K rays through the flat list and the spheres: hits[k] is what
// intersect_closest(s, rays[k], skip[k]) returns through the list (the same arithmetic and
// order), at one pass over the entries for all K. A lane with fewer than K rays passes copies
// with tmax = 0, which nothing hits. Without random walks (F without kFeatureSubsurface) rays
// leave from no skipped triangle: skip is then ignored (callers must pass kInvalid, or the
// hits differ from intersect_closest's), and the loop makes no skip test.
template <uint32_t F, int K>
TRACER_HD TRACER_INLINE void flat_closest_multi(const TraceView& s, const Ray* rays,
                                                const uint32_t* skip, Hit* hits) {
  constexpr bool kSkips = (F & kFeatureSubsurface) != 0;
  vec3 o[K], d[K];
  float tbest[K];
  uint32_t best[K], fa[K];
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (int k = 0; k < K; ++k) {
    o[k] = rays[k].o;
    d[k] = rays[k].d;
    tbest[k] = rays[k].tmax;
    best[k] = kInvalid;
    fa[k] = kSkips && skip[k] < s.tri_count ? s.tri_to_flat[skip[k]] : kInvalid;
  }
  // The solids, each map loaded once for the K rays.
  for (uint32_t g = 0; g < s.flat_solid_count; ++g) {
    const FlatPrim m = load_flat_loop(s.flat_solids, g);
#if defined(__CUDACC__)
#pragma unroll
#endif
    for (int k = 0; k < K; ++k)
      flat_solid_hit(m, g, o[k], d[k], fa[k], kInvalid, tbest[k], best[k]);
  }
  flat_range_multi<true, K, kSkips>(s.flat_loop, flat_quads_begin(s),
                                    s.flat_quads - s.flat_box_faces, o, d, fa, tbest, best);
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (int k = 0; k < K; ++k)
    if (s.flat_box_faces) flat_box_hit(s, o[k], d[k], fa[k], kInvalid, tbest[k], best[k]);
  flat_range_multi<false, K, kSkips>(s.flat_loop, s.flat_quads, s.flat_count, o, d, fa, tbest, best);
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (int k = 0; k < K; ++k) {
    Hit hit = flat_entry_hit(s, rays[k], best[k], tbest[k]);
    if (F & kFeatureSpheres) {
      for (uint32_t j = 0; j < s.sphere_count; ++j) {
        const uint32_t prim = s.tri_count + j;
        if (kSkips && prim == skip[k]) continue;
        const Sphere sph = load_sphere(s.spheres, j);
        float t;
        if (intersect_sphere(rays[k], sph.center, sph.radius, tbest[k], t)) {
          tbest[k] = t;
          hit.t = t;
          hit.prim = prim;
          hit.u = hit.v = 0.0f;
        }
      }
    }
    hits[k] = hit;
  }
}

// Entries [begin, end) against two rays at once: the nearest hit of `ext` (kept in tbest/best,
// skipping entry fa) and whether anything blocks `sh` in (0, sh.tmax) (skipping entries sa and
// sb). Each entry is loaded once for both; a lane with no ray of one kind passes one with
// tmax = 0, which nothing hits.
template <bool kQuads>
TRACER_HD TRACER_INLINE void flat_range_pair(const FlatPrim* prims, uint32_t begin, uint32_t end,
                                             const Ray& ext, uint32_t fa, float& tbest,
                                             uint32_t& best, const Ray& sh, uint32_t sa,
                                             uint32_t sb, bool& blocked) {
  bool b = blocked;
#if defined(__CUDACC__)
#pragma unroll 2
#endif
  for (uint32_t i = begin; i < end; ++i) {
    const FlatPrim p = load_flat_loop(prims, i);
    float t, u, v;
    flat_hit(p, ext.o, ext.d, t, u, v);
    if (flat_accept<kQuads>(u, v, t, tbest) & (i != fa)) {
      tbest = t;
      best = i;
    }
    flat_hit(p, sh.o, sh.d, t, u, v);
    b = b | (flat_accept<kQuads>(u, v, t, sh.tmax) & (i != sa) & (i != sb));
  }
  blocked = b;
}

// One pass over the flat list and the spheres for a lane's extension ray and its shadow ray:
// the same answers as intersect_closest(s, ext, ext_skip) and intersect_any(s, sh, sh_skip,
// sh_skip2) through the flat list (the same arithmetic), at one loop's cost instead of two.
// The megakernel uses it for small scenes; its lanes trace a shadow ray together with the next
// extension ray of their path. The shadow ray must run between two points of the scene (as
// next-event estimation's do): it skips the entries on the scene's hull, which it cannot cross.
// Without random walks (F without kFeatureSubsurface) rays leave from no skipped triangle.
template <uint32_t F>
TRACER_HD TRACER_INLINE Hit flat_closest_and_any(const TraceView& s, const Ray& ext, uint32_t ext_skip,
                                          const Ray& sh, uint32_t sh_skip, uint32_t sh_skip2,
                                          bool& blocked) {
  constexpr bool kWalks = (F & kFeatureSubsurface) != 0;
  const uint32_t fa = kWalks && ext_skip < s.tri_count ? s.tri_to_flat[ext_skip] : kInvalid;
  const uint32_t sa = sh_skip < s.tri_count ? s.tri_to_flat[sh_skip] : kInvalid;
  const uint32_t sb = kWalks && sh_skip2 < s.tri_count ? s.tri_to_flat[sh_skip2] : kInvalid;
  float tbest = ext.tmax;
  uint32_t best = kInvalid;
  blocked = false;
  // The solids: the extension ray's nearest face, and whether one blocks the shadow ray.
  for (uint32_t g = 0; g < s.flat_solid_count; ++g) {
    const FlatPrim m = load_flat_loop(s.flat_solids, g);
    flat_solid_hit(m, g, ext.o, ext.d, fa, kInvalid, tbest, best);
    float ts = sh.tmax;
    uint32_t bs = kInvalid;
    flat_solid_hit(m, g, sh.o, sh.d, sa, sb, ts, bs);
    blocked = blocked | (bs != kInvalid);
  }
  flat_range_pair<true>(s.flat_loop, flat_quads_begin(s), s.flat_quad_blockers, ext, fa, tbest,
                        best, sh, sa, sb, blocked);
  flat_range<true, false>(s.flat_loop, s.flat_quad_blockers, s.flat_quads - s.flat_box_faces,
                          ext.o, ext.d, fa, kInvalid, tbest, best);
  if (s.flat_box_faces) flat_box_hit(s, ext.o, ext.d, fa, kInvalid, tbest, best);
  flat_range_pair<false>(s.flat_loop, s.flat_quads, s.flat_triangle_blockers_end, ext, fa, tbest, best,
                         sh, sa, sb, blocked);
  flat_range<false, false>(s.flat_loop, s.flat_triangle_blockers_end, s.flat_count, ext.o, ext.d, fa,
                           kInvalid, tbest, best);
  Hit hit = flat_entry_hit(s, ext, best, tbest);
  if (F & kFeatureSpheres) {
    for (uint32_t k = 0; k < s.sphere_count; ++k) {
      const uint32_t prim = s.tri_count + k;
      const Sphere sph = load_sphere(s.spheres, k);
      float t;
      if (prim != ext_skip && intersect_sphere(ext, sph.center, sph.radius, tbest, t)) {
        tbest = t;
        hit.t = t;
        hit.prim = prim;
        hit.u = hit.v = 0.0f;
      }
      if (!blocked && prim != sh_skip && prim != sh_skip2 &&
          intersect_sphere(sh, sph.center, sph.radius, sh.tmax, t))
        blocked = true;
    }
  }
  return hit;
}

// Traversal of the 4-wide BVH in the "while-while" form with postponed leaves of Aila & Laine,
// "Understanding the Efficiency of Ray Traversal on GPUs" (HPG 2009): a lane that reaches a leaf
// parks it and keeps descending inner nodes until every lane of the warp holds a leaf, then all
// test their leaves together. This keeps the lanes of a warp on the same kind of work. Each step
// tests the four child boxes of one node; closest-hit queries visit them near-first (a five-
// comparator sorting network), any-hit queries in stored order, since any blocker will do.
// kAnyHit stops at the first hit in (0, ray.tmax). Primitives `skip` and `skip2` are ignored:
// the light a shadow ray aims at, and the triangle a ray leaves from (a ray cannot re-enter the
// plane it left; this backs up the origin offset where a triangle is much larger than the
// distances involved). The stack holds child references; the builder bounds its depth.
template <uint32_t F, bool kAnyHit>
TRACER_HD inline Hit traverse(const TraceView& s, const Ray& ray, uint32_t skip, uint32_t skip2) {
  if ((F & kFeatureFlatList) && s.use_flat) return flat_traverse<F, kAnyHit>(s, ray, skip, skip2);
#if !defined(__CUDA_ARCH__)
  if (s.cpu_bvh.nodes) {
    return kAnyHit ? cpu_intersect_any(s, ray, skip, skip2)
                   : cpu_intersect_closest(s, ray, skip, skip2);
  }
#endif
  Hit hit;
  const vec3 inv_d = 1.0f / ray.d;  // infinities are handled by intersect_aabb
  const RayTriSetup setup(ray, inv_d);
  float tmax = ray.tmax;
  uint32_t stack[kBvhStackSize];
  TraversalCursor c = traversal_start(s, ray);
  while (!traverse_round<F, kAnyHit>(s, ray, inv_d, setup, skip, skip2, tmax, hit, stack, c)) {
  }
  return hit;
}

// Nearest hit along the ray in (0, ray.tmax), ignoring primitive `skip` (the triangle the ray
// leaves from, or kInvalid). F without kFeatureSpheres: the scene has none.
template <uint32_t F = kAllFeatures>
TRACER_HD inline Hit intersect_closest(const TraceView& s, const Ray& ray,
                                       uint32_t skip = kInvalid) {
  return traverse<F, false>(s, ray, skip, kInvalid);
}

// True when anything blocks the ray in (0, ray.tmax), ignoring primitive `skip` (the light the
// shadow ray aims at, so that reaching it is never mistaken for being blocked).
template <uint32_t F = kAllFeatures>
TRACER_HD inline bool intersect_any(const TraceView& s, const Ray& ray, uint32_t skip,
                                    uint32_t skip2 = kInvalid) {
  return traverse<F, true>(s, ray, skip, skip2).valid();
}

// Whether anything blocks a ray between two points of the scene, such as a next-event shadow ray
// (both ends on surfaces, offset towards each other): intersect_any's answer, except that the
// flat list's hull entries are skipped, since such a ray cannot cross them (FlatList).
template <uint32_t F = kAllFeatures>
TRACER_HD inline bool shadow_blocked(const TraceView& s, const Ray& ray, uint32_t skip,
                                     uint32_t skip2 = kInvalid) {
  if ((F & kFeatureFlatList) && s.use_flat)
    return flat_traverse<F, true, true>(s, ray, skip, skip2).valid();
  return intersect_any<F>(s, ray, skip, skip2);
}

}  // namespace tracer
