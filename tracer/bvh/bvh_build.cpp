// Host-side BVH builder: a binary binned-SAH tree (16 bins per axis over centroid bounds, leaves
// when splitting does not pay), then collapsed into the 4-wide tree that traversal uses. Both
// passes are iterative so that deep inputs cannot overflow the call stack.
#include <algorithm>
#include <chrono>
#include <limits>
#include <stdexcept>
#include <string>

#include "bvh/bvh.h"

namespace tracer {
namespace {

constexpr int kBins = 16;
constexpr float kTraversalCost = 1.0f;
constexpr float kIntersectCost = 1.0f;
// Leaves at this depth stop splitting, so traversal with a kBvhStackSize stack cannot overflow.
constexpr uint32_t kMaxDepth = kBvhStackSize - 4;

struct Task {
  uint32_t node, depth;
};

// Surface area in double: a box of finite float bounds can have an area (or even an extent)
// beyond the float range, which made the SAH cost inf / inf = NaN. Infinite bounds (from callers
// that skip validate_scene) count as the float range, so the cost stays finite for any input.
double area_double(const Aabb& b) {
  if (b.empty()) return 0.0;
  const glm::dvec3 big(std::numeric_limits<float>::max());
  const glm::dvec3 e =
      glm::clamp(glm::dvec3(b.hi), -big, big) - glm::clamp(glm::dvec3(b.lo), -big, big);
  return 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
}

// The bin of centroid coordinate c in [lo, lo + kBins / scale]. A NaN position (an empty or
// non-finite primitive box from a caller that skipped validate_scene, or an extent whose scale
// underflowed to 0 next to an infinite distance) goes to bin 0 instead of through int(NaN),
// which is undefined and was an out-of-bounds index.
int bin_of(float c, float lo, float scale) {
  const float f = (c - lo) * scale;
  return f >= 0.0f ? int(std::min(f, float(kBins - 1))) : 0;
}

// The binary tree being built. count == 0: inner node whose children are left_first and
// left_first + 1. count > 0: leaf holding prim_indices[left_first, left_first + count).
struct BinaryNode {
  Aabb box;
  uint32_t left_first = 0, count = 0;
  bool is_leaf() const { return count > 0; }
};

}  // namespace

namespace {
// Collapses the binary tree into 4-wide nodes, top down: a wide node starts with the two
// children of a binary inner node and repeatedly replaces the inner child of largest surface area
// by its two children until it holds four (Wald, Benthin & Boulos 2008). The traversal stack
// bound decides how far that may go: a node reached with at most `stack` entries below it pushes
// at most (children - 1), and a subtree of binary height h can always be collapsed so that it
// pushes at most h more (two children per node, as in the binary traversal). Opening stops where
// stack + children - 1 + height(child) could exceed kBvhStackSize for some child; the binary
// builder's depth cap keeps height(root) below kBvhStackSize, so two children always fit.
void collapse_to_wide(const std::vector<BinaryNode>& bin, Bvh& bvh) {
  struct Work {
    uint32_t bin_node, wide_node, stack, depth;
  };
  BvhSlot empty{};
  empty.lo = vec3(kInfinity);
  empty.hi = vec3(-kInfinity);
  // Binary heights, bottom up: children always have larger indices than their parent.
  std::vector<uint32_t> height(bin.size(), 0);
  for (size_t i = bin.size(); i-- > 0;) {
    if (!bin[i].is_leaf())
      height[i] = 1 + std::max(height[bin[i].left_first], height[bin[i].left_first + 1]);
  }
  bvh.nodes.clear();
  bvh.nodes.reserve(bin.size() / 3 + 1);
  bvh.nodes.push_back(BvhNode{});
  std::vector<Work> work{{0, 0, 0, 0}};
  while (!work.empty()) {
    const Work w = work.back();
    work.pop_back();
    bvh.stats.max_depth = std::max(bvh.stats.max_depth, w.depth);
    uint32_t cand[kBvhWidth];
    int k = 0;
    const BinaryNode& b = bin[w.bin_node];
    if (b.is_leaf()) {
      cand[k++] = w.bin_node;  // a single-leaf tree: the root holds that one leaf
    } else {
      cand[k++] = b.left_first;
      cand[k++] = b.left_first + 1;
    }
    while (k < kBvhWidth) {
      int best = -1;
      for (int i = 0; i < k; ++i) {
        if (!bin[cand[i]].is_leaf() &&
            (best < 0 || bin[cand[i]].box.area() > bin[cand[best]].box.area()))
          best = i;
      }
      if (best < 0) break;
      // After opening: k + 1 children, the tallest of them max_height high.
      const uint32_t opened = cand[best];
      uint32_t max_height = height[opened] - 1;
      for (int i = 0; i < k; ++i)
        if (i != best) max_height = std::max(max_height, height[cand[i]]);
      if (w.stack + uint32_t(k) + max_height > uint32_t(kBvhStackSize)) break;
      cand[best] = bin[opened].left_first;
      cand[k++] = bin[opened].left_first + 1;
    }
    const uint32_t child_stack = w.stack + uint32_t(k) - 1;
    bvh.stats.max_stack = std::max(bvh.stats.max_stack, child_stack);
    BvhNode node;
    for (int i = 0; i < kBvhWidth; ++i) node.child[i] = empty;
    for (int i = 0; i < k; ++i) {
      const BinaryNode& c = bin[cand[i]];
      BvhSlot& slot = node.child[i];
      slot.lo = c.box.lo;
      slot.hi = c.box.hi;
      slot.pad = 0;
      if (c.is_leaf()) {
        slot.ref = kBvhLeafBit | c.left_first;
        bvh.prim_indices[c.left_first + c.count - 1] |= kBvhLastPrimBit;
        bvh.stats.leaf_count++;
      } else {
        slot.ref = uint32_t(bvh.nodes.size());
        bvh.nodes.push_back(BvhNode{});
        work.push_back({cand[i], slot.ref, child_stack, w.depth + 1});
      }
    }
    bvh.nodes[w.wide_node] = node;
  }
  bvh.nodes.shrink_to_fit();
  bvh.stats.node_count = uint32_t(bvh.nodes.size());
}

}  // namespace

Bvh build_bvh(const std::vector<Aabb>& bounds, int max_leaf_size) {
  const auto start = std::chrono::steady_clock::now();
  Bvh bvh;
  std::vector<BinaryNode> nodes;
  const uint32_t n = uint32_t(bounds.size());
  bvh.prim_indices.resize(n);
  for (uint32_t i = 0; i < n; ++i) bvh.prim_indices[i] = i;
  std::vector<vec3> centroids(n);
  for (uint32_t i = 0; i < n; ++i) centroids[i] = bounds[i].centroid();

  if (n >= kBvhLeafBit) {  // leaf references keep 31 bits for the first primitive
    throw std::length_error("build_bvh: " + std::to_string(n) + " primitives; at most " +
                            std::to_string(kBvhLeafBit - 1) + " fit in a leaf reference");
  }
  nodes.reserve(n > 0 ? 2 * n : 1);
  BinaryNode root;
  root.left_first = 0;
  root.count = n;
  nodes.push_back(root);
  if (n == 0) {  // an empty scene has no nodes; traversal checks for that
    bvh.stats.build_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return bvh;
  }

  std::vector<Task> stack;
  stack.push_back({0, 0});
  double sah_sum = 0.0, root_area = 0.0;
  while (!stack.empty()) {
    const Task task = stack.back();
    stack.pop_back();
    BinaryNode& node = nodes[task.node];
    Aabb box, cbox;
    for (uint32_t i = 0; i < node.count; ++i) {
      const uint32_t p = bvh.prim_indices[node.left_first + i];
      box.grow(bounds[p]);
      cbox.grow(centroids[p]);
    }
    node.box = box;
    if (task.node == 0) root_area = std::max(area_double(box), 1e-300);

    const float leaf_cost = kIntersectCost * float(node.count);
    int best_axis = -1, best_split = 0;
    float best_cost = leaf_cost;
    if (node.count > 1 && task.depth < kMaxDepth) {
      for (int axis = 0; axis < 3; ++axis) {
        const float lo = cbox.lo[axis], hi = cbox.hi[axis];
        if (!(hi > lo)) continue;
        Aabb bin_box[kBins];
        uint32_t bin_count[kBins] = {};
        const float scale = float(kBins) / (hi - lo);
        for (uint32_t i = 0; i < node.count; ++i) {
          const uint32_t p = bvh.prim_indices[node.left_first + i];
          const int b = bin_of(centroids[p][axis], lo, scale);
          bin_count[b]++;
          bin_box[b].grow(bounds[p]);
        }
        float left_area[kBins - 1];
        uint32_t left_count[kBins - 1];
        Aabb acc;
        uint32_t cnt = 0;
        for (int i = 0; i < kBins - 1; ++i) {
          acc.grow(bin_box[i]);
          cnt += bin_count[i];
          left_area[i] = acc.area();
          left_count[i] = cnt;
        }
        acc = Aabb();
        cnt = 0;
        const float inv_area = 1.0f / std::max(box.area(), 1e-30f);
        for (int i = kBins - 1; i > 0; --i) {
          acc.grow(bin_box[i]);
          cnt += bin_count[i];
          if (cnt == 0 || left_count[i - 1] == 0) continue;
          const float cost = kTraversalCost + kIntersectCost * inv_area *
                                                  (left_area[i - 1] * float(left_count[i - 1]) +
                                                   acc.area() * float(cnt));
          if (cost < best_cost) {
            best_cost = cost;
            best_axis = axis;
            best_split = i;
          }
        }
      }
    }
    const bool must_split = node.count > uint32_t(max_leaf_size) * 4 && task.depth < kMaxDepth;
    if (best_axis < 0 && must_split) {
      // All centroids coincide (or SAH sees no gain): split the range in half so leaves stay small.
      best_axis = 3;
    }
    if (best_axis < 0 || (node.count <= uint32_t(max_leaf_size) && best_cost >= leaf_cost)) {
      sah_sum += area_double(box) * kIntersectCost * node.count;
      continue;
    }
    uint32_t* first = bvh.prim_indices.data() + node.left_first;
    uint32_t* last = first + node.count;
    uint32_t* mid;
    if (best_axis == 3) {
      mid = first + node.count / 2;
    } else {
      const float lo = cbox.lo[best_axis];
      const float scale = float(kBins) / (cbox.hi[best_axis] - lo);
      mid = std::partition(first, last, [&](uint32_t p) {
        return bin_of(centroids[p][best_axis], lo, scale) < best_split;
      });
      if (mid == first || mid == last) mid = first + node.count / 2;
    }
    const uint32_t left_count = uint32_t(mid - first);
    const uint32_t child = uint32_t(nodes.size());
    const uint32_t node_first = node.left_first, node_count = node.count;
    sah_sum += area_double(box) * kTraversalCost;
    BinaryNode left, right;
    left.left_first = node_first;
    left.count = left_count;
    right.left_first = node_first + left_count;
    right.count = node_count - left_count;
    nodes[task.node].left_first = child;
    nodes[task.node].count = 0;
    nodes.push_back(left);  // invalidates `node`
    nodes.push_back(right);
    stack.push_back({child + 1, task.depth + 1});
    stack.push_back({child, task.depth + 1});
  }
  bvh.stats.binary_node_count = uint32_t(nodes.size());
  bvh.stats.sah_cost = float(sah_sum / root_area);
  collapse_to_wide(nodes, bvh);
  bvh.stats.build_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return bvh;
}

}  // namespace tracer
