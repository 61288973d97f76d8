// The BVH must find exactly what brute force finds: the nearest hit for closest-hit queries and
// any hit for occlusion, on random soups of triangles and spheres and on real meshes.
#include <gtest/gtest.h>

#include <fstream>
#include <iostream>
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

// Both traversals against brute force, and the CPU's SSE traversal (bvh/cpu_bvh.h) against the
// shared one it must reproduce bit for bit: the same primitive, t and barycentrics, also when
// the nearest primitive is skipped (as the integrator skips a shadow ray's light).
void check_against_brute_force(const Scene& scene, int rays, const std::string& what) {
  const CompiledScene cs(scene, 16, 16);
  const Aabb box = scene_bounds(cs);
  SceneView shared = cs.view();
  shared.cpu_bvh = CpuBvhView();
  check_view(shared, box.lo, box.hi, rays, what + " (shared traversal)");
  // The 8-wide compressed tree the GPU walks, through the same shared traversal.
  ASSERT_FALSE(cs.bvh8().nodes.empty() && !scene.mesh.indices.empty()) << what << ": no 8-wide tree";
  if (!cs.bvh8().nodes.empty()) {
    SceneView wide8 = shared;
    wide8.nodes8 = cs.bvh8().nodes.data();
    wide8.prim_indices8 = cs.bvh8().prim_indices.data();
    wide8.node_count = uint32_t(cs.bvh8().nodes.size());
    check_view(wide8, box.lo, box.hi, rays, what + " (8-wide traversal)");
    EXPECT_LE(cs.bvh8().stats.max_stack, uint32_t(kBvhStackSize)) << what;
    EXPECT_EQ(cs.bvh8().prim_indices.size(), cs.prim_indices().size()) << what;
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

}  // namespace
