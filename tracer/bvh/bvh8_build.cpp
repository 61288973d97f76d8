// Host-side builder of the 8-wide compressed BVH (bvh8.h) from the 4-wide tree: collapse,
// octant slot order, conservative quantisation.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include "bvh/bvh8.h"

namespace tracer {
namespace {

bool valid_slot(const BvhSlot& s) { return s.lo.x <= s.hi.x; }

struct Child {
  Aabb box;
  uint32_t ref;  // a 4-wide reference: inner node index, or kBvhLeafBit | first primitive
};

// The exponent (biased, IEEE single) of the smallest power of two s with origin + 255 s >= hi
// in float arithmetic, or 0 (scale 0) for an axis of zero extent.
uint32_t axis_exponent(float origin, float hi) {
  if (!(hi > origin)) return 0;
  if (!std::isfinite(hi - origin)) return 254;
  int e;
  std::frexp((hi - origin) / 255.0f, &e);  // (hi - origin) / 255 < 2^e
  uint32_t biased = uint32_t(std::clamp(e + 127, 1, 254));
  while (biased < 254) {
    const uint32_t bits = biased << 23;
    float scale;
    std::memcpy(&scale, &bits, sizeof scale);
    if (bvh8_plane(origin, 255u, scale) >= hi) break;
    ++biased;
  }
  return biased;
}

// The largest q in [0, 255] whose plane is at or below x, and the smallest at or above.
uint32_t quantise_lo(float origin, float scale, float x) {
  if (scale == 0.0f) return 0;
  int q = int(std::clamp(std::floor((x - origin) / scale), 0.0f, 255.0f));
  while (q > 0 && bvh8_plane(origin, uint32_t(q), scale) > x) --q;
  return uint32_t(q);
}
uint32_t quantise_hi(float origin, float scale, float x) {
  if (scale == 0.0f) return 0;
  int q = int(std::clamp(std::ceil((x - origin) / scale), 0.0f, 255.0f));
  while (q < 255 && bvh8_plane(origin, uint32_t(q), scale) < x) ++q;
  return uint32_t(q);
}

// Children to slots: slot s is visited first by rays of octant s (bit a set: direction a
// negative), so it should hold the child nearest to where such rays come from, the one of
// least dot(centroid - node centroid, direction). Greedy over the costs in increasing order
// (the paper solves the assignment exactly with an auction; greedy is within a few per cent).
void assign_slots(const Child* c, int k, const Aabb& box, int slot_of[8]) {
  struct Cost {
    float cost;
    int child, slot;
  };
  Cost costs[64];
  int n = 0;
  const vec3 pc = box.centroid();
  for (int i = 0; i < k; ++i) {
    const vec3 d = c[i].box.centroid() - pc;
    for (int s = 0; s < 8; ++s) {
      const vec3 dir((s & 1) ? -1.0f : 1.0f, (s & 2) ? -1.0f : 1.0f, (s & 4) ? -1.0f : 1.0f);
      costs[n++] = {glm::dot(d, dir), i, s};
    }
  }
  std::stable_sort(costs, costs + n, [](const Cost& a, const Cost& b) { return a.cost < b.cost; });
  bool child_done[8] = {}, slot_done[8] = {};
  for (int i = 0; i < k; ++i) slot_of[i] = -1;
  for (int j = 0; j < n; ++j) {
    if (child_done[costs[j].child] || slot_done[costs[j].slot]) continue;
    child_done[costs[j].child] = slot_done[costs[j].slot] = true;
    slot_of[costs[j].child] = costs[j].slot;
  }
}

}  // namespace

Aabb bvh8_child_box(const Bvh8Node& n, uint32_t slot) {
  Aabb b;
  if (bvh8_byte(n.meta, slot) == 0) return b;
  for (int a = 0; a < 3; ++a) {
    const float scale = bvh8_scale(n.exps, a);
    b.lo[a] = bvh8_plane(n.origin[a], bvh8_byte(n.q[a], slot), scale);
    b.hi[a] = bvh8_plane(n.origin[a], bvh8_byte(n.q[3 + a], slot), scale);
  }
  return b;
}

Bvh8 build_bvh8(const Bvh& bvh4) {
  const auto start = std::chrono::steady_clock::now();
  Bvh8 out;
  const std::vector<BvhNode>& n4 = bvh4.nodes;
  if (n4.empty()) return out;
  // need[i]: the most stack entries a traversal of 4-wide node i's subtree pushes.
  std::vector<uint32_t> need(n4.size(), 0);
  for (size_t i = n4.size(); i-- > 0;) {  // children have larger indices than their parent
    uint32_t k = 0, below = 0;
    for (const BvhSlot& s : n4[i].child) {
      if (!valid_slot(s)) continue;
      ++k;
      if (!is_leaf_ref(s.ref)) below = std::max(below, need[s.ref]);
    }
    need[i] = (k ? k - 1 : 0) + below;
  }
  auto children_of = [&](uint32_t node, Child* c, int& k) {
    for (const BvhSlot& s : n4[node].child)
      if (valid_slot(s)) c[k++] = {Aabb{s.lo, s.hi}, s.ref};
  };

  struct Work {
    uint32_t ref4;    // the 4-wide node whose subtree this 8-wide node covers
    uint32_t node8;   // its index
    uint32_t stack;   // entries on the stack when a traversal reaches it
    uint32_t depth;
  };
  out.nodes.reserve(n4.size() / 2 + 1);
  out.nodes.push_back(Bvh8Node{});
  out.prim_indices.reserve(bvh4.prim_indices.size());
  std::vector<Work> work{{0, 0, 0, 0}};
  for (size_t w_i = 0; w_i < work.size(); ++w_i) {  // breadth first: children consecutive
    const Work w = work[w_i];
    out.stats.max_depth = std::max(out.stats.max_depth, w.depth);
    Child c[kBvh8Width];
    int k = 0;
    children_of(w.ref4, c, k);
    // Open the inner child of largest area while the slots and the stack bound allow.
    for (;;) {
      int best = -1;
      for (int i = 0; i < k; ++i) {
        if (is_leaf_ref(c[i].ref)) continue;
        int kc = 0;
        for (const BvhSlot& s : n4[c[i].ref].child) kc += valid_slot(s) ? 1 : 0;
        if (k - 1 + kc > kBvh8Width) continue;
        // After opening: k - 1 + kc children, each inner one needing its 4-wide bound.
        uint32_t below = 0;
        for (int j = 0; j < k; ++j)
          if (j != i && !is_leaf_ref(c[j].ref)) below = std::max(below, need[c[j].ref]);
        for (const BvhSlot& s : n4[c[i].ref].child)
          if (valid_slot(s) && !is_leaf_ref(s.ref)) below = std::max(below, need[s.ref]);
        if (w.stack + uint32_t(k - 1 + kc - 1) + below > uint32_t(kBvhStackSize)) continue;
        if (best < 0 || c[i].box.area() > c[best].box.area()) best = i;
      }
      if (best < 0) break;
      const uint32_t opened = c[best].ref;
      c[best] = c[--k];
      children_of(opened, c, k);
    }
    Aabb box;
    for (int i = 0; i < k; ++i) box.grow(c[i].box);
    int slot_of[kBvh8Width];
    assign_slots(c, k, box, slot_of);
    Child by_slot[kBvh8Width];
    bool used[kBvh8Width] = {};
    for (int i = 0; i < k; ++i) {
      by_slot[slot_of[i]] = c[i];
      used[slot_of[i]] = true;
    }

    Bvh8Node node{};
    node.origin = box.lo;
    const uint32_t e[3] = {axis_exponent(box.lo.x, box.hi.x), axis_exponent(box.lo.y, box.hi.y),
                           axis_exponent(box.lo.z, box.hi.z)};
    node.exps = e[0] | e[1] << 8 | e[2] << 16;
    const uint32_t stack_below = w.stack + uint32_t(k - 1);
    out.stats.max_stack = std::max(out.stats.max_stack, stack_below);
    node.child_base = uint32_t(out.nodes.size());
    node.prim_base = uint32_t(out.prim_indices.size());
    uint32_t inner = 0;
    for (uint32_t s = 0; s < kBvh8Width; ++s) {
      uint32_t meta = 0, q[6] = {255, 255, 255, 0, 0, 0};  // empty: lo above hi
      if (used[s]) {
        const Child& ch = by_slot[s];
        for (int a = 0; a < 3; ++a) {
          const float scale = bvh8_scale(node.exps, a);
          q[a] = quantise_lo(node.origin[a], scale, ch.box.lo[a]);
          q[3 + a] = quantise_hi(node.origin[a], scale, ch.box.hi[a]);
        }
        if (is_leaf_ref(ch.ref)) {
          const uint32_t offset = uint32_t(out.prim_indices.size()) - node.prim_base;
          if (offset > 0x7eu) return Bvh8();  // see build_bvh8 in bvh8.h
          meta = offset + 1;
          for (uint32_t i = ch.ref & ~kBvhLeafBit;; ++i) {
            out.prim_indices.push_back(bvh4.prim_indices[i]);
            if (bvh4.prim_indices[i] & kBvhLastPrimBit) break;
          }
          out.stats.leaf_count++;
        } else {
          meta = 0x80u | inner++;
        }
      }
      for (int p = 0; p < 6; ++p) node.q[p][s >> 2] |= q[p] << (8u * (s & 3u));
      node.meta[s >> 2] |= meta << (8u * (s & 3u));
    }
    // The inner children, consecutive, in slot order (their rank is their meta's low bits).
    for (uint32_t s = 0; s < kBvh8Width; ++s) {
      if (!used[s] || is_leaf_ref(by_slot[s].ref)) continue;
      work.push_back({by_slot[s].ref, uint32_t(out.nodes.size()), stack_below, w.depth + 1});
      out.nodes.push_back(Bvh8Node{});
    }
    out.nodes[w.node8] = node;
  }
  out.stats.node_count = uint32_t(out.nodes.size());
  out.stats.build_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace tracer
