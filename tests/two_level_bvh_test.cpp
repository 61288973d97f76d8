// The BVH's second level: instanced meshes traced through their instances must give the hits,
// surface points, normals and images of the same scene flattened into world-space triangles.
#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>
#include <random>

#include "integrator/renderer.h"
#include "scene/compiled_scene.h"
#include "scene_builders.h"

namespace tracer {
namespace {
using namespace test;

Scene flattened(Scene s) {
  flatten_instances(s);
  return s;
}

// The flattened scene's triangle for instanced hit id `prim` (instances in order, each its mesh's
// triangles in order, appended after the scene's own triangles).
uint32_t flat_triangle_of(const Scene& s, const SceneView& v, uint32_t prim) {
  uint64_t id = uint64_t(v.tri_count) + v.sphere_count, tri = v.tri_count;
  for (const MeshInstance& in : s.instances) {
    const uint64_t n = s.instanced_meshes[in.mesh].mesh.indices.size();
    if (prim < id + n) return uint32_t(tri + (prim - id));
    id += n;
    tri += n;
  }
  return kInvalid;
}

TEST(TwoLevelBvh, HitsMatchTheFlattenedScene) {
  const Scene inst = instanced_scene();
  const Scene flat = flattened(inst);
  ASSERT_EQ(flat.instances.size(), 0u);
  ASSERT_EQ(flat.mesh.indices.size(), inst.mesh.indices.size() + inst.instanced_triangle_count());
  const CompiledScene a(inst, 64, 64), b(flat, 64, 64);
  const SceneView &va = a.view(), &vb = b.view();
  EXPECT_TRUE(va.features & kFeatureInstances);
  EXPECT_FALSE(vb.features & kFeatureInstances);
  EXPECT_EQ(a.instances().size(), inst.instances.size() - 1);  // the empty mesh's is left out
  EXPECT_EQ(a.inst_tri_verts().size(), inst.instanced_meshes[0].mesh.indices.size() +
                                           inst.instanced_meshes[1].mesh.indices.size());

  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  int hits = 0, instanced = 0, mismatched = 0, blocked_mismatch = 0;
  constexpr int kRays = 20000;
  for (int i = 0; i < kRays; ++i) {
    Ray r;
    r.o = vec3(3.5f * u(rng), 2.0f + 2.5f * u(rng), 3.5f * u(rng));
    r.d = glm::normalize(vec3(u(rng), u(rng), u(rng)));
    r.tmax = kInfinity;
    r.pad = 0.0f;
    const Hit ha = intersect_closest(va, r), hb = intersect_closest(vb, r);
    ASSERT_EQ(ha.valid(), hb.valid());  // inside a closed room
    ++hits;
    const bool is_inst = ha.prim >= va.tri_count + va.sphere_count;
    instanced += is_inst;
    const uint32_t expect = is_inst                  ? flat_triangle_of(inst, va, ha.prim)
                            : ha.prim < va.tri_count ? ha.prim
                                                     : vb.tri_count + (ha.prim - va.tri_count);
    if (expect != hb.prim) {  // a ray through a shared edge may pick either neighbour
      ++mismatched;
      EXPECT_NEAR(ha.t, hb.t, 1e-4f * hb.t);
      continue;
    }
    // Distances differ by the rounding of the instance's map (a few ulps of the coordinates).
    EXPECT_NEAR(ha.t, hb.t, 2e-5f * hb.t + 1e-5f);
    const SurfaceHit sa = make_surface_hit(va, r, ha), sb = make_surface_hit(vb, r, hb);
    EXPECT_LT(glm::length(sa.p - sb.p), 1e-4f * (1.0f + glm::length(sb.p)));
    EXPECT_GT(glm::dot(sa.ng, sb.ng), 0.9999f) << "ray " << i;
    EXPECT_GT(glm::dot(sa.ns, sb.ns), 0.999f) << "ray " << i;
    EXPECT_EQ(sa.front, sb.front);
    EXPECT_EQ(sa.material, sb.material);
    EXPECT_EQ(sa.light, sb.light);
    // Any-hit queries agree along a shortened ray, and a ray leaving the hit triangle with
    // its id skipped does not find it again.
    Ray half = r;
    half.tmax = 0.999f * ha.t;
    blocked_mismatch += intersect_any(va, half, kInvalid) != intersect_any(vb, half, kInvalid);
    Ray back;
    back.o = sa.p;
    back.d = -r.d;
    back.tmax = 0.5f * ha.t;
    back.pad = 0.0f;
    EXPECT_NE(intersect_closest(va, back, ha.prim).prim, ha.prim);
  }
  EXPECT_EQ(hits, kRays);
  EXPECT_GT(instanced, kRays / 20);
  EXPECT_LE(mismatched, kRays / 1000);
  EXPECT_LE(blocked_mismatch, kRays / 1000);
}

// Instances that place few triangles are written out after loading (with a note), since
// world-space triangles trace faster; the image is the same.
TEST(TwoLevelBvh, SmallInstancesAreWrittenOut) {
  Scene s = instanced_scene();
  const uint64_t placed = s.instanced_triangle_count();
  const size_t before = s.mesh.indices.size(), count = s.instances.size();
  ASSERT_LT(placed, kKeepInstancesFrom);
  EXPECT_TRUE(flatten_small_instances(s));
  EXPECT_TRUE(s.instances.empty());
  EXPECT_EQ(s.mesh.indices.size(), before + placed);
  ASSERT_EQ(s.diagnostics.notes.size(), 1u);
  EXPECT_NE(s.diagnostics.notes[0].find(std::to_string(count) + " instances written out as " +
                                       std::to_string(placed) + " triangles"),
            std::string::npos)
      << s.diagnostics.notes[0];
  EXPECT_FALSE(flatten_small_instances(s));  // nothing left to write out
}

TEST(TwoLevelBvh, ImagesMatchTheFlattenedScene) {
  const Scene inst = instanced_scene();
  RenderSettings rs;
  rs.width = rs.height = 24;
  rs.max_depth = 5;
  const PixelStats a = render_pixel_stats(inst, rs, 96);
  const PixelStats b = render_pixel_stats(flattened(inst), rs, 96, 1u << 20);
  EXPECT_EQ(a.nonfinite, 0u);
  expect_same_means(a, b, "instanced vs flattened");
}

// A hundred million triangles by instances: one mesh stored once, a thousand placements; the
// compiled scene holds one copy of the triangles and a thousand-entry first level.
TEST(TwoLevelBvh, AHundredMillionInstancedTrianglesStayOneMesh) {
  Scene s;
  const uint32_t white = s.add_material("white", diffuse(vec3(0.7f)));
  s.add_material("light", diffuse(vec3(0.0f), vec3(5.0f)));
  add_quad(s.mesh, vec3(-1.0f, 100.0f, -1.0f), vec3(0.0f, 0.0f, 2.0f), vec3(2.0f, 0.0f, 0.0f), 1);
  InstancedMesh tile{"tile", {}};
  add_grid_box(tile.mesh, vec3(0.0f), vec3(0.9f, 0.1f, 0.9f), 129, white);  // 199,692 triangles
  s.instanced_meshes.push_back(tile);
  for (int z = 0; z < 25; ++z)
    for (int x = 0; x < 21; ++x)
      s.instances.push_back({0, glm::translate(glm::mat4(1.0f), vec3(float(x), 0.0f, float(z)))});
  ASSERT_GE(s.instanced_triangle_count(), 100000000u);
  EXPECT_FALSE(flatten_small_instances(s));  // far above kKeepInstancesFrom: kept
  EXPECT_EQ(s.instances.size(), 525u);
  const CompiledScene cs(s, 32, 32);
  EXPECT_EQ(cs.inst_tri_verts().size(), tile.mesh.indices.size());
  EXPECT_EQ(cs.instances().size(), s.instances.size());
  // The last instance's last triangle has the largest id.
  const SceneView& v = cs.view();
  Ray r;
  r.o = vec3(20.5f, 5.0f, 24.5f);
  r.d = vec3(0.0f, -1.0f, 0.0f);
  r.tmax = kInfinity;
  r.pad = 0.0f;
  const Hit h = intersect_closest(v, r);
  ASSERT_TRUE(h.valid());
  EXPECT_NEAR(h.t, 4.9f, 1e-5f);
  EXPECT_GE(h.prim, v.instances[v.instance_count - 1].prim_base);
  const SurfaceHit sh = make_surface_hit(v, r, h);
  EXPECT_NEAR(sh.p.y, 0.1f, 1e-5f);
  EXPECT_GT(sh.ng.y, 0.9999f);
  EXPECT_TRUE(intersect_any(v, r, kInvalid));
}

}  // namespace
}  // namespace tracer
