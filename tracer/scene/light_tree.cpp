// The light BVH's build: per-light bounds, the union of bounds and of direction cones, and the
// top-down split by pbrt-v4's surface area orientation heuristic (pbrt-v4 sec. 12.6.3; Conty
// Estevez & Kulla 2018).
#include "scene/light_tree.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

namespace tracer {
namespace {

constexpr double kPiD = 3.14159265358979323846;

double safe_acos(double x) {
  return std::acos(std::clamp(x, -1.0, 1.0));
}

// The angle between unit vectors, accurate when they are close or opposite (pbrt-v4's
// AngleBetween).
double angle_between(glm::dvec3 a, glm::dvec3 b) {
  if (glm::dot(a, b) < 0.0) return kPiD - 2.0 * std::asin(std::min(1.0, glm::length(a + b) / 2));
  return 2.0 * std::asin(std::min(1.0, glm::length(b - a) / 2));
}

// Rotation of v by `angle` about the unit axis k (Rodrigues).
glm::dvec3 rotate(glm::dvec3 v, glm::dvec3 k, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return v * c + glm::cross(k, v) * s + k * glm::dot(k, v) * (1.0 - c);
}

// The smallest cone (axis, cos theta) holding cones a and b (pbrt-v4's Union of DirectionCones).
void cone_union(vec3 wa, float cos_a, vec3 wb, float cos_b, vec3* w, float* cos_o) {
  const double theta_a = safe_acos(cos_a), theta_b = safe_acos(cos_b);
  const glm::dvec3 da = glm::normalize(glm::dvec3(wa)), db = glm::normalize(glm::dvec3(wb));
  const double theta_d = angle_between(da, db);
  if (std::min(theta_d + theta_b, kPiD) <= theta_a) {
    *w = wa;
    *cos_o = cos_a;
    return;
  }
  if (std::min(theta_d + theta_a, kPiD) <= theta_b) {
    *w = wb;
    *cos_o = cos_b;
    return;
  }
  const double theta_o = (theta_a + theta_d + theta_b) / 2;
  const glm::dvec3 wr = glm::cross(da, db);
  if (theta_o >= kPiD || glm::dot(wr, wr) == 0.0) {
    *w = wa;
    *cos_o = -1.0f;
    return;
  }
  *w = vec3(glm::normalize(rotate(da, glm::normalize(wr), theta_o - theta_a)));
  // A hair wider than computed, so that rounding never leaves a light's normal outside.
  *cos_o = float(std::cos(std::min(theta_o + 1e-5, kPiD)));
}

// pbrt-v4's EvaluateCost: power x the solid angle measure of the cone x the box's area; a split
// multiplies it by Kr, which penalises splits across the box's short axes.
double cost(const LightBounds& b) {
  if (!(b.power > 0.0f)) return 0.0;
  const double theta_o = safe_acos(b.cos_o), theta_e = safe_acos(b.cos_e);
  const double theta_w = std::min(theta_o + theta_e, kPiD);
  const double sin_o = std::sqrt(std::max(0.0, 1.0 - double(b.cos_o) * b.cos_o));
  const double m_omega =
      2 * kPiD * (1 - b.cos_o) +
      kPiD / 2 *
          (2 * theta_w * sin_o - std::cos(theta_o - 2 * theta_w) - 2 * theta_o * sin_o + b.cos_o);
  return double(b.power) * m_omega * double(b.box.area());
}

int ceil_log2(size_t n) {
  int k = 0;
  while ((size_t(1) << k) < n) ++k;
  return k;
}

struct Builder {
  const std::vector<LightBounds>& bounds;
  LightTree& tree;
  uint32_t max_depth;

  LightTreeNode make_node(const LightBounds& b, uint32_t index, uint32_t leaf_count) const {
    LightTreeNode n{};
    n.lo = b.box.lo;
    n.hi = b.box.hi;
    n.power = b.power;
    n.axis = b.axis;
    n.cos_o = b.cos_o;
    n.sin_o = std::sqrt(std::max(0.0f, 1.0f - b.cos_o * b.cos_o));
    n.radius = 0.5f * glm::length(b.box.hi - b.box.lo);
    n.cos_e = b.cos_e;
    n.index = index;
    n.flags = (leaf_count > 0 ? kLightNodeLeaf | leaf_count << kLightNodeCountShift : 0u) |
              (b.two_sided ? kLightNodeTwoSided : 0u);
    return n;
  }

  LightBounds make_leaf(const std::vector<uint32_t>& lights, size_t start, size_t end,
                        uint32_t node, uint64_t trail, uint32_t depth) {
    LightBounds b;
    const uint32_t first = uint32_t(tree.leaves.size());
    for (size_t i = start; i < end; ++i) {
      const uint32_t li = lights[i];
      b = union_bounds(b, bounds[li]);
      tree.leaves.push_back({li, bounds[li].power});
      tree.trails[li] = trail;
    }
    tree.nodes[node] = make_node(b, first, uint32_t(end - start));
    tree.depth = std::max(tree.depth, depth);
    tree.leaf_count++;
    return b;
  }

  // Builds the subtree over lights[start, end) at `depth`; returns its bounds.
  LightBounds build(std::vector<uint32_t>& lights, size_t start, size_t end, uint64_t trail,
                    uint32_t depth) {
    const uint32_t node = uint32_t(tree.nodes.size());
    tree.nodes.emplace_back();
    if (end - start == 1) return make_leaf(lights, start, end, node, trail, depth);
    LightBounds all;
    Aabb centroids;
    for (size_t i = start; i < end; ++i) {
      all = union_bounds(all, bounds[lights[i]]);
      centroids.grow(bounds[lights[i]].box.centroid());
    }
    const Aabb& box = all.box;
    constexpr int kBuckets = 12;
    auto bucket_of = [&](uint32_t li, int dim) {
      const float lo = centroids.lo[dim], ext = centroids.hi[dim] - lo;
      const int b = int(kBuckets * ((bounds[li].box.centroid()[dim] - lo) / ext));
      return std::clamp(b, 0, kBuckets - 1);
    };
    // From here only halving keeps every leaf within max_depth (a node of n lights at depth d
    // has leaves at d + ceil(log2 n) when halved: the invariant d + ceil(log2 n) <= max_depth
    // holds at the root and is kept by every split).
    const bool halve = depth + uint32_t(ceil_log2(end - start)) >= max_depth;
    double best = INFINITY;
    int best_dim = -1, best_bucket = -1;
    for (int dim = 0; dim < 3 && !halve; ++dim) {
      if (!(centroids.hi[dim] > centroids.lo[dim])) continue;
      LightBounds buckets[kBuckets];
      for (size_t i = start; i < end; ++i)
        buckets[bucket_of(lights[i], dim)] =
            union_bounds(buckets[bucket_of(lights[i], dim)], bounds[lights[i]]);
      LightBounds below[kBuckets];  // below[i]: buckets 0..i
      below[0] = buckets[0];
      for (int i = 1; i < kBuckets; ++i) below[i] = union_bounds(below[i - 1], buckets[i]);
      const vec3 e = box.hi - box.lo;
      const double kr = double(max_component(e)) / double(e[dim]);
      LightBounds above;  // buckets i+1 .. end
      for (int i = kBuckets - 2; i >= 0; --i) {
        above = union_bounds(above, buckets[i + 1]);
        const double c = kr * (cost(below[i]) + cost(above));
        if (below[i].power > 0.0f && above.power > 0.0f && c < best) {
          best = c;
          best_dim = dim;
          best_bucket = i;
        }
      }
    }
    if (end - start <= kMaxLightsPerLeaf && (halve || !(best < cost(all))))
      return make_leaf(lights, start, end, node, trail, depth);
    size_t mid = (start + end) / 2;
    if (best_dim >= 0) {
      const auto first = lights.begin() + std::ptrdiff_t(start);
      const auto last = lights.begin() + std::ptrdiff_t(end);
      const auto split = std::stable_partition(
          first, last, [&](uint32_t li) { return bucket_of(li, best_dim) <= best_bucket; });
      const size_t m = size_t(split - lights.begin());
      if (m > start && m < end) mid = m;
    }
    const LightBounds b0 = build(lights, start, mid, trail, depth + 1);
    const uint32_t second = uint32_t(tree.nodes.size());
    const LightBounds b1 = build(lights, mid, end, trail | (uint64_t(1) << depth), depth + 1);
    const LightBounds b = union_bounds(b0, b1);
    tree.nodes[node] = make_node(b, second, 0);
    return b;
  }
};

}  // namespace

LightBounds light_bounds(const SceneView& s, const Light& l) {
  LightBounds b;
  if (!(l.power > 0.0f)) return b;
  switch (LightKind(l.kind)) {
    case kLightPrimitive:
      if (l.prim < s.tri_count) {
        // One-sided: emits around its normal (the side material_emission calls the front),
        // theta_o = 0, theta_e = pi/2; two-sided: the same cone, read with |cos|.
        const TriangleVerts& tv = s.tri_verts[l.prim];
        b.box.grow(tv.v0);
        b.box.grow(tv.v1);
        b.box.grow(tv.v2);
        const vec3 n = glm::cross(tv.v1 - tv.v0, tv.v2 - tv.v0);
        const float len = glm::length(n);
        if (!(len > 0.0f)) return LightBounds();
        b.axis = n / len;
        b.cos_o = 1.0f;
        b.two_sided =
            (s.materials[s.tri_shading[l.prim].material].flags & kMaterialTwoSidedEmission) != 0;
      } else {
        // A sphere emits along every normal: theta_o = pi, theta_e = pi/2.
        const Sphere& sph = s.spheres[l.prim - s.tri_count];
        b.box.grow(sph.center - vec3(sph.radius));
        b.box.grow(sph.center + vec3(sph.radius));
        b.cos_o = -1.0f;
      }
      b.cos_e = 0.0f;
      b.power = l.power;
      return b;
    case kLightPoint:
    case kLightSpot: {
      // pbrt-v4's PointLight / SpotLight::Bounds: a point; a point light emits over the whole
      // sphere (theta_o = pi), a spot within its falloff's start (theta_o) plus the width of the
      // falloff (theta_e).
      const PointLight& pl = s.point_lights[l.prim];
      b.box.grow(pl.position);
      if (LightKind(l.kind) == kLightSpot) {
        b.axis = pl.axis;
        b.cos_o = pl.cos_falloff_start;
        b.cos_e = std::cos(std::max(0.0f, std::acos(glm::clamp(pl.cos_falloff_end, -1.0f, 1.0f)) -
                                              std::acos(glm::clamp(pl.cos_falloff_start, -1.0f, 1.0f))));
      } else {
        b.cos_o = -1.0f;
        b.cos_e = 0.0f;
      }
      b.power = l.power;
      return b;
    }
    case kLightEnvironment:
    case kLightDistant:
      return LightBounds();  // at infinity: chosen apart from the tree (integrator/lights.h)
  }
  return LightBounds();
}

LightBounds union_bounds(const LightBounds& a, const LightBounds& b) {
  if (!(a.power > 0.0f)) return b;
  if (!(b.power > 0.0f)) return a;
  LightBounds u;
  u.box = a.box;
  u.box.grow(b.box);
  cone_union(a.axis, a.cos_o, b.axis, b.cos_o, &u.axis, &u.cos_o);
  u.cos_e = std::min(a.cos_e, b.cos_e);
  u.power = a.power + b.power;
  u.two_sided = a.two_sided || b.two_sided;
  return u;
}

LightTree build_light_tree(const std::vector<LightBounds>& bounds, uint32_t max_depth) {
  const auto t0 = std::chrono::steady_clock::now();
  LightTree tree;
  tree.trails.assign(bounds.size(), kNotInLightTree);
  std::vector<uint32_t> lights;
  for (uint32_t i = 0; i < bounds.size(); ++i)
    if (bounds[i].power > 0.0f && !bounds[i].box.empty()) lights.push_back(i);
  if (lights.empty()) return tree;
  tree.nodes.reserve(2 * lights.size() - 1);
  max_depth = std::min(max_depth, 63u);
  if (uint32_t(ceil_log2(lights.size())) > max_depth)
    throw std::invalid_argument("build_light_tree: more lights than a tree of depth " +
                                std::to_string(max_depth) + " holds");
  Builder{bounds, tree, max_depth}.build(lights, 0, lights.size(), 0, 0);
  tree.build_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return tree;
}

}  // namespace tracer
