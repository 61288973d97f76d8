// Building the light BVH on the host: the bounds of each light (one switch on its kind) and the
// binary tree over them that render.light_sampler bvh descends (scene/light_tree_view.h).
#pragma once

#include <vector>

#include "scene/scene_view.h"

namespace tracer {

// What a light can light: its box, the cone its normals lie in (axis, cos theta_o), how far
// from its normal it emits (cos theta_e), and its power (Light::power). Power 0: the light is
// not in the tree (lights at infinity, lights that emit nothing).
struct LightBounds {
  Aabb box;
  vec3 axis = vec3(0.0f, 0.0f, 1.0f);
  float power = 0.0f;
  float cos_o = 1.0f;
  float cos_e = 0.0f;
  bool two_sided = false;
};

// The bounds of light `l` of scene `s` (whose arrays must be in host memory): the one place that
// knows each light kind's shape. A new kind of light is one case here.
LightBounds light_bounds(const SceneView& s, const Light& l);

// The smallest bounds holding both (pbrt-v4's Union of LightBounds and of DirectionCones).
LightBounds union_bounds(const LightBounds& a, const LightBounds& b);

struct LightTree {
  std::vector<LightTreeNode> nodes;    // root first; empty when no light has power
  std::vector<LightLeafEntry> leaves;  // each leaf's lights
  std::vector<uint64_t> trails;        // one per light: its way from the root, or kNotInLightTree
  uint32_t depth = 0;                  // of the deepest leaf (at most 63)
  uint32_t leaf_count = 0;
  double build_ms = 0.0;
};

// Each node splits its lights where pbrt-v4's surface area orientation heuristic (power x
// orientation measure x box area, over 12 buckets per axis) is lowest, unless no split costs
// less than the node itself and it holds at most kMaxLightsPerLeaf lights, which then make a
// leaf (Cycles' light tree makes the same choice). Where the splits would take a leaf deeper
// than max_depth (at most 63, the trail's bits), nodes are halved instead.
LightTree build_light_tree(const std::vector<LightBounds>& bounds, uint32_t max_depth = 63);

}  // namespace tracer
