// The light BVH as the integrator reads it: nodes with a box, an orientation cone and a power;
// the importance of a node for a shading point; the stochastic descent that chooses a light; and
// the probability of one light retraced from its bit trail, for MIS. pbrt-v4's BVHLightSampler
// (Pharr, Jakob & Humphreys, 4th ed., sec. 12.6.3) after Conty Estevez & Kulla, "Importance
// Sampling of Many Lights with Adaptive Tree Splitting" (HPG 2018). Built by scene/light_tree.h.
#pragma once

#include "core/math.h"

namespace tracer {

// How next-event estimation chooses a light (render.light_sampler).
enum LightSampler : uint32_t {
  kLightSamplerUniform = 0,  // every light alike
  kLightSamplerPower = 1,    // in proportion to power (SceneView::light_cdf)
  kLightSamplerBvh = 2,      // the light tree, by each node's importance for the shading point
};

// Where a light is chosen from: a point and its geometric normal (zero: none, as in a medium).
struct LightContext {
  vec3 p;
  vec3 n;
};

// A shading point's normal in 12 bits (octahedral map, 6 bits per coordinate; Cigolle et al.,
// "A Survey of Efficient Representations for Independent Unit Vectors", JCGT 2014). The path
// keeps the code of its last vertex (PathState::prev_normal), so the tree's pmf at a
// BSDF-sampled emitter sees the very normal that next-event estimation used there; the code
// moves a normal by at most four degrees, which only blurs the importance's cos theta_i bound.
constexpr uint32_t kLightNormalBits = 12;

TRACER_HD TRACER_INLINE uint32_t pack_light_normal(vec3 n) {
  const float l1 = glm::abs(n.x) + glm::abs(n.y) + glm::abs(n.z);
  if (!(l1 > 0.0f)) return 0u;
  float x = n.x / l1, y = n.y / l1;
  if (n.z < 0.0f) {  // fold the lower half over the diagonals
    const float fx = (1.0f - glm::abs(y)) * (x >= 0.0f ? 1.0f : -1.0f);
    const float fy = (1.0f - glm::abs(x)) * (y >= 0.0f ? 1.0f : -1.0f);
    x = fx;
    y = fy;
  }
  const uint32_t qx = uint32_t(glm::clamp(x * 0.5f + 0.5f, 0.0f, 1.0f) * 63.0f + 0.5f);
  const uint32_t qy = uint32_t(glm::clamp(y * 0.5f + 0.5f, 0.0f, 1.0f) * 63.0f + 0.5f);
  return qx | qy << 6;
}

TRACER_HD TRACER_INLINE vec3 unpack_light_normal(uint32_t code) {
  const float x = float(code & 63u) * (2.0f / 63.0f) - 1.0f;
  const float y = float((code >> 6) & 63u) * (2.0f / 63.0f) - 1.0f;
  vec3 n(x, y, 1.0f - glm::abs(x) - glm::abs(y));
  if (n.z < 0.0f) {
    const float t = -n.z;
    n.x += n.x >= 0.0f ? -t : t;
    n.y += n.y >= 0.0f ? -t : t;
  }
  return glm::normalize(n);
}

// LightTreeNode::flags; a leaf's light count is in the bits from kLightNodeCountShift on.
enum LightTreeNodeFlags : uint32_t {
  kLightNodeLeaf = 1u << 0,
  kLightNodeTwoSided = 1u << 1,  // some light below emits from both faces: |cos| about the axis
  kLightNodeCountShift = 8,
};
// A leaf holds up to this many lights, chosen among by power: lights that no split would
// separate in space or orientation (the two triangles of a quad lamp, whose boxes coincide).
constexpr uint32_t kMaxLightsPerLeaf = 8;

// One node, 64 bytes. The first child of an interior node follows it; `index` is its second
// child, or a leaf's first entry in SceneView::light_tree.leaves. The cone: every light below
// emits only in directions within theta_e of some direction within theta_o of `axis`.
struct alignas(16) LightTreeNode {
  vec3 lo;
  float power;  // the lights' summed Light::power
  vec3 hi;
  float cos_o;  // cos theta_o: the spread of the lights' normals about the axis
  vec3 axis;
  float cos_e;  // cos theta_e: how far from its normal each light emits (pi/2 for a surface)
  uint32_t index;
  uint32_t flags;  // LightTreeNodeFlags and a leaf's count
  float sin_o;     // sin theta_o
  float radius;    // of the box's bounding sphere: half its diagonal
};
static_assert(sizeof(LightTreeNode) == 64, "LightTreeNode is read as four float4");

// A light's way from the root to its leaf: bit d says which child it took at depth d (1: the
// second). Trails have at most 63 bits (light_tree.cpp keeps the tree that shallow); lights
// outside the tree (at infinity, zero power) have this one.
constexpr uint64_t kNotInLightTree = ~uint64_t(0);

// Node k, as four 16-byte reads through the read-only cache on the GPU.
TRACER_HD TRACER_INLINE LightTreeNode load_light_node(const LightTreeNode* nodes, uint32_t k) {
#if defined(__CUDA_ARCH__)
  const float4* q = reinterpret_cast<const float4*>(nodes + k);
  const float4 a = __ldg(q), b = __ldg(q + 1), c = __ldg(q + 2), d = __ldg(q + 3);
  LightTreeNode n;
  n.lo = vec3(a.x, a.y, a.z);
  n.power = a.w;
  n.hi = vec3(b.x, b.y, b.z);
  n.cos_o = b.w;
  n.axis = vec3(c.x, c.y, c.z);
  n.cos_e = c.w;
  n.index = __float_as_uint(d.x);
  n.flags = __float_as_uint(d.y);
  n.sin_o = d.z;
  n.radius = d.w;
  return n;
#else
  return nodes[k];
#endif
}

namespace detail {
// cos(max(0, a - b)) and sin(max(0, a - b)) from the sines and cosines of angles a, b in [0, pi].
TRACER_HD TRACER_INLINE float cos_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  return cos_a > cos_b ? 1.0f : cos_a * cos_b + sin_a * sin_b;
}
TRACER_HD TRACER_INLINE float sin_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  return cos_a > cos_b ? 0.0f : sin_a * cos_b - cos_a * sin_b;
}
}  // namespace detail

// How much the lights under `node` may give to point p with normal n (n zero: no surface):
// power / distance^2, times the cosine of the smallest angle at which any of them may emit
// towards p and that of the smallest angle at which p may receive from the box. A conservative
// bound in angle: zero only when no light below can reach p. pbrt-v4's LightBounds::Importance,
// but the distance is clamped below by the box's bounding radius squared (pbrt-v4 clamps by the
// half-diagonal itself, a length, which makes the tree depend on the scene's units). Four square
// roots and two divisions; every angle is carried as its cosine and sine.
TRACER_HD inline float light_node_importance(const LightTreeNode& node, vec3 p, vec3 n) {
  const vec3 to_p = p - (0.5f * node.lo + 0.5f * node.hi);
  const float dist2 = glm::dot(to_p, to_p);
  const float r = node.radius, r2 = r * r;
  // theta_b: the half-angle of the cone from p that holds the box's bounding sphere (every
  // direction when p is inside it; then the direction to p does not matter either).
  float cos_b = -1.0f, sin_b = 0.0f, inv_dist = 0.0f;
  if (dist2 > r2) {
    inv_dist = fast_rsqrt(dist2);
    sin_b = r * inv_dist;
    cos_b = safe_sqrt(1.0f - sin_b * sin_b);
  }
  // theta_w: the angle between the axis and the way to p; less theta_o and theta_b, the
  // smallest angle from any light's normal to p (theta'), which must be below theta_e.
  float cos_w = glm::dot(node.axis, to_p) * inv_dist;
  if (node.flags & kLightNodeTwoSided) cos_w = glm::abs(cos_w);
  const float sin_w = safe_sqrt(1.0f - cos_w * cos_w);
  const float cos_x = detail::cos_sub_clamped(sin_w, cos_w, node.sin_o, node.cos_o);
  const float sin_x = detail::sin_sub_clamped(sin_w, cos_w, node.sin_o, node.cos_o);
  const float cos_p = detail::cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
  if (cos_p <= node.cos_e) return 0.0f;
  float importance = node.power * cos_p;
  if (n.x != 0.0f || n.y != 0.0f || n.z != 0.0f) {
    // theta_i at p, less theta_b; two-sided, as transmitters receive from both sides.
    const float cos_i = glm::abs(glm::dot(to_p, n)) * inv_dist;
    const float sin_i = safe_sqrt(1.0f - cos_i * cos_i);
    importance *= detail::cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
  }
  return glm::max(fast_div(importance, glm::max(glm::max(dist2, r2), 1e-12f)), 0.0f);
}

// A light of a leaf, with its power (Light::power).
struct LightLeafEntry {
  uint32_t light;
  float power;
};

// The arrays the descent reads (SceneView::light_tree).
struct LightTreeView {
  const LightTreeNode* nodes;
  const LightLeafEntry* leaves;  // the lights of each leaf, one leaf after another
  const uint64_t* trails;        // per light
};

// A light chosen from the tree: `light` (kInvalid when none can reach the point), its
// probability, and the choosing number rescaled to [0, 1) within the choices made.
struct LightTreeChoice {
  uint32_t light;
  float pmf;
  float u;
};

// Stochastic descent from the root: at each node, a child in proportion to its importance; in
// the leaf, a light in proportion to its power. The pmf is the product of those choices
// (pbrt-v4's BVHLightSampler::Sample). A lone leaf at the root is taken without asking its
// importance: it would only spare the choice within it for points it cannot light.
TRACER_HD inline LightTreeChoice light_tree_choose(const LightTreeView& t, const LightContext& ctx,
                                                   float u) {
  LightTreeChoice c;
  c.light = kInvalid;
  c.pmf = 0.0f;
  c.u = u;
  uint32_t k = 0;
  float pmf = 1.0f;
  for (;;) {
    const LightTreeNode node = load_light_node(t.nodes, k);
    if (node.flags & kLightNodeLeaf) {
      const uint32_t count = node.flags >> kLightNodeCountShift;
      float rest = u * node.power;
      for (uint32_t j = 0;; ++j) {
        const LightLeafEntry e = t.leaves[node.index + j];
        if (rest < e.power || j + 1 >= count) {
          c.light = e.light;
          c.pmf = pmf * (e.power / node.power);
          c.u = glm::clamp(rest / e.power, 0.0f, 0x1.fffffep-1f);
          return c;
        }
        rest -= e.power;
      }
    }
    const float i0 = light_node_importance(load_light_node(t.nodes, k + 1), ctx.p, ctx.n);
    const float i1 = light_node_importance(load_light_node(t.nodes, node.index), ctx.p, ctx.n);
    const float sum = i0 + i1;
    if (!(sum > 0.0f)) return c;
    const float p0 = i0 / sum, p1 = i1 / sum;
    if (u < p0) {
      u = glm::min(u / p0, 0x1.fffffep-1f);
      pmf *= p0;
      k = k + 1;
    } else {
      u = glm::min((u - p0) / p1, 0x1.fffffep-1f);
      pmf *= p1;
      k = node.index;
    }
  }
}

// The probability that light_tree_choose returns `light`, retraced from the root along its
// trail with the same importances in the same order, so that it equals the sampled pmf.
TRACER_HD inline float light_tree_pmf(const LightTreeView& t, uint32_t light,
                                      const LightContext& ctx) {
  uint64_t trail = t.trails[light];
  if (trail == kNotInLightTree) return 0.0f;
  uint32_t k = 0;
  float pmf = 1.0f;
  for (;;) {
    const LightTreeNode node = load_light_node(t.nodes, k);
    if (node.flags & kLightNodeLeaf) {
      const uint32_t count = node.flags >> kLightNodeCountShift;
      for (uint32_t j = 0; j < count; ++j) {
        const LightLeafEntry e = t.leaves[node.index + j];
        if (e.light == light) return pmf * (e.power / node.power);
      }
      return 0.0f;
    }
    const float i0 = light_node_importance(load_light_node(t.nodes, k + 1), ctx.p, ctx.n);
    const float i1 = light_node_importance(load_light_node(t.nodes, node.index), ctx.p, ctx.n);
    const float sum = i0 + i1;
    if (!(sum > 0.0f)) return 0.0f;
    if (trail & 1u) {
      pmf *= i1 / sum;
      k = node.index;
    } else {
      pmf *= i0 / sum;
      k = k + 1;
    }
    trail >>= 1;
  }
}

}  // namespace tracer
