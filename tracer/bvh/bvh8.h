// An 8-wide compressed BVH, a build variant for now (TRACER_VARIANT_BVH8 in both the C++ and the
// CUDA flags: the walk in bvh/traverse.h is compiled only there, since beside the 4-wide walk it
// costs the megakernels registers; PERFORMANCE.md, row 93): 80-byte nodes whose
// eight child boxes are quantised to 8 bits per plane against the node's origin and a
// power-of-two scale per axis, children stored in slots ordered by ray octant, in the spirit of
// Ylitie, Karras & Laine, "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide
// BVHs" (HPG 2017). It is made from the 4-wide tree of bvh.h (bvh8_build.cpp) and traversed by
// the same while-while loop with the same stack of child references (bvh/traverse.h), so the
// wavefront's dynamic fetch and the leaves' primitive tests are shared. The quantised boxes
// contain the exact ones in float arithmetic (the builder checks the decoding the traversal
// does), so the traversal keeps bvh.h's robust slab test.
#pragma once

#include <cstring>
#include <vector>

#include "bvh/bvh.h"

namespace tracer {

constexpr int kBvh8Width = 8;

// Whether this build walks the 8-wide tree (and CompiledScene builds it).
#if defined(TRACER_VARIANT_BVH8)
constexpr bool kBvh8Build = true;
#else
constexpr bool kBvh8Build = false;
#endif

// One node: 80 bytes, five 16-byte loads on the GPU.
//  origin: the node box's lower corner; exps: bits 0-23 the biased exponents (IEEE single:
//   scale = 2^(e - 127); 0 gives scale 0) of x, y, z, bits 24-31 unused.
//  child_base: the index of the node's first inner child (its inner children are consecutive);
//  prim_base: the index in Bvh8::prim_indices of its first leaf primitive (its leaves' primitives
//   are consecutive, each leaf's last entry marked with kBvhLastPrimBit).
//  meta: one byte per slot, slot s in byte s & 3 of meta[s >> 2]: 0 an empty slot; 0x80 | r an
//   inner child, the r-th of the node's inner children; 1..0x7f a leaf whose first primitive is
//   entry prim_base + meta - 1.
//  q: the quantised child boxes, plane p (lo x, lo y, lo z, hi x, hi y, hi z) of slot s in byte
//   s & 3 of q[p][s >> 2]: the plane lies at origin + q * scale on its axis.
struct alignas(16) Bvh8Node {
  vec3 origin;
  uint32_t exps;
  uint32_t child_base;
  uint32_t prim_base;
  uint32_t meta[2];
  uint32_t q[6][2];
};
static_assert(sizeof(Bvh8Node) == 80, "Bvh8Node must stay 80 bytes");

TRACER_HD TRACER_INLINE uint32_t bvh8_byte(const uint32_t* pair, uint32_t slot) {
  return (pair[slot >> 2] >> (8u * (slot & 3u))) & 0xffu;
}

// The scale of axis a: 2^(e - 127) made from the exponent's bits.
TRACER_HD TRACER_INLINE float bvh8_scale(uint32_t exps, int axis) {
  const uint32_t bits = ((exps >> (8 * axis)) & 0xffu) << 23;
#if defined(__CUDA_ARCH__)
  return __uint_as_float(bits);
#else
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
#endif
}

// A plane's coordinate: origin + q * scale, the product exact (8 bits times a power of two), the
// sum rounded once (a fused multiply-add gives the same value).
TRACER_HD TRACER_INLINE float bvh8_plane(float origin, uint32_t q, float scale) {
  return origin + float(q) * scale;
}

TRACER_HD TRACER_INLINE Bvh8Node load_node8(const Bvh8Node* nodes, uint32_t i) {
#if defined(__CUDA_ARCH__)
  const uint4* p = reinterpret_cast<const uint4*>(nodes + i);
  const uint4 a = __ldg(p), b = __ldg(p + 1), c = __ldg(p + 2), d = __ldg(p + 3),
              e = __ldg(p + 4);
  Bvh8Node n;
  n.origin = vec3(__uint_as_float(a.x), __uint_as_float(a.y), __uint_as_float(a.z));
  n.exps = a.w;
  n.child_base = b.x;
  n.prim_base = b.y;
  n.meta[0] = b.z;
  n.meta[1] = b.w;
  n.q[0][0] = c.x;
  n.q[0][1] = c.y;
  n.q[1][0] = c.z;
  n.q[1][1] = c.w;
  n.q[2][0] = d.x;
  n.q[2][1] = d.y;
  n.q[3][0] = d.z;
  n.q[3][1] = d.w;
  n.q[4][0] = e.x;
  n.q[4][1] = e.y;
  n.q[5][0] = e.z;
  n.q[5][1] = e.w;
  return n;
#else
  return nodes[i];
#endif
}

struct Bvh8BuildStats {
  uint32_t node_count = 0;
  uint32_t leaf_count = 0;
  uint32_t max_depth = 0;
  uint32_t max_stack = 0;  // most stack entries a traversal can hold, <= kBvhStackSize
  double build_ms = 0.0;
};

struct Bvh8 {
  std::vector<Bvh8Node> nodes;        // empty: no 8-wide tree (see build_bvh8)
  std::vector<uint32_t> prim_indices;  // each node's leaves' primitives, consecutive
  Bvh8BuildStats stats;
};

// Collapses the 4-wide tree into the 8-wide compressed one: a node takes its 4-wide node's
// children and opens the inner child of largest surface area into its own children while eight
// slots hold them and the traversal stack stays within kBvhStackSize; then the children are
// placed in the slots by ray octant and their boxes quantised. Returns an empty tree where a
// node's leaves hold more than 126 primitives (leaves of thousands of coinciding primitives at
// the builder's depth cap): such a scene keeps the 4-wide tree.
Bvh8 build_bvh8(const Bvh& bvh4);

// The decoded box of slot s (tests and the builder's check; traversal decodes the same way).
Aabb bvh8_child_box(const Bvh8Node& n, uint32_t slot);

}  // namespace tracer
