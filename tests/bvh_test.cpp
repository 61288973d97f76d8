// The BVH must find exactly what brute force finds: the nearest hit for closest-hit queries and
// any hit for occlusion, on random soups of triangles and spheres and on real meshes.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#include <numeric>
#include <random>

#include "scene/loader.h"
#include "scene_builders.h"
#include "test_util.h"

namespace {
using namespace test;

Hit brute_force(const SceneView& s, const Ray& ray) {
  Hit best;
  const RayTriSetup setup(ray, 1.0f / ray.d);
  float tmax = ray.tmax;
  for (uint32_t p = 0; p < s.tri_count + s.sphere_count; ++p) {
    float t, b1 = 0, b2 = 0;
    bool h;
    if (p < s.tri_count) {
      const auto& tv = s.tri_verts[p];
      h = intersect_triangle(setup, tv.v0, tv.v1, tv.v2, tmax, t, b1, b2);
    } else {
      const auto& sp = s.spheres[p - s.tri_count];
      h = intersect_sphere(ray, sp.center, sp.radius, tmax, t);
    }
    if (h) {
      tmax = t;
      best.t = t;
      best.prim = p;
    }
  }
  return best;
}

Ray random_ray(std::mt19937& rng, vec3 lo, vec3 hi) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const vec3 ext = hi - lo;
  Ray r;
  r.o = lo - 0.25f * ext + 1.5f * ext * vec3(u(rng), u(rng), u(rng));
  const vec3 target = lo + ext * vec3(u(rng), u(rng), u(rng));
  r.d = glm::normalize(target - r.o);
  r.tmax = kInfinity;
  r.pad = 0;
  return r;
}

// Checks one traversal (the view's) against brute force on random rays.
void check_view(const SceneView& v, vec3 lo, vec3 hi, int rays, const std::string& what) {
  std::mt19937 rng(1234);
  int hits = 0, mismatches = 0;
  for (int i = 0; i < rays; ++i) {
    Ray r = random_ray(rng, lo, hi);
    const Hit a = intersect_closest(v, r);
    const Hit b = brute_force(v, r);
    if (a.valid()) ++hits;
    // Coplanar duplicates (the Cornell OBJ has some) tie at the same t: either prim is right.
    if (a.valid() != b.valid() || a.t != b.t) {
      if (mismatches++ < 5)
        ADD_FAILURE() << what << ": ray " << i << " bvh prim " << a.prim << " t " << a.t
                      << " vs brute force prim " << b.prim << " t " << b.t;
    }
    // Occlusion must agree too, with the ray cut short just before the nearest hit and beyond.
    Ray s = r;
    s.tmax = b.valid() ? b.t * 2.0f : 1e30f;
    EXPECT_EQ(intersect_any(v, s, kInvalid), b.valid()) << what << ": ray " << i;
    if (b.valid()) {
      s.tmax = b.t * 0.5f;
      const Hit c = brute_force(v, s);
      EXPECT_EQ(intersect_any(v, s, kInvalid), c.valid()) << what << ": short ray " << i;
    }
  }
  EXPECT_EQ(mismatches, 0) << what;
  EXPECT_GT(hits, rays / 10) << what << ": the rays should hit something often";
}

// The 8-wide tree holds every primitive once, within the stack bound, and each decoded child box
// contains the boxes of all primitives below it.
void check_bvh8_boxes(const CompiledScene& cs, const Bvh8& b8, const std::string& what) {
  if (b8.nodes.empty()) return;
  EXPECT_LE(b8.stats.max_stack, uint32_t(kBvhStackSize)) << what;
  ASSERT_EQ(b8.prim_indices.size(), cs.prim_indices().size()) << what;
  const SceneView& v = cs.view();
  std::vector<int> seen(v.tri_count + v.sphere_count, 0);
  auto prim_box = [&](uint32_t p) {
    Aabb b;
    if (p < v.tri_count) {
      b.grow(v.tri_verts[p].v0);
      b.grow(v.tri_verts[p].v1);
      b.grow(v.tri_verts[p].v2);
    } else {
      const Sphere& s = v.spheres[p - v.tri_count];
      b.grow(s.center - vec3(s.radius));
      b.grow(s.center + vec3(s.radius));
    }
    return b;
  };
  // Every primitive below node n, gathered by walking down.
  std::function<void(uint32_t, std::vector<uint32_t>&)> below = [&](uint32_t n,
                                                                    std::vector<uint32_t>& out) {
    const Bvh8Node& node = b8.nodes[n];
    for (uint32_t s = 0; s < 8; ++s) {
      const uint32_t meta = bvh8_byte(node.meta, s);
      if (meta == 0) continue;
      if (meta & 0x80u) {
        below(node.child_base + (meta & 0x7fu), out);
        continue;
      }
      for (uint32_t i = node.prim_base + meta - 1;; ++i) {
        out.push_back(b8.prim_indices[i] & ~kBvhLastPrimBit);
        if (b8.prim_indices[i] & kBvhLastPrimBit) break;
      }
    }
  };
  int bad = 0;
  for (uint32_t n = 0; n < b8.nodes.size(); ++n) {
    const Bvh8Node& node = b8.nodes[n];
    for (uint32_t s = 0; s < 8; ++s) {
      const uint32_t meta = bvh8_byte(node.meta, s);
      if (meta == 0) continue;
      std::vector<uint32_t> prims;
      if (meta & 0x80u) {
        below(node.child_base + (meta & 0x7fu), prims);
      } else {
        for (uint32_t i = node.prim_base + meta - 1;; ++i) {
          prims.push_back(b8.prim_indices[i] & ~kBvhLastPrimBit);
          ++seen[prims.back()];
          if (b8.prim_indices[i] & kBvhLastPrimBit) break;
        }
      }
      const Aabb box = bvh8_child_box(node, s);
      for (uint32_t p : prims) {
        const Aabb pb = prim_box(p);
        const bool inside = glm::all(glm::lessThanEqual(box.lo, pb.lo)) &&
                            glm::all(glm::lessThanEqual(pb.hi, box.hi));
        if (!inside && bad++ < 3)
          ADD_FAILURE() << what << ": node " << n << " slot " << s << " does not hold prim " << p;
      }
    }
  }
  for (size_t p = 0; p < seen.size(); ++p)
    if (seen[p] != 1 && bad++ < 6)
      ADD_FAILURE() << what << ": prim " << p << " in " << seen[p] << " leaves of the 8-wide tree";
}

// Both traversals against brute force, and the CPU's SSE traversal (bvh/cpu_bvh.h) against the
// shared one it must reproduce bit for bit: the same primitive, t and barycentrics, also when
// the nearest primitive is skipped (as the integrator skips a shadow ray's light).
void check_against_brute_force(const Scene& scene, int rays, const std::string& what) {
  const CompiledScene cs(scene, 16, 16);
  const Aabb box = scene_bounds(cs);
  SceneView shared = cs.view();
  shared.cpu_bvh = CpuBvhView();
  check_view(shared, box.lo, box.hi, rays, what + " (shared traversal)");
  // The 8-wide compressed tree of bvh8 builds, through the same shared traversal (compiled
  // there only; other builds check its boxes and primitives).
  const Bvh8 b8 = build_bvh8(cs.bvh());
  ASSERT_FALSE(b8.nodes.empty() && !scene.mesh.indices.empty()) << what << ": no 8-wide tree";
  check_bvh8_boxes(cs, b8, what);
  if (kBvh8Build && !b8.nodes.empty()) {
    SceneView wide8 = shared;
    wide8.nodes8 = b8.nodes.data();
    wide8.prim_indices8 = b8.prim_indices.data();
    wide8.node_count = uint32_t(b8.nodes.size());
    check_view(wide8, box.lo, box.hi, rays, what + " (8-wide traversal)");
  }
  if (!cpu_bvh_supported()) {
    std::cout << "[   NOTE   ] no SSE traversal in this build; only the shared one was checked\n";
    return;
  }
  const SceneView& simd = cs.view();
  ASSERT_NE(simd.cpu_bvh.nodes, nullptr) << what << ": CompiledScene should build the CPU BVH";
  check_view(simd, box.lo, box.hi, rays, what + " (SSE traversal)");
  std::mt19937 rng(99);
  int differ = 0;
  for (int i = 0; i < rays; ++i) {
    const Ray r = random_ray(rng, box.lo, box.hi);
    const Hit a = intersect_closest(simd, r), b = intersect_closest(shared, r);
    const bool same = a.prim == b.prim && a.t == b.t && a.u == b.u && a.v == b.v;
    if (!same && differ++ < 5)
      ADD_FAILURE() << what << ": ray " << i << " SSE prim " << a.prim << " t " << a.t << " uv "
                    << a.u << "," << a.v << " vs shared prim " << b.prim << " t " << b.t << " uv "
                    << b.u << "," << b.v;
    if (!b.valid()) continue;
    const Hit a2 = intersect_closest(simd, r, b.prim), b2 = intersect_closest(shared, r, b.prim);
    EXPECT_TRUE(a2.prim == b2.prim && a2.t == b2.t) << what << ": skipping prim " << b.prim;
    Ray s = r;
    s.tmax = b.t * 1.5f;
    EXPECT_EQ(intersect_any(simd, s, b.prim), intersect_any(shared, s, b.prim)) << what;
  }
  EXPECT_EQ(differ, 0) << what;
}

TEST(Bvh, NodesAreOneCacheLine) {
  EXPECT_EQ(sizeof(BvhNode), 128u);
}

TEST(Bvh, RandomTrianglesAndSpheresMatchBruteForce) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-10.0f, 10.0f), small(-1.0f, 1.0f), rad(0.05f, 1.0f);
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  for (int i = 0; i < 3000; ++i) {
    const vec3 c(u(rng), u(rng), u(rng));
    add_triangle(s.mesh, c + vec3(small(rng), small(rng), small(rng)),
                 c + vec3(small(rng), small(rng), small(rng)),
                 c + vec3(small(rng), small(rng), small(rng)), 0);
  }
  for (int i = 0; i < 200; ++i) s.spheres.push_back({vec3(u(rng), u(rng), u(rng)), rad(rng), 0});
  check_against_brute_force(s, 4000, "random soup");
}

TEST(Bvh, DegenerateInputs) {
  // Many primitives with the same centroid must still build a valid, shallow-enough tree.
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  for (int i = 0; i < 500; ++i) s.spheres.push_back({vec3(0.0f), 0.5f + 0.001f * i, 0});
  check_against_brute_force(s, 500, "concentric spheres");
  const CompiledScene cs(s, 4, 4);
  EXPECT_LT(cs.bvh_stats().max_depth, uint32_t(kBvhStackSize));
  EXPECT_LE(cs.bvh_stats().max_stack, uint32_t(kBvhStackSize));
}

TEST(Bvh, SinglePrimitive) {
  // The binary tree is one leaf; the 4-wide root holds it in its only slot.
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  add_triangle(s.mesh, vec3(-1, -1, -1), vec3(1, -1, 0), vec3(0, 1, 1), 0);
  check_against_brute_force(s, 200, "one triangle");
  const CompiledScene cs(s, 4, 4);
  EXPECT_EQ(cs.bvh_stats().node_count, 1u);
  EXPECT_EQ(cs.bvh_stats().leaf_count, 1u);
}

TEST(Bvh, DeepUnbalancedTreeStaysWithinTheStack) {
  // Triangles at geometrically growing distances make SAH peel off one small group per level,
  // so the binary tree reaches its depth cap; collapsing it must keep the traversal stack
  // within kBvhStackSize and still find every hit.
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  float x = 1.0f;
  for (int i = 0; i < 400; ++i, x *= 1.03f) {
    const float h = 2.0f * x;
    add_triangle(s.mesh, vec3(x, -h, -h), vec3(x, h, -h), vec3(x, 0, h), 0);
    add_triangle(s.mesh, vec3(-x, -h, -h), vec3(-x, 0, h), vec3(-x, h, -h), 0);
  }
  check_against_brute_force(s, 3000, "geometric series");
  const CompiledScene cs(s, 4, 4);
  EXPECT_LE(cs.bvh_stats().max_stack, uint32_t(kBvhStackSize));
  EXPECT_GT(cs.bvh_stats().max_depth, 4u) << "the input should make a deep tree";
}

TEST(Bvh, EmptyScene) {
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  const CompiledScene cs(s, 4, 4);
  Ray r{vec3(0.0f), kInfinity, vec3(0, 0, 1), 0.0f};
  EXPECT_FALSE(intersect_closest(cs.view(), r).valid());
  EXPECT_FALSE(intersect_any(cs.view(), r, kInvalid));
}

void check_mesh_file(const std::string& path, int rays) {
  std::ifstream f(path);
  if (!f) GTEST_SKIP() << path << " is not installed (scripts/setup.sh installs it)";
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  append_mesh_file(s, path, glm::mat4(1.0f), 0, SourceLoc{"bvh_test", 0});
  ASSERT_GT(s.mesh.indices.size(), 0u);
  check_against_brute_force(s, rays, path);
}

TEST(Bvh, StanfordBunnyMatchesBruteForce) {
  check_mesh_file("/usr/share/glmark2/models/bunny.obj", 1500);
}

TEST(Bvh, CornellBoxObjMatchesBruteForce) {
  check_mesh_file("/usr/share/doc/python3-tinyobjloader/examples/cornell_box.obj", 3000);
}

// ---- The parallel build: the same tree on every machine ----

// Boxes of n random triangles, most in dense clusters of different spreads and the rest spread
// out, so that the builder's top levels (nodes of 64K primitives or more, split one tree level
// at a time over fixed chunks) and its sequential subtrees both meet uneven splits.
std::vector<Aabb> random_triangle_boxes(uint32_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-100.0f, 100.0f), size(0.01f, 1.0f);
  std::normal_distribution<float> g(0.0f, 1.0f);
  vec3 centre[8];
  float spread[8];
  for (int c = 0; c < 8; ++c) {
    centre[c] = vec3(u(rng), u(rng), u(rng));
    spread[c] = 0.5f + 3.0f * float(c);
  }
  std::vector<Aabb> boxes(n);
  for (Aabb& b : boxes) {
    const int c = int(rng() % 10);  // 8 and 9: anywhere
    const vec3 at =
        c < 8 ? centre[c] + spread[c] * vec3(g(rng), g(rng), g(rng)) : vec3(u(rng), u(rng), u(rng));
    const float s = size(rng);
    for (int v = 0; v < 3; ++v) b.grow(at + s * vec3(g(rng), g(rng), g(rng)));
  }
  return boxes;
}

void expect_same_tree(const Bvh& a, const Bvh& b, const std::string& what) {
  ASSERT_EQ(a.nodes.size(), b.nodes.size()) << what;
  EXPECT_EQ(std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(BvhNode)), 0)
      << what << ": the nodes differ";
  EXPECT_TRUE(a.prim_indices == b.prim_indices) << what << ": the primitive order differs";
  EXPECT_EQ(a.stats.node_count, b.stats.node_count) << what;
  EXPECT_EQ(a.stats.binary_node_count, b.stats.binary_node_count) << what;
  EXPECT_EQ(a.stats.leaf_count, b.stats.leaf_count) << what;
  EXPECT_EQ(a.stats.max_depth, b.stats.max_depth) << what;
  EXPECT_EQ(a.stats.max_stack, b.stats.max_stack) << what;
  EXPECT_EQ(std::memcmp(&a.stats.sah_cost, &b.stats.sah_cost, sizeof(float)), 0)
      << what << ": SAH cost " << a.stats.sah_cost << " vs " << b.stats.sah_cost;
}

void expect_each_primitive_once(const Bvh& bvh, size_t n) {
  std::vector<int> seen(n, 0);
  for (uint32_t e : bvh.prim_indices) seen[e & ~kBvhLastPrimBit]++;
  int wrong = 0;
  for (size_t i = 0; i < n; ++i)
    if (seen[i] != 1 && wrong++ < 5) ADD_FAILURE() << "primitive " << i << " seen " << seen[i];
}

// The CPU and the GPU render from trees built on different machines, with different core
// counts; images of one seed agree pixel for pixel only if the tree does not depend on them.
TEST(Bvh, TreeIsTheSameForAnyThreadCount) {
  const std::vector<Aabb> boxes = random_triangle_boxes(300000, 11);
  const Bvh one = build_bvh(boxes, 4, 1);
  expect_each_primitive_once(one, boxes.size());
  EXPECT_LE(one.stats.max_stack, uint32_t(kBvhStackSize));
  for (int threads : {2, 3, 8})
    expect_same_tree(one, build_bvh(boxes, 4, threads), std::to_string(threads) + " threads");
}

// Empty, NaN, infinite, denormal and coincident boxes, enough of them that the top levels'
// chunked passes see them too: one tree for any thread count, every primitive in one leaf.
TEST(Bvh, DegenerateBoundsMakeTheSameTreeForAnyThreadCount) {
  const std::vector<Aabb> boxes = degenerate_boxes(12000, 500);
  const Bvh one = build_bvh(boxes, 4, 1);
  EXPECT_TRUE(std::isfinite(one.stats.sah_cost)) << one.stats.sah_cost;
  EXPECT_LE(one.stats.max_stack, uint32_t(kBvhStackSize));
  expect_each_primitive_once(one, boxes.size());
  for (int threads : {2, 5})
    expect_same_tree(one, build_bvh(boxes, 4, threads), std::to_string(threads) + " threads");
}

// A landscape of 160K triangles (the top levels split it before the subtrees do), with
// triangles floating above it, built on every core: the nearest hits of brute force.
TEST(Bvh, LargeSceneMatchesBruteForce) {
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  const int cells = 280;
  auto height = [](float x, float z) {
    return 2.0f * std::sin(0.11f * x) * std::cos(0.07f * z) + 0.3f * std::sin(1.3f * x + z);
  };
  for (int i = 0; i < cells; ++i) {
    for (int j = 0; j < cells; ++j) {
      const float x = float(i), z = float(j);
      const vec3 a(x, height(x, z), z), b(x + 1, height(x + 1, z), z);
      const vec3 c(x + 1, height(x + 1, z + 1), z + 1), d(x, height(x, z + 1), z + 1);
      add_triangle(s.mesh, a, b, c, 0);
      add_triangle(s.mesh, a, c, d, 0);
    }
  }
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, float(cells)), up(3.0f, 30.0f), small(-2, 2);
  for (int i = 0; i < 3000; ++i) {
    const vec3 c(u(rng), up(rng), u(rng));
    add_triangle(s.mesh, c + vec3(small(rng), small(rng), small(rng)),
                 c + vec3(small(rng), small(rng), small(rng)),
                 c + vec3(small(rng), small(rng), small(rng)), 0);
  }
  check_against_brute_force(s, 300, "landscape");
}

// The SAH cost of the tree that the sequential builder made before the build ran in parallel
// (bvh_build.cpp's history): 16 bins per axis over the centroid bounds, traversal and
// intersection cost 1, leaves of up to 4 primitives unless splitting pays, nodes of more than
// 16 always split, nothing split at depth kBvhStackSize - 4. For finite bounds.
double sequential_sah_cost(const std::vector<Aabb>& bounds) {
  constexpr int kBins = 16;
  constexpr uint32_t kMaxLeaf = 4, kMaxDepth = kBvhStackSize - 4;
  auto area = [](const Aabb& b) {
    const glm::dvec3 e = glm::dvec3(b.hi) - glm::dvec3(b.lo);
    return 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
  };
  auto bin_of = [](float c, float lo, float scale) {
    const float f = (c - lo) * scale;
    return f >= 0.0f ? int(std::min(f, float(kBins - 1))) : 0;
  };
  std::vector<uint32_t> prims(bounds.size());
  std::iota(prims.begin(), prims.end(), 0u);
  struct Range {
    uint32_t first, count, depth;
  };
  std::vector<Range> stack{{0, uint32_t(prims.size()), 0}};
  double sah = 0.0, root_area = 0.0;
  while (!stack.empty()) {
    const Range r = stack.back();
    stack.pop_back();
    Aabb box, cbox;
    for (uint32_t i = r.first; i < r.first + r.count; ++i) {
      box.grow(bounds[prims[i]]);
      cbox.grow(bounds[prims[i]].centroid());
    }
    if (r.count == prims.size()) root_area = area(box);
    const float leaf_cost = float(r.count);
    int best_axis = -1, best_split = 0;
    float best_cost = leaf_cost;
    for (int axis = 0; axis < 3 && r.count > 1 && r.depth < kMaxDepth; ++axis) {
      const float lo = cbox.lo[axis], hi = cbox.hi[axis];
      if (!(hi > lo)) continue;
      Aabb bin_box[kBins];
      uint32_t bin_count[kBins] = {};
      const float scale = float(kBins) / (hi - lo);
      for (uint32_t i = r.first; i < r.first + r.count; ++i) {
        const int b = bin_of(bounds[prims[i]].centroid()[axis], lo, scale);
        bin_count[b]++;
        bin_box[b].grow(bounds[prims[i]]);
      }
      const float inv_area = 1.0f / std::max(box.area(), 1e-30f);
      for (int split = 1; split < kBins; ++split) {
        Aabb left, right;
        uint32_t nl = 0, nr = 0;
        for (int b = 0; b < kBins; ++b) {
          (b < split ? left : right).grow(bin_box[b]);
          (b < split ? nl : nr) += bin_count[b];
        }
        if (nl == 0 || nr == 0) continue;
        const float cost = 1.0f + inv_area * (left.area() * float(nl) + right.area() * float(nr));
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = axis;
          best_split = split;
        }
      }
    }
    if (best_axis < 0 && r.count > 4 * kMaxLeaf && r.depth < kMaxDepth) best_axis = 3;
    if (best_axis < 0 || (r.count <= kMaxLeaf && best_cost >= leaf_cost)) {
      sah += area(box) * r.count;
      continue;
    }
    uint32_t* first = prims.data() + r.first;
    uint32_t* mid = first + r.count / 2;
    if (best_axis < 3) {
      const float lo = cbox.lo[best_axis];
      const float scale = float(kBins) / (cbox.hi[best_axis] - lo);
      mid = std::partition(first, first + r.count, [&](uint32_t p) {
        return bin_of(bounds[p].centroid()[best_axis], lo, scale) < best_split;
      });
    }
    const uint32_t left = uint32_t(mid - first);
    sah += area(box);
    stack.push_back({r.first, left, r.depth + 1});
    stack.push_back({r.first + left, r.count - left, r.depth + 1});
  }
  return sah / root_area;
}

// Building in parallel must not cost tree quality: the SAH cost of the binary tree (before the
// collapse) within 1% of the sequential builder's on the same boxes.
TEST(Bvh, ParallelBuildKeepsTheSequentialSahCost) {
  const std::vector<Aabb> boxes = random_triangle_boxes(300000, 11);
  const double reference = sequential_sah_cost(boxes);
  const Bvh bvh = build_bvh(boxes, 4, 2);
  std::cout << "[   NOTE   ] SAH cost " << bvh.stats.sah_cost << ", sequential builder "
            << reference << "\n";
  EXPECT_NEAR(bvh.stats.sah_cost, reference, 0.01 * reference);
}

}  // namespace
