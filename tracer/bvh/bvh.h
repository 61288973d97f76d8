// The BVH layout shared by both backends: 4-wide 128-byte nodes in one flat array and a primitive
// index array that leaves point into. Traversal lives in bvh/traverse.h beside the primitives it
// tests; the host-side binned-SAH builder is declared here.
#pragma once

#include <vector>

#include "core/math.h"

namespace tracer {

struct Aabb {
  vec3 lo = vec3(kInfinity);
  vec3 hi = vec3(-kInfinity);
  TRACER_HD void grow(vec3 p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  TRACER_HD void grow(const Aabb& b) {
    lo = glm::min(lo, b.lo);
    hi = glm::max(hi, b.hi);
  }
  // Halves first: lo + hi can overflow for finite bounds (the same value otherwise).
  TRACER_HD vec3 centroid() const { return 0.5f * lo + 0.5f * hi; }
  TRACER_HD bool empty() const { return lo.x > hi.x; }
  TRACER_HD float area() const {
    if (empty()) return 0.0f;
    const vec3 e = hi - lo;
    return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
  }
};

// The tree is 4-wide: fewer, larger steps per ray than a binary tree, and one 128-byte fetch
// brings the boxes of all four children (Wald, Benthin & Boulos, "Getting Rid of Packets", 2008;
// Ylitie, Karras & Laine, "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide
// BVHs", HPG 2017, who go further and quantise the boxes).
constexpr int kBvhWidth = 4;

// A child reference. Inner nodes: the node's index. Leaves (kBvhLeafBit set): the index of the
// leaf's first entry in prim_indices; the leaf's last entry carries kBvhLastPrimBit, so leaves
// of any size fit in one 32-bit reference.
constexpr uint32_t kBvhLeafBit = 0x80000000u;
constexpr uint32_t kBvhLastPrimBit = 0x80000000u;
TRACER_HD TRACER_INLINE bool is_leaf_ref(uint32_t ref) {
  return (ref & kBvhLeafBit) != 0;
}

// One child of a node: its box and its reference, 32 bytes (tinybvh's binary node layout). An
// unused slot has an empty box (lo = +inf, hi = -inf) that no ray enters.
struct alignas(16) BvhSlot {
  vec3 lo;
  uint32_t ref;
  vec3 hi;
  uint32_t pad;
};
static_assert(sizeof(BvhSlot) == 32, "BvhSlot must stay 32 bytes");

// Slots are stored child by child (array of structures) rather than axis by axis: a child's box
// is two 16-byte loads, tested as soon as it arrives, so the traversal holds two values per
// child (distance, reference) instead of the 24 coordinates of all four boxes.
struct alignas(16) BvhNode {
  BvhSlot child[kBvhWidth];
};
static_assert(sizeof(BvhNode) == 128, "BvhNode must stay one 128-byte cache line");

// Loads one slot as two 16-byte reads through the read-only cache on the GPU (plain float loads
// of a vec3 layout would take eight 4-byte instructions).
TRACER_HD TRACER_INLINE BvhSlot load_slot(const BvhNode* nodes, uint32_t node, int i) {
#if defined(__CUDA_ARCH__)
  const float4* p = reinterpret_cast<const float4*>(&nodes[node].child[i]);
  const float4 a = __ldg(p), b = __ldg(p + 1);
  BvhSlot c;
  c.lo = vec3(a.x, a.y, a.z);
  c.ref = __float_as_uint(a.w);
  c.hi = vec3(b.x, b.y, b.z);
  c.pad = 0;
  return c;
#else
  return nodes[node].child[i];
#endif
}

// Slab test against [0, tmax], returning the entry distance or kInfinity on a miss. inv_d is
// 1/d with IEEE infinities for zero components. Each slab's near and far planes are picked by
// the sign of inv_d (Williams et al., "An Efficient and Robust Ray-Box Intersection Algorithm",
// JGT 2005), and the comparisons are ordered so that the NaN of 0 * inf (a ray lying in a slab's
// plane) is ignored, treating the box as closed. t_far is widened by 1 + 2*gamma(3) so rounding
// cannot make a ray miss a box that holds a surface it hits (Ize, "Robust BVH Ray Traversal",
// JCGT 2013).
TRACER_HD TRACER_INLINE float intersect_aabb(vec3 lo, vec3 hi, vec3 o, vec3 inv_d, float tmax) {
  float t_near = 0.0f, t_far = tmax;
#if defined(__CUDACC__)
#pragma unroll
#endif
  for (int a = 0; a < 3; ++a) {
    const bool pos = inv_d[a] >= 0.0f;
    // (b - o) * inv_d, not the cheaper fma(b, inv_d, -o * inv_d): the latter cancels
    // catastrophically far from the origin and would break the error bound below.
    const float tn = ((pos ? lo[a] : hi[a]) - o[a]) * inv_d[a];
    const float tf = ((pos ? hi[a] : lo[a]) - o[a]) * inv_d[a];
    t_near = tn > t_near ? tn : t_near;
    t_far = tf < t_far ? tf : t_far;
  }
  t_far *= 1.0f + 2.0f * gamma_bound(3);
  return t_near <= t_far ? t_near : kInfinity;
}

// Entries of the traversal stack; the builder keeps every tree within it
// (BvhBuildStats::max_stack).
constexpr int kBvhStackSize = 64;

struct BvhBuildStats {
  uint32_t node_count = 0;         // 4-wide nodes; the root is node 0 and is never a leaf
  uint32_t binary_node_count = 0;  // nodes of the binary tree it was collapsed from
  uint32_t leaf_count = 0;
  uint32_t max_depth = 0;  // of the 4-wide tree
  uint32_t max_stack = 0;  // most stack entries a traversal can hold, <= kBvhStackSize
  float sah_cost =
      0.0f;  // of the binary tree: traversal 1, primitive 1, relative to the root's area
  double build_ms = 0.0;
};

struct Bvh {
  std::vector<BvhNode> nodes;
  std::vector<uint32_t> prim_indices;
  BvhBuildStats stats;
};

// Binned SAH build (Wald, "On fast Construction of SAH-based Bounding Volume Hierarchies", 2007)
// of a binary tree over primitives given by their bounds and centroids, collapsed into a 4-wide
// tree whose traversal stack cannot overflow kBvhStackSize. It runs on `threads` threads (0: one
// per core), and the tree (nodes, prim_indices and stats but build_ms) is the same for any
// number of them, so that every machine renders the same image.
Bvh build_bvh(const std::vector<Aabb>& prim_bounds, int max_leaf_size = 4, int threads = 0);

}  // namespace tracer
