// Ray-origin offsets (Wächter & Binder 2019) must hold at every scene scale and far from the
// origin: a ray leaving a surface never re-hits it, and a shadow ray towards a visible light is
// never blocked by the surfaces at its two ends.
#include <gtest/gtest.h>

#include <random>

#include "scene_builders.h"

namespace {
using namespace test;

struct Case {
  float scale;
  vec3 offset;
};

std::vector<Case> cases() {
  std::vector<Case> c;
  for (float s : {1e-3f, 1e-2f, 1e-1f, 1.0f, 1e1f, 1e2f, 1e3f, 1e4f}) c.push_back({s, vec3(0.0f)});
  for (float s : {1.0f, 1e1f, 1e2f}) c.push_back({s, vec3(1e4f, -1e4f, 1e4f)});
  return c;
}

vec3 hemisphere_dir(std::mt19937& rng, vec3 n) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const vec3 local = sample_cosine_hemisphere(vec2(u(rng), u(rng)));
  return glm::normalize(Frame::from_normal(n).to_world(local));
}

TEST(RayOffset, NoSelfIntersectionOnPlanesAndSpheres) {
  for (const Case& c : cases()) {
    Scene s;
    s.materials.push_back({"m", diffuse(vec3(0.5f))});
    const float k = c.scale;
    add_quad(s.mesh, c.offset + k * vec3(-1, 0, -1), k * vec3(0, 0, 2), k * vec3(2, 0, 0), 0);
    s.spheres.push_back({c.offset + k * vec3(0.3f, 0.5f, 0.2f), 0.4f * k, 0});
    const CompiledScene cs(s, 4, 4);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    int self_hits = 0, tested = 0;
    for (int i = 0; i < 4000; ++i) {
      Ray r;
      r.o = c.offset + k * vec3(u(rng) * 0.9f, 2.0f, u(rng) * 0.9f);
      r.d = glm::normalize(c.offset + k * vec3(u(rng) * 0.9f, 0.0f, u(rng) * 0.9f) - r.o);
      r.tmax = kInfinity;
      r.pad = 0;
      const Hit h = intersect_closest(cs.view(), r);
      if (!h.valid()) continue;
      const SurfaceHit sh = make_surface_hit(cs.view(), r, h);
      const vec3 n = sh.front ? sh.ng : -sh.ng;
      // Leave on the viewer's side: nothing of the same surface may be hit again.
      const Ray out = spawn_ray(sh.p, sh.ng, hemisphere_dir(rng, n));
      const Hit h2 = intersect_closest(cs.view(), out);
      const bool on_floor = h.prim < 2, again_floor = h2.valid() && h2.prim < 2;
      if ((on_floor && again_floor) || (!on_floor && h2.prim == h.prim)) ++self_hits;
      // Grazing directions are the hardest case for offsets.
      vec3 t = glm::normalize(glm::cross(n, vec3(0.3f, 0.1f, 0.9f)));
      const Ray graze = spawn_ray(sh.p, sh.ng, glm::normalize(t + 1e-3f * n));
      const Hit h3 = intersect_closest(cs.view(), graze);
      if (on_floor && h3.valid() && h3.prim < 2) ++self_hits;
      ++tested;
    }
    EXPECT_GT(tested, 1000);
    EXPECT_EQ(self_hits, 0) << "scale " << c.scale << " offset " << c.offset.x;
  }
}

// smallpt's walls: spheres of radius 1e5 whose near surface is a few units from the origin. The
// hit must land on the surface (in float it cancelled to 0.01 units off) and a ray leaving it
// must not hit it again, or the walls show self-shadowing bands.
TEST(RayOffset, HugeSphereWallsAsInSmallpt) {
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  const vec3 centers[] = {{100001.0f, 40.8f, 81.6f}, {-99901.0f, 40.8f, 81.6f},
                          {50.0f, 40.8f, 100000.0f}, {50.0f, 100000.0f, 81.6f},
                          {50.0f, -99918.4f, 81.6f}};
  for (vec3 c : centers) s.spheres.push_back({c, 1e5f, 0});
  const CompiledScene cs(s, 4, 4);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  int self_hits = 0, tested = 0;
  double worst = 0.0;
  for (int i = 0; i < 20000; ++i) {
    Ray r;
    r.o = vec3(10.0f + 80.0f * u(rng), 5.0f + 70.0f * u(rng), 10.0f + 140.0f * u(rng));
    r.d = sample_uniform_sphere(vec2(u(rng), u(rng)));
    r.tmax = kInfinity;
    r.pad = 0;
    const Hit h = intersect_closest(cs.view(), r);
    if (!h.valid()) continue;  // out through the open front
    const SurfaceHit sh = make_surface_hit(cs.view(), r, h);
    const SphereDesc& sp = s.spheres[h.prim];  // no triangles: prim is the sphere index
    const glm::dvec3 e = glm::dvec3(sh.p) - glm::dvec3(sp.center);
    worst = std::max(worst, std::abs(glm::length(e) - 1e5));  // distance off the surface
    const vec3 n = sh.front ? sh.ng : -sh.ng;
    const Hit h2 = intersect_closest(cs.view(), spawn_ray(sh.p, sh.ng, hemisphere_dir(rng, n)));
    if (h2.valid() && h2.prim == h.prim) ++self_hits;
    ++tested;
  }
  EXPECT_GT(tested, 15000);
  EXPECT_EQ(self_hits, 0);
  EXPECT_LT(worst, 2e-3) << "hit points off the wall surface";
}

TEST(RayOffset, RaysInsideSpheresReachTheFarSide) {
  for (const Case& c : cases()) {
    Scene s;
    s.materials.push_back({"m", diffuse(vec3(0.5f))});
    const float radius = c.scale;
    s.spheres.push_back({c.offset, radius, 0});
    const CompiledScene cs(s, 4, 4);
    std::mt19937 rng(5);
    int bad = 0;
    for (int i = 0; i < 2000; ++i) {
      const vec3 d0 = sample_uniform_sphere(vec2(std::uniform_real_distribution<float>()(rng),
                                                 std::uniform_real_distribution<float>()(rng)));
      Ray r{c.offset, kInfinity, d0, 0.0f};
      const Hit h = intersect_closest(cs.view(), r);
      ASSERT_TRUE(h.valid());
      const SurfaceHit sh = make_surface_hit(cs.view(), r, h);
      // Reflect back inside: the next hit is the far side, a chord away, never the same spot.
      const Ray in = spawn_ray(sh.p, sh.ng, hemisphere_dir(rng, -sh.ng));
      const Hit h2 = intersect_closest(cs.view(), in);
      if (!h2.valid() || h2.t < 1e-3f * radius) ++bad;
    }
    EXPECT_EQ(bad, 0) << "scale " << c.scale << " offset " << c.offset.x;
  }
}

TEST(RayOffset, NoFalseShadowing) {
  for (const Case& c : cases()) {
    Scene s;
    s.materials.push_back({"m", diffuse(vec3(0.5f))});
    s.materials.push_back({"light", diffuse(vec3(0.0f), vec3(1.0f))});
    const float k = c.scale;
    add_quad(s.mesh, c.offset + k * vec3(-1, 0, -1), k * vec3(0, 0, 2), k * vec3(2, 0, 0), 0);
    // A light quad above, facing down.
    add_quad(s.mesh, c.offset + k * vec3(-0.2f, 1.5f, -0.2f), k * vec3(0.4f, 0, 0),
             k * vec3(0, 0, 0.4f), 1);
    // A sphere far to the side whose top also sees the light.
    s.spheres.push_back({c.offset + k * vec3(0.0f, 0.3f, 0.0f), 0.05f * k, 0});
    const CompiledScene cs(s, 4, 4);
    const SceneView& v = cs.view();
    ASSERT_EQ(v.light_count, 2u);
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    int blocked = 0;
    for (int i = 0; i < 4000; ++i) {
      // A point on the floor outside the sphere's shadow, or on the sphere's top cap.
      vec3 p, n;
      if (i % 2 == 0) {
        const vec3 q = k * vec3(0.5f + 0.45f * u(rng), 0.0f, -0.9f + 1.8f * u(rng));
        Ray r{c.offset + q + vec3(0.0f, k, 0.0f), kInfinity, vec3(0, -1, 0), 0.0f};
        const Hit h = intersect_closest(v, r);
        ASSERT_TRUE(h.valid());
        const SurfaceHit sh = make_surface_hit(v, r, h);
        p = sh.p;
        n = sh.front ? sh.ng : -sh.ng;
      } else {
        const vec3 top = glm::normalize(vec3(0.1f * (u(rng) - 0.5f), 1.0f, 0.1f * (u(rng) - 0.5f)));
        Ray r{s.spheres[0].center + 3.0f * k * 0.05f * top, kInfinity, -top, 0.0f};
        const Hit h = intersect_closest(v, r);
        ASSERT_TRUE(h.valid());
        const SurfaceHit sh = make_surface_hit(v, r, h);
        p = sh.p;
        n = sh.ng;
      }
      const LightSample ls = sample_light(v, p, n, u(rng), vec2(u(rng), u(rng)));
      ASSERT_TRUE(ls.valid);
      const Ray shadow = spawn_ray_to(p, n, ls.p, ls.n);
      if (intersect_any(v, shadow, ls.prim)) ++blocked;
    }
    EXPECT_EQ(blocked, 0) << "scale " << c.scale << " offset " << c.offset.x;
  }
}

}  // namespace
