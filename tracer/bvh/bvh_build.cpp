// Host-side binned-SAH BVH builder: 16 bins per axis over centroid bounds, leaves when splitting
// does not pay, iterative so that deep inputs cannot overflow the call stack.
#include <algorithm>
#include <chrono>

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

}  // namespace

Bvh build_bvh(const std::vector<Aabb>& bounds, int max_leaf_size) {
  const auto start = std::chrono::steady_clock::now();
  Bvh bvh;
  const uint32_t n = uint32_t(bounds.size());
  bvh.prim_indices.resize(n);
  for (uint32_t i = 0; i < n; ++i) bvh.prim_indices[i] = i;
  std::vector<vec3> centroids(n);
  for (uint32_t i = 0; i < n; ++i) centroids[i] = bounds[i].centroid();

  bvh.nodes.reserve(n > 0 ? 2 * n : 1);
  BvhNode root{};
  root.left_first = 0;
  root.count = n;
  bvh.nodes.push_back(root);
  if (n == 0) {  // an empty scene has no nodes; traversal checks for that
    bvh.nodes.clear();
    bvh.stats.build_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return bvh;
  }

  std::vector<Task> stack;
  stack.push_back({0, 0});
  double sah_sum = 0.0;
  float root_area = 0.0f;
  while (!stack.empty()) {
    const Task task = stack.back();
    stack.pop_back();
    BvhNode& node = bvh.nodes[task.node];
    Aabb box, cbox;
    for (uint32_t i = 0; i < node.count; ++i) {
      const uint32_t p = bvh.prim_indices[node.left_first + i];
      box.grow(bounds[p]);
      cbox.grow(centroids[p]);
    }
    node.lo = box.lo;
    node.hi = box.hi;
    if (task.node == 0) root_area = std::max(box.area(), 1e-30f);
    bvh.stats.max_depth = std::max(bvh.stats.max_depth, task.depth);

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
          const int b = std::min(kBins - 1, int((centroids[p][axis] - lo) * scale));
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
      bvh.stats.leaf_count++;
      sah_sum += double(box.area()) * kIntersectCost * node.count;
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
        return std::min(kBins - 1, int((centroids[p][best_axis] - lo) * scale)) < best_split;
      });
      if (mid == first || mid == last) mid = first + node.count / 2;
    }
    const uint32_t left_count = uint32_t(mid - first);
    const uint32_t child = uint32_t(bvh.nodes.size());
    const uint32_t node_first = node.left_first, node_count = node.count;
    sah_sum += double(box.area()) * kTraversalCost;
    BvhNode left{}, right{};
    left.left_first = node_first;
    left.count = left_count;
    right.left_first = node_first + left_count;
    right.count = node_count - left_count;
    bvh.nodes[task.node].left_first = child;
    bvh.nodes[task.node].count = 0;
    bvh.nodes.push_back(left);  // invalidates `node`
    bvh.nodes.push_back(right);
    stack.push_back({child + 1, task.depth + 1});
    stack.push_back({child, task.depth + 1});
  }
  bvh.nodes.shrink_to_fit();
  bvh.stats.node_count = uint32_t(bvh.nodes.size());
  bvh.stats.sah_cost = float(sah_sum / root_area);
  bvh.stats.build_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return bvh;
}

}  // namespace tracer
