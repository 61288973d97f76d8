// Watertightness of the ray-triangle test (Woop et al. 2013): rays aimed exactly at the shared
// edges and vertices of closed meshes must never slip through.
#include <gtest/gtest.h>

#include <random>

#include "scene_builders.h"

namespace {
using namespace test;

// Aims rays from far outside at `target` (a point on a shared edge or vertex) and from the inside
// outward through it; each must hit the mesh.
int count_leaks(const CompiledScene& cs, vec3 centre, float scale,
                const std::vector<vec3>& targets, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  int leaks = 0;
  for (const vec3& t : targets) {
    for (int k = 0; k < 8; ++k) {
      // From outside: start beyond the target, jittered, aimed exactly at it.
      const vec3 dir_out = glm::normalize(t - centre + 0.3f * scale * vec3(u(rng), u(rng), u(rng)));
      Ray r;
      r.o = t + 7.3f * scale * dir_out;
      r.d = glm::normalize(t - r.o);
      r.tmax = kInfinity;
      r.pad = 0;
      if (!intersect_closest(cs.view(), r).valid()) ++leaks;
      // From inside through the same point.
      Ray q;
      q.o = centre + 0.01f * scale * vec3(u(rng), u(rng), u(rng));
      q.d = glm::normalize(t - q.o);
      q.tmax = kInfinity;
      q.pad = 0;
      if (!intersect_closest(cs.view(), q).valid()) ++leaks;
    }
  }
  return leaks;
}

std::vector<vec3> edge_and_vertex_targets(const TriangleMesh& m) {
  std::vector<vec3> t;
  for (const auto& tri : m.indices) {
    const vec3 a = m.positions[tri.x], b = m.positions[tri.y], c = m.positions[tri.z];
    t.insert(t.end(), {a, 0.5f * (a + b), 0.5f * (b + c), 0.5f * (c + a), 0.3f * a + 0.7f * b});
  }
  return t;
}

TEST(Watertight, IcosphereEdgesAndVertices) {
  for (float scale : {1e-3f, 1.0f, 1e3f}) {
    Scene s;
    s.materials.push_back({"m", diffuse(vec3(0.5f))});
    const vec3 centre = vec3(0.3f, -0.2f, 0.1f) * scale;
    add_icosphere(s.mesh, centre, 1.3f * scale, 3, 0);
    const CompiledScene cs(s, 4, 4);
    std::mt19937 rng(42);
    EXPECT_EQ(count_leaks(cs, centre, scale, edge_and_vertex_targets(s.mesh), rng), 0)
        << "scale " << scale;
  }
}

TEST(Watertight, BoxCornersAndEdges) {
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  add_box(s.mesh, vec3(-1.0f, -2.0f, -0.5f), vec3(1.5f, 1.0f, 2.0f), 0);
  const CompiledScene cs(s, 4, 4);
  std::mt19937 rng(3);
  EXPECT_EQ(
      count_leaks(cs, vec3(0.25f, -0.5f, 0.75f), 1.0f, edge_and_vertex_targets(s.mesh), rng), 0);
}

TEST(Watertight, AxisAlignedRaysThroughSharedEdge) {
  // The classic failure case: a ray exactly along a coordinate axis through the diagonal edge of a
  // quad, where a non-watertight test can miss both triangles.
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  add_quad(s.mesh, vec3(-1.0f, -1.0f, 0.0f), vec3(2.0f, 0.0f, 0.0f), vec3(0.0f, 2.0f, 0.0f), 0);
  const CompiledScene cs(s, 4, 4);
  int leaks = 0;
  for (int i = 0; i <= 1000; ++i) {
    const float a = -1.0f + 2.0f * float(i) / 1000.0f;  // points on the diagonal x = y
    Ray r{vec3(a, a, 5.0f), kInfinity, vec3(0.0f, 0.0f, -1.0f), 0.0f};
    if (!intersect_closest(cs.view(), r).valid()) {
      ++leaks;
      ADD_FAILURE() << "ray through (" << a << ", " << a << ") slipped through";
    }
  }
  EXPECT_EQ(leaks, 0);
}

}  // namespace
