// Numerical stress suite (ctest labels `cpu` and `stress`): ray offsets at extreme (offset, scale)
// pairs, a scene far from the origin renders like the original, needle and sliver triangles stay
// watertight, and degenerate parameters (IOR 1 and 4, albedo 0 and 1, zero aperture, tiny lights,
// huge and tiny emission, grazing angles) never produce NaN or Inf.
#include <gtest/gtest.h>

#include <random>

#include "scene/loader.h"
#include "scene_builders.h"

namespace {
using namespace test;

// Offsets: spawn rays off planes and spheres at (offset, scale); nothing may re-hit its surface
// and shadow rays to a visible light may not be blocked.
TEST(Stress, RayOffsetsAtExtremeOffsetsAndScales) {
  const struct {
    float offset, scale;
  } cases[] = {{0.0f, 1.0f}, {1e3f, 1.0f}, {0.0f, 1e-3f}, {1e4f, 1e3f}};
  for (const auto& c : cases) {
    Scene s;
    s.materials.push_back({"m", diffuse(vec3(0.5f))});
    s.materials.push_back({"light", diffuse(vec3(0.0f), vec3(1.0f))});
    const vec3 o(c.offset, -0.5f * c.offset, 0.25f * c.offset);
    const float k = c.scale;
    add_quad(s.mesh, o + k * vec3(-1, 0, -1), k * vec3(0, 0, 2), k * vec3(2, 0, 0), 0);
    add_quad(s.mesh, o + k * vec3(-0.2f, 1.5f, -0.2f), k * vec3(0.4f, 0, 0), k * vec3(0, 0, 0.4f), 1);
    const CompiledScene cs(s, 4, 4);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    int self = 0, blocked = 0;
    for (int i = 0; i < 3000; ++i) {
      Ray r{o + k * vec3(1.8f * u(rng) - 0.9f, 1.0f, 1.8f * u(rng) - 0.9f), kInfinity,
            vec3(0, -1, 0), 0.0f};
      const Hit h = intersect_closest(cs.view(), r);
      ASSERT_TRUE(h.valid());
      const SurfaceHit sh = make_surface_hit(cs.view(), r, h);
      const vec3 n = sh.front ? sh.ng : -sh.ng;
      const vec3 d = glm::normalize(
          Frame::from_normal(n).to_world(sample_cosine_hemisphere(vec2(u(rng), u(rng)))));
      const Hit h2 = intersect_closest(cs.view(), spawn_ray(sh.p, sh.ng, d));
      if (h2.valid() && h2.prim < 2) ++self;
      const LightSample ls = sample_light(cs.view(), sh.p, n, u(rng), vec2(u(rng), u(rng)));
      if (ls.valid && intersect_any(cs.view(), spawn_ray_to(sh.p, n, ls.p, ls.n), ls.prim)) ++blocked;
    }
    EXPECT_EQ(self, 0) << "offset " << c.offset << " scale " << c.scale;
    EXPECT_EQ(blocked, 0) << "offset " << c.offset << " scale " << c.scale;
  }
}

// The Cornell box moved 1e5 from the origin (in its own units, mm) renders with the same error.
TEST(Stress, SceneFarFromTheOriginRendersTheSame) {
  const Scene base = builtin_default_scene();
  Scene far = base;
  const vec3 shift(1e5f, -1e5f, 1e5f);
  for (auto& p : far.mesh.positions) p += shift;
  far.camera.position += shift;
  far.camera.look_at += shift;
  RenderSettings rs = base.settings;
  rs.width = rs.height = 24;
  const PixelStats a = render_pixel_stats(base, rs, 512);
  const PixelStats b = render_pixel_stats(far, rs, 512, 1u << 22);
  EXPECT_EQ(a.nonfinite + b.nonfinite, 0u);
  // Image means agree within their standard errors (4 sigma) per channel.
  for (int c = 0; c < 3; ++c) {
    double ma = 0, mb = 0, va = 0, vb = 0;
    for (size_t i = 0; i < a.mean.size(); ++i) {
      ma += a.mean[i][c];
      mb += b.mean[i][c];
      va += a.var[i][c] / a.spp;
      vb += b.var[i][c] / b.spp;
    }
    const double n = double(a.mean.size());
    EXPECT_NEAR(ma / n, mb / n, 4.0 * std::sqrt((va + vb) / (n * n)) + 1e-4) << "channel " << c;
  }
}

// Needle and sliver triangles in a closed fan: rays through the shared vertex and edges hit.
TEST(Stress, NeedlesAndSliversAreWatertight) {
  Scene s;
  s.materials.push_back({"m", diffuse(vec3(0.5f))});
  // A fan of 2000 thin triangles around the origin in the z = 0 plane, closed over 360 degrees.
  const int n = 2000;
  const uint32_t centre = 0;
  s.mesh.positions.push_back(vec3(0.0f));
  for (int i = 0; i < n; ++i) {
    const float a = 2.0f * kPi * i / n;
    s.mesh.positions.push_back(vec3(std::cos(a), std::sin(a), 0.0f) * (i % 2 ? 1e3f : 1.0f));
  }
  for (int i = 0; i < n; ++i) {
    s.mesh.indices.push_back(uvec3(centre, 1 + i, 1 + (i + 1) % n));
    s.mesh.materials.push_back(0);
  }
  const CompiledScene cs(s, 4, 4);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  int leaks = 0;
  for (int i = 0; i < 20000; ++i) {
    // Aim at the centre vertex or at a point on a random shared edge.
    const int e = 1 + int((u(rng) * 0.5f + 0.5f) * (n - 1));
    const vec3 target = i % 2 ? vec3(0.0f) : s.mesh.positions[size_t(e)] * 0.37f;
    const vec3 from = vec3(u(rng), u(rng), 2.0f + u(rng));
    const Ray r{from, kInfinity, glm::normalize(target - from), 0.0f};
    if (!intersect_closest(cs.view(), r).valid()) ++leaks;
    const Ray axis{vec3(target.x, target.y, 5.0f), kInfinity, vec3(0, 0, -1), 0.0f};
    if (!intersect_closest(cs.view(), axis).valid()) ++leaks;  // axis-parallel
  }
  EXPECT_EQ(leaks, 0);
}

// Degenerate parameters must not produce NaN or Inf anywhere in the image.
TEST(Stress, DegenerateParametersStayFinite) {
  auto render = [](Scene s, const char* what) -> vec3 {
    RenderSettings rs;
    rs.width = rs.height = 16;
    const PixelStats ps = render_pixel_stats(s, rs, 64);
    EXPECT_EQ(ps.nonfinite, 0u) << what;
    int bad = 0;
    for (const vec3& m : ps.mean) bad += is_finite(m) ? 0 : 1;
    EXPECT_EQ(bad, 0) << what;
    return ps.image_mean();
  };
  Scene box = builtin_default_scene();
  for (float ior : {1.0f, 1.0001f, 4.0f}) {
    Scene s = box;
    Material glass;
    glass.type = MaterialType::kDielectric;
    glass.ior = ior;
    glass.albedo = vec3(1.0f);
    s.materials.push_back({"glass", glass});
    s.spheres.push_back({vec3(278, 120, 250), 100.0f, uint32_t(s.materials.size() - 1)});
    const vec3 m = render(s, ior > 2 ? "ior 4" : ior > 1.0f ? "ior 1.0001" : "ior 1");
    if (ior == 1.0f) {  // an index-matched sphere is invisible: the plain box's image
      const PixelStats plain = [&] {
        RenderSettings rs;
        rs.width = rs.height = 16;
        return render_pixel_stats(box, rs, 64);
      }();
      EXPECT_NEAR(m.x, plain.image_mean().x, 0.08f * plain.image_mean().x);
    }
  }
  {
    Scene s = box;  // albedo exactly 0 and exactly 1
    for (auto& m : s.materials)
      if (!m.material.is_emissive()) m.material.albedo = vec3(m.name == "white" ? 1.0f : 0.0f);
    render(s, "albedo 0 and 1");
  }
  {
    Scene s = box;  // a tiny light (1e-4 of the box) with huge emission, and a tiny emission
    for (auto& m : s.materials)
      if (m.material.is_emissive()) m.material.emission *= 1e12f;
    const vec3 bright = render(s, "huge emission");
    EXPECT_TRUE(is_finite(bright));
    for (auto& m : s.materials)
      if (m.material.is_emissive()) m.material.emission *= 1e-30f;
    render(s, "tiny emission");
  }
  {
    Scene s = box;  // a nearly zero-radius emitting sphere
    Material bulb = diffuse(vec3(0.0f), vec3(1e6f));
    s.materials.push_back({"bulb", bulb});
    s.spheres.push_back({vec3(278, 400, 278), 1e-4f, uint32_t(s.materials.size() - 1)});
    render(s, "zero-radius light");
  }
  {
    Scene s = box;  // zero aperture with a focus distance, and a rough dielectric at grazing view
    s.camera.aperture_radius = 0.0f;
    s.camera.focus_distance = 1.0f;
    Material frosted;
    frosted.type = MaterialType::kDielectric;
    frosted.roughness = 1.0f;
    frosted.albedo = vec3(1.0f);
    s.materials.push_back({"frosted", frosted});
    add_quad(s.mesh, vec3(0, 1, 0), vec3(555, 0, 0), vec3(0, 0.001f, 555), uint32_t(s.materials.size() - 1));
    render(s, "grazing rough dielectric");
  }
}

}  // namespace
