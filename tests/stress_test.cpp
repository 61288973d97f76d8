// Numerical stress suite (ctest labels `cpu` and `stress`): ray offsets at extreme (offset, scale)
// pairs, a scene far from the origin renders like the original, needle and sliver triangles stay
// watertight, and degenerate parameters (IOR 1 and 4, albedo 0 and 1, zero aperture, tiny lights,
// huge and tiny emission, grazing angles) never produce NaN or Inf.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>

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

namespace {
using namespace test;

// One scene of the magnitude sweep and what validate_scene must do with it.
struct MagnitudeCase {
  std::string name;
  Scene scene;
  const char* rejection = nullptr;  // a word of the error; null: the scene must render
};

// A scene lit by a small lamp, seen from (0, 0, -10), with what `add` puts in it.
template <typename Add>
Scene lamp_scene(Add add) {
  Scene s;
  s.source = "magnitudes";
  s.materials.push_back({"white", diffuse(vec3(0.7f))});
  s.materials.push_back({"light", diffuse(vec3(0.0f), vec3(4.0f))});
  s.camera.position = vec3(0, 0, -10);
  s.camera.look_at = vec3(0);
  s.settings.width = s.settings.height = 8;
  add(s);
  return s;
}

Scene scaled_cornell_box(float k) {
  Scene box = builtin_default_scene();
  for (vec3& p : box.mesh.positions) p *= k;
  box.camera.position *= k;
  box.camera.look_at *= k;
  box.settings.width = box.settings.height = 16;
  return box;
}

std::string num(float x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", double(x));
  return buf;
}

// Huge, tiny, denormal and mixed magnitudes. The bounds (scene/validate.cpp): nothing may reach
// past 1e12 from the origin (the triangle test's products of three coordinate differences would
// overflow), and a scene must span at least 64 ray offsets (or its rays skip its surfaces).
std::vector<MagnitudeCase> magnitude_cases() {
  std::vector<MagnitudeCase> out;
  const auto sphere = [](vec3 c, float r, uint32_t m) {
    return [=](Scene& s) { s.spheres.push_back({c, r, m}); };
  };
  const auto lamp = sphere(vec3(0, 3, 0), 0.5f, 1);
  for (float r : {1e6f, 1e11f, 1e13f, 1e19f, 2e38f, 3.4e38f}) {  // a sphere around the camera
    out.push_back({"enclosing sphere of radius " + num(r), lamp_scene([&](Scene& s) {
                     sphere(vec3(0), r, 0)(s);
                     lamp(s);
                   }),
                   r > 1e12f ? "supported 1e+12" : nullptr});
  }
  for (float r : {1e-19f, 1e-38f, 1e-44f}) {  // small, below FLT_MIN, denormal
    out.push_back({"sphere of radius " + num(r), lamp_scene([&](Scene& s) {
                     sphere(vec3(0), r, 0)(s);
                     lamp(s);
                   })});
    out.push_back({"lamp of radius " + num(r), lamp_scene([&](Scene& s) {
                     sphere(vec3(0), 1.0f, 0)(s);
                     sphere(vec3(0, 3, 0), r, 1)(s);
                   })});
    out.push_back({"quads of side " + num(2 * r), lamp_scene([&](Scene& s) {
                     add_quad(s.mesh, vec3(-r, -r, 0), vec3(0, 2 * r, 0), vec3(2 * r, 0, 0), 0);
                     add_quad(s.mesh, vec3(-r, 2, -r), vec3(2 * r, 0, 0), vec3(0, 0, 2 * r), 1);
                     lamp(s);
                   })});
  }
  for (float d : {1e11f, 1e20f, 1e30f}) {
    out.push_back({"sphere at " + num(d), lamp_scene([&](Scene& s) {
                     sphere(vec3(d, 0, 0), 1.0f, 0)(s);
                     lamp(s);
                   }),
                   d > 1e12f ? "supported 1e+12" : nullptr});
  }
  for (float k : {1e6f, 1e13f, 1e20f, 1.5e38f}) {
    out.push_back({"floor of half-side " + num(k), lamp_scene([&](Scene& s) {
                     add_quad(s.mesh, vec3(-k, -1, -k), vec3(0, 0, 2 * k), vec3(2 * k, 0, 0), 0);
                     lamp(s);
                   }),
                   k > 1e12f ? "supported 1e+12" : nullptr});
  }
  out.push_back({"mixed: 1e11 sky, 1e-30 speck", lamp_scene([&](Scene& s) {
                   sphere(vec3(0), 1e11f, 0)(s);
                   sphere(vec3(0.5f, 0, 0), 1e-30f, 0)(s);
                   lamp(s);
                 })});
  Scene far_camera = lamp_scene([&](Scene& s) { lamp(s); });
  far_camera.camera.position = vec3(1e15f, 0, -10);
  out.push_back({"camera at 1e15", far_camera, "the camera reaches 1e+15"});
  for (float k : {1e-3f, 1e-6f})
    out.push_back({"Cornell box scaled by " + num(k), scaled_cornell_box(k)});
  for (float k : {1e-8f, 1e-20f})
    out.push_back({"Cornell box scaled by " + num(k), scaled_cornell_box(k), "64 ray offsets"});
  return out;
}

// Every magnitude either renders without a non-finite sample or is rejected with the bound it
// breaks; a caller that skips validate_scene still gets a finite SAH cost and a render that
// neither crashes nor hangs (issue 20: a sphere of radius 2e38 crashed the CPU traversal and
// `info` printed "SAH cost -nan").
TEST(Stress, ExtremeMagnitudesRenderOrAreRejected) {
  for (const MagnitudeCase& c : magnitude_cases()) {
    SCOPED_TRACE(c.name);
    Scene s = c.scene;
    std::string error;
    try {
      validate_scene(s);
    } catch (const InputError& e) {
      error = e.what();
    }
    if (c.rejection) {
      EXPECT_NE(error.find(c.rejection), std::string::npos) << error;
    } else {
      EXPECT_EQ(error, "");
      const PixelStats ps = render_pixel_stats(s, s.settings, 16);
      EXPECT_EQ(ps.nonfinite, 0u);
      EXPECT_TRUE(is_finite(ps.image_mean()));
    }
    // Without validation (the unmodified scene, as an API caller may pass it).
    const CompiledScene cs(c.scene, 8, 8);
    EXPECT_TRUE(std::isfinite(cs.bvh_stats().sah_cost)) << cs.bvh_stats().sah_cost;
    render_pixel_stats(c.scene, c.scene.settings, 2);
  }
}

// The accepted end of the tiny range renders like the original: the Cornell box scaled by 1e-3
// and 1e-6 (its walls then 5.55e-4 across, 36 ray offsets near the origin) against the box at
// scale 1, image means within 4 standard errors per channel.
TEST(Stress, ScaledDownSceneRendersTheSame) {
  RenderSettings rs;
  rs.width = rs.height = 16;
  const PixelStats a = render_pixel_stats(scaled_cornell_box(1.0f), rs, 256);
  for (float k : {1e-3f, 1e-6f}) {
    SCOPED_TRACE(k);
    const PixelStats b = render_pixel_stats(scaled_cornell_box(k), rs, 256, 1u << 20);
    EXPECT_EQ(b.nonfinite, 0u);
    for (int ch = 0; ch < 3; ++ch) {
      double ma = 0, mb = 0, va = 0, vb = 0;
      for (size_t i = 0; i < a.mean.size(); ++i) {
        ma += a.mean[i][ch];
        mb += b.mean[i][ch];
        va += a.var[i][ch] / a.spp;
        vb += b.var[i][ch] / b.spp;
      }
      const double n = double(a.mean.size());
      EXPECT_NEAR(ma / n, mb / n, 4.0 * std::sqrt((va + vb) / (n * n)) + 1e-4) << "channel " << ch;
    }
  }
}

// The builder on any bounds a caller may hand it: empty, NaN, infinite, beyond the float range
// in extent, denormal, all in one place. Every primitive ends in exactly one leaf and the SAH
// cost is finite (the bins of a NaN centroid were int(NaN), an out-of-range index).
TEST(Stress, BvhBuilderTakesAnyBounds) {
  const std::vector<Aabb> boxes = degenerate_boxes(40, 40);
  const Bvh bvh = build_bvh(boxes);
  EXPECT_TRUE(std::isfinite(bvh.stats.sah_cost)) << bvh.stats.sah_cost;
  std::vector<int> seen(boxes.size(), 0);
  for (uint32_t e : bvh.prim_indices) seen[e & ~kBvhLastPrimBit]++;
  for (size_t i = 0; i < seen.size(); ++i) EXPECT_EQ(seen[i], 1) << "primitive " << i;
  EXPECT_LE(bvh.stats.max_stack, uint32_t(kBvhStackSize));
}

// Rays with a NaN or infinite origin or direction hit nothing in the BVH traversals, SSE and
// shared (the slab test ignores NaN, so such a ray entered every slot, empty ones included, and
// overflowed the traversal stack). The flat list has no stack to overrun: there such a ray only
// has to come back.
TEST(Stress, NonFiniteRaysHitNothing) {
  Scene s = builtin_default_scene();
  s.spheres.push_back({vec3(278, 100, 278), 50.0f, 0});
  const CompiledScene flat_scene(s, 4, 4);
  for (int i = 0; i < 200; ++i)  // enough triangles for a BVH of several levels
    add_quad(s.mesh, vec3(float(i), 10, 10), vec3(0.5f, 0, 0), vec3(0, 0.5f, 0), 0);
  const CompiledScene cs(s, 4, 4);
  const float inf = std::numeric_limits<float>::infinity(), nan = std::nanf("");
  const Ray rays[] = {{vec3(nan, 273, -800), kInfinity, vec3(0, 0, 1), 0.0f},
                      {vec3(278, 273, -800), kInfinity, vec3(nan), 0.0f},
                      {vec3(278, inf, -800), kInfinity, vec3(0, 0, 1), 0.0f},
                      {vec3(278, 273, -800), kInfinity, vec3(0, 0, inf), 0.0f}};
  SceneView simd = cs.view(), shared = cs.view(), flat = flat_scene.view();
  simd.use_flat = shared.use_flat = 0;
  shared.cpu_bvh = CpuBvhView();  // the traversal the GPU runs
  ASSERT_NE(simd.cpu_bvh.nodes, nullptr);
  flat.use_flat = 1;
  ASSERT_GT(flat.flat_count, 0u);
  for (const Ray& r : rays) {
    SCOPED_TRACE(testing::Message() << "ray " << &r - rays);
    for (const SceneView& v : {simd, shared}) {
      EXPECT_FALSE(intersect_closest(v, r).valid());
      EXPECT_FALSE(intersect_any(v, r, kInvalid));
    }
    intersect_closest(flat, r);
    intersect_any(flat, r, kInvalid);
  }
}

}  // namespace
