// Tests for tracer/core/sampling.h and the light sampling of tracer/integrator/lights.h: every
// warp is chi-square tested against its pdf (tests/chi_square.h), every pdf is checked against
// its closed form and integrates to one, and sample_light agrees with light_pdf.
#include "core/sampling.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "chi_square.h"
#include "core/math.h"
#include "integrator/lights.h"

namespace tracer {
namespace {

// Sidak correction over all chi-square tests in this executable.
constexpr double kSignificance = 0.01;
constexpr int kChiSquareTests = 14;
constexpr size_t kSamples = 1000000;

glm::dvec3 to_d(vec3 v) {
  return glm::dvec3(v);
}

using chi2::Uniform;

// ---------------------------------------------------------------------------------------------
// The harness itself: p-values against tabulated chi-square quantiles.

TEST(ChiSquareHarness, PValuesMatchTables) {
  EXPECT_NEAR(chi2::gamma_q(1.0, 2.5), std::exp(-2.5), 1e-12);
  EXPECT_NEAR(chi2::chi_square_p_value(3.841459, 1), 0.05, 1e-6);    // 95% quantile, 1 dof
  EXPECT_NEAR(chi2::chi_square_p_value(18.307038, 10), 0.05, 1e-6);  // 10 dof
  EXPECT_NEAR(chi2::chi_square_p_value(6.634897, 1), 0.01, 1e-6);
  EXPECT_NEAR(chi2::chi_square_p_value(1074.679, 1000), 0.05,
              1e-4);  // large dof, continued fraction
  EXPECT_NEAR(chi2::chi_square_p_value(932.3, 1000), 0.9386, 2e-3);  // series branch
  EXPECT_NEAR(chi2::sidak_alpha(0.01, 1), 0.01, 1e-15);
}

TEST(ChiSquareHarness, RejectsABiasedHistogramAndKeepsAFairOne) {
  std::mt19937 e(7);
  std::vector<double> fair(100, 0.0), biased(100, 0.0), expected(100, 10000.0);
  for (int i = 0; i < 1000000; ++i) {
    const float u = chi2::uniform_float(e);
    fair[int(u * 100)] += 1.0;
    biased[std::min(99, int(std::pow(u, 0.98f) * 100))] += 1.0;  // a 2% warp
  }
  EXPECT_TRUE(chi2::chi_square_test(fair, expected, 0.01, 1).passed);
  EXPECT_FALSE(chi2::chi_square_test(biased, expected, 0.01, 1).passed);
  // A sample where the pdf is zero fails regardless of the statistic.
  std::vector<double> obs = {10, 10, 1}, exp = {10.5, 10.5, 0};
  EXPECT_FALSE(chi2::chi_square_test(obs, exp, 0.01, 1).passed);
}

// ---------------------------------------------------------------------------------------------
// Direction warps.

TEST(SamplingTest, CosineHemisphereMatchesItsPdf) {
  // The pdf must be the closed form cos(theta)/pi, not merely agree with the sampler.
  for (float z : {0.0f, 0.1f, 0.5f, 0.9f, 1.0f})
    EXPECT_NEAR(cosine_hemisphere_pdf(z), z / M_PI, 1e-7) << "z = " << z;
  EXPECT_EQ(cosine_hemisphere_pdf(-0.3f), 0.0f);

  Uniform rng(1);
  bool all_unit_upper = true;
  auto sample = [&](glm::dvec3& w) {
    const vec3 v = sample_cosine_hemisphere(rng.f2());
    all_unit_upper &= std::abs(glm::length(v) - 1.0f) < 1e-5f && v.z >= 0.0f;
    w = to_d(v);
    return true;
  };
  auto pdf = [](glm::dvec3 w) { return double(cosine_hemisphere_pdf(float(w.z))); };
  const chi2::Result r = chi2::sphere_chi_square(sample, pdf, kSamples, chi2::SphereBins(),
                                                 kSignificance, kChiSquareTests);
  EXPECT_TRUE(r.passed) << r.message;
  EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
  EXPECT_TRUE(all_unit_upper);
}

TEST(SamplingTest, UniformSphereMatchesItsPdf) {
  EXPECT_NEAR(uniform_sphere_pdf(), 1.0 / (4.0 * M_PI), 1e-8);
  Uniform rng(2);
  bool all_unit = true;
  auto sample = [&](glm::dvec3& w) {
    const vec3 v = sample_uniform_sphere(rng.f2());
    all_unit &= std::abs(glm::length(v) - 1.0f) < 1e-5f;
    w = to_d(v);
    return true;
  };
  auto pdf = [](glm::dvec3) { return double(uniform_sphere_pdf()); };
  chi2::SphereBins bins;
  bins.basis = chi2::Basis(glm::dvec3(0.3, -0.5, 0.8));  // tilted cells, so poles are not special
  const chi2::Result r =
      chi2::sphere_chi_square(sample, pdf, kSamples, bins, kSignificance, kChiSquareTests);
  EXPECT_TRUE(r.passed) << r.message;
  EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
  EXPECT_TRUE(all_unit);
}

TEST(SamplingTest, UniformHemisphereMatchesItsPdf) {
  EXPECT_NEAR(uniform_hemisphere_pdf(), 1.0 / (2.0 * M_PI), 2e-8);
  Uniform rng(3);
  auto sample = [&](glm::dvec3& w) {
    w = to_d(sample_uniform_hemisphere(rng.f2()));
    return true;
  };
  auto pdf = [](glm::dvec3 w) { return w.z > 0.0 ? double(uniform_hemisphere_pdf()) : 0.0; };
  const chi2::Result r = chi2::sphere_chi_square(sample, pdf, kSamples, chi2::SphereBins(),
                                                 kSignificance, kChiSquareTests);
  EXPECT_TRUE(r.passed) << r.message;
  EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
}

TEST(SamplingTest, UniformConeMatchesItsPdf) {
  // From a very narrow cone (2.6 degrees, the size of a distant light) to one wider than a
  // hemisphere. The cells cover only the cone; directions outside it land in a cell whose
  // expected count is zero.
  uint32_t seed = 10;
  for (float cos_max : {0.999f, 0.9f, 0.3f, -0.5f}) {
    SCOPED_TRACE(testing::Message() << "cos_max = " << cos_max);
    EXPECT_NEAR(uniform_cone_pdf(cos_max), 1.0 / (2.0 * M_PI * (1.0 - double(cos_max))),
                1e-5 * uniform_cone_pdf(cos_max));
    Uniform rng(seed++);
    auto sample = [&](glm::dvec3& w) {
      w = to_d(sample_uniform_cone(rng.f2(), cos_max));
      return true;
    };
    auto pdf = [&](glm::dvec3 w) {
      return w.z >= double(cos_max) ? double(uniform_cone_pdf(cos_max)) : 0.0;
    };
    chi2::SphereBins bins;
    bins.z_lo = cos_max;
    const chi2::Result r =
        chi2::sphere_chi_square(sample, pdf, kSamples, bins, kSignificance, kChiSquareTests);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
  }
}

// ---------------------------------------------------------------------------------------------
// Planar warps.

TEST(SamplingTest, ConcentricDiskIsUniformOverTheDisk) {
  EXPECT_NEAR(uniform_disk_pdf(), 1.0 / M_PI, 4e-8);
  Uniform rng(20);
  auto sample = [&](glm::dvec2& p) {
    p = glm::dvec2(sample_uniform_disk_concentric(rng.f2()));
    return true;
  };
  auto pdf = [](glm::dvec2 p) { return glm::dot(p, p) <= 1.0 ? double(uniform_disk_pdf()) : 0.0; };
  chi2::PlaneBins bins;
  bins.x0 = bins.y0 = -1.0;
  bins.x1 = bins.y1 = 1.0;
  const chi2::Result r =
      chi2::plane_chi_square(sample, pdf, kSamples, bins, kSignificance, kChiSquareTests);
  EXPECT_TRUE(r.passed) << r.message;
  EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
  // The corners of the square map to the rim.
  EXPECT_NEAR(glm::length(sample_uniform_disk_concentric(vec2(0.0f, 0.0f))), 1.0f, 1e-6f);
  EXPECT_EQ(sample_uniform_disk_concentric(vec2(0.5f, 0.5f)), vec2(0.0f));
}

TEST(SamplingTest, UniformTriangleIsUniformByArea) {
  // A scalene triangle with no edge on the cell grid, sampled as lights.h does:
  // p = b0 v0 + b1 v1 + (1 - b0 - b1) v2.
  const glm::dvec2 v0(0.0, 0.0), v1(1.0, 0.2), v2(0.3, 0.9);
  const double area = 0.5 * std::abs((v1.x - v0.x) * (v2.y - v0.y) - (v2.x - v0.x) * (v1.y - v0.y));
  auto edge = [](glm::dvec2 a, glm::dvec2 b, glm::dvec2 p) {
    return (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
  };
  Uniform rng(21);
  bool barycentrics_valid = true;
  auto sample = [&](glm::dvec2& p) {
    const vec2 b = sample_uniform_triangle(rng.f2());
    barycentrics_valid &= b.x >= 0.0f && b.y >= 0.0f && b.x + b.y <= 1.0f + 1e-6f;
    p = double(b.x) * v0 + double(b.y) * v1 + (1.0 - double(b.x) - double(b.y)) * v2;
    return true;
  };
  auto pdf = [&](glm::dvec2 p) {
    const bool inside = edge(v0, v1, p) >= 0.0 && edge(v1, v2, p) >= 0.0 && edge(v2, v0, p) >= 0.0;
    return inside ? 1.0 / area : 0.0;
  };
  chi2::PlaneBins bins;
  bins.x0 = 0.0, bins.x1 = 1.0, bins.y0 = 0.0, bins.y1 = 0.9;
  const chi2::Result r =
      chi2::plane_chi_square(sample, pdf, kSamples, bins, kSignificance, kChiSquareTests);
  EXPECT_TRUE(r.passed) << r.message;
  EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
  EXPECT_TRUE(barycentrics_valid);
}

// ---------------------------------------------------------------------------------------------
// Power heuristic (Veach 1997, eq. 9.13 with beta = 2).

TEST(SamplingTest, PowerHeuristicValues) {
  EXPECT_FLOAT_EQ(power_heuristic(1.0f, 1.0f), 0.5f);
  EXPECT_FLOAT_EQ(power_heuristic(2.0f, 1.0f), 0.8f);
  EXPECT_FLOAT_EQ(power_heuristic(1.0f, 3.0f), 0.1f);
  EXPECT_FLOAT_EQ(power_heuristic(1.0f, 0.0f), 1.0f);
  EXPECT_EQ(power_heuristic(0.0f, 1.0f), 0.0f);
  EXPECT_EQ(power_heuristic(0.0f, 0.0f), 0.0f);  // no NaN when neither strategy can sample it
  EXPECT_EQ(power_heuristic(kInfinity, 1.0f), 1.0f);
  EXPECT_EQ(power_heuristic(1.0f, kInfinity), 0.0f);
  // The weights of two strategies sum to one and depend only on the ratio of the pdfs, across
  // the whole range where their squares stay finite, and also when only one square overflows.
  const float values[] = {1e-18f, 1e-6f, 0.01f, 0.3f, 1.0f, 7.0f, 1e3f, 1e9f, 1e18f, 1e25f};
  for (float a : values)
    for (float b : values) {
      if (a * a == kInfinity && b * b == kInfinity) continue;
      EXPECT_NEAR(power_heuristic(a, b) + power_heuristic(b, a), 1.0f, 1e-6f) << a << " " << b;
      const double r = double(b) / double(a);
      EXPECT_NEAR(power_heuristic(a, b), 1.0 / (1.0 + r * r), 1e-6) << a << " " << b;
    }
}

// ---------------------------------------------------------------------------------------------
// Frame::from_normal (Duff et al. 2017), which the sphere light sampling relies on.

TEST(SamplingTest, FrameIsOrthonormalAndRightHanded) {
  std::vector<vec3> normals = {vec3(0, 0, 1),
                               vec3(0, 0, -1),
                               vec3(1, 0, 0),
                               vec3(0, -1, 0),
                               glm::normalize(vec3(1e-4f, 0, -1)),
                               glm::normalize(vec3(0.3f, -0.2f, -0.9f))};
  Uniform rng(30);
  for (int i = 0; i < 1000; ++i) normals.push_back(sample_uniform_sphere(rng.f2()));
  for (vec3 n : normals) {
    const Frame f = Frame::from_normal(n);
    EXPECT_NEAR(glm::length(f.t), 1.0f, 1e-5f);
    EXPECT_NEAR(glm::length(f.b), 1.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(f.t, f.b), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(f.t, n), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(f.b, n), 0.0f, 1e-5f);
    EXPECT_LT(glm::length(glm::cross(f.t, f.b) - n), 1e-5f);
    const vec3 v(0.3f, -0.7f, 0.2f);
    EXPECT_LT(glm::length(f.to_local(f.to_world(v)) - v), 1e-5f);
    EXPECT_LT(glm::length(f.to_world(vec3(0, 0, 1)) - n), 1e-6f);
  }
}

// ---------------------------------------------------------------------------------------------
// Light sampling: a hand-built SceneView (no BVH; sampling does not trace rays).

struct LightScene {
  std::vector<TriangleVerts> tris;
  std::vector<TriangleShading> shading;
  std::vector<Sphere> spheres;
  std::vector<Material> materials;
  std::vector<Light> lights;
  std::vector<float> cdf;
  SceneView view;

  uint32_t material(vec3 emission, uint32_t flags = 0) {
    Material m;
    m.emission = emission;
    m.flags = flags;
    materials.push_back(m);
    return uint32_t(materials.size() - 1);
  }
  void triangle(vec3 a, vec3 b, vec3 c, uint32_t mat) {
    TriangleVerts t{};
    t.v0 = a;
    t.v1 = b;
    t.v2 = c;
    tris.push_back(t);
    TriangleShading s{};
    s.material = mat;
    s.light = kInvalid;
    shading.push_back(s);
  }
  void sphere(vec3 c, float r, uint32_t mat) {
    Sphere sp{};
    sp.center = c;
    sp.radius = r;
    sp.material = mat;
    sp.light = kInvalid;
    spheres.push_back(sp);
  }

  // Lights in primitive order (triangles, then spheres), chosen by luminance x area, as the host
  // scene compiler does; the test only needs the CDF to match the powers.
  void finish() {
    const uint32_t tri_count = uint32_t(tris.size());
    auto add = [&](uint32_t prim, float area, const Material& m) {
      lights.push_back({prim, area, luminance(m.emission) * area, 0});
      return uint32_t(lights.size() - 1);
    };
    for (uint32_t i = 0; i < tri_count; ++i) {
      const Material& m = materials[shading[i].material];
      if (!m.is_emissive()) continue;
      const TriangleVerts& t = tris[i];
      shading[i].light = add(i, 0.5f * glm::length(glm::cross(t.v1 - t.v0, t.v2 - t.v0)), m);
    }
    for (uint32_t i = 0; i < spheres.size(); ++i) {
      const Material& m = materials[spheres[i].material];
      if (!m.is_emissive()) continue;
      spheres[i].light = add(tri_count + i, 4.0f * kPi * spheres[i].radius * spheres[i].radius, m);
    }
    double total = 0.0;
    for (const Light& l : lights) total += l.power;
    cdf.assign(1, 0.0f);
    double acc = 0.0;
    for (const Light& l : lights) {
      acc += l.power;
      cdf.push_back(float(acc / total));
    }
    cdf.back() = 1.0f;
    view.tri_verts = tris.data();
    view.tri_shading = shading.data();
    view.spheres = spheres.data();
    view.materials = materials.data();
    view.lights = lights.data();
    view.light_cdf = cdf.data();
    view.tri_count = tri_count;
    view.sphere_count = uint32_t(spheres.size());
    view.material_count = uint32_t(materials.size());
    view.light_count = uint32_t(lights.size());
  }

  uint32_t light_of(uint32_t prim) const {
    return prim < tris.size() ? shading[prim].light : spheres[prim - tris.size()].light;
  }

  // Density of the direction of sample_light(ref) at w: every light the ray from ref crosses
  // contributes light_pdf at the point sample_light would have returned (the nearest crossing of
  // a sphere seen from outside, the only crossing from inside, the crossing of a triangle).
  double direction_pdf(vec3 ref, glm::dvec3 w) const {
    const glm::dvec3 o(ref);
    double sum = 0.0;
    for (uint32_t i = 0; i < tris.size(); ++i) {
      if (shading[i].light == kInvalid) continue;
      // Moeller-Trumbore in double.
      const glm::dvec3 a(tris[i].v0), b(tris[i].v1), c(tris[i].v2);
      const glm::dvec3 e1 = b - a, e2 = c - a, pv = glm::cross(w, e2);
      const double det = glm::dot(e1, pv);
      if (std::abs(det) < 1e-14) continue;
      const glm::dvec3 tv = o - a;
      const double u = glm::dot(tv, pv) / det;
      const glm::dvec3 qv = glm::cross(tv, e1);
      const double v = glm::dot(w, qv) / det, t = glm::dot(e2, qv) / det;
      if (u < 0.0 || v < 0.0 || u + v > 1.0 || t <= 0.0) continue;
      const vec3 ng = glm::normalize(glm::cross(tris[i].v1 - tris[i].v0, tris[i].v2 - tris[i].v0));
      sum += light_pdf(view, shading[i].light, light_select_pdf(view, shading[i].light), ref,
                       vec3(o + t * w), ng);
    }
    for (const Sphere& s : spheres) {
      if (s.light == kInvalid) continue;
      const glm::dvec3 f = o - glm::dvec3(s.center);
      const double bb = glm::dot(f, w), cc = glm::dot(f, f) - double(s.radius) * s.radius;
      const double disc = bb * bb - cc;
      if (disc < 0.0) continue;
      const double t0 = -bb - std::sqrt(disc), t1 = -bb + std::sqrt(disc);
      const double t = t0 > 0.0 ? t0 : t1;
      if (t <= 0.0) continue;
      const glm::dvec3 p = o + t * w;
      sum += light_pdf(view, s.light, light_select_pdf(view, s.light), ref, vec3(p),
                       vec3(glm::normalize(p - glm::dvec3(s.center))));
    }
    return sum;
  }
};

// Any unit normal at ref; away from every light's surface it only nudges ref by a few ulps.
const vec3 kRefNormal = glm::normalize(vec3(0.3f, 0.5f, -0.8f));

// Runs the direction chi-square of sample_light from ref, and checks every sample against
// light_pdf and its light's geometry. Returns the number of times each light was picked.
std::vector<double> check_light_sampling(const LightScene& sc, vec3 ref, vec3 ref_n,
                                         chi2::SphereBins bins, uint32_t seed) {
  Uniform rng(seed);
  std::vector<double> picked(sc.lights.size(), 0.0);
  int pdf_mismatch = 0, off_light = 0, invalid = 0;
  auto sample = [&](glm::dvec3& w) {
    const float u_pick = rng.f();
    const LightSample ls = sample_light(sc.view, ref, ref_n, u_pick, rng.f2());
    if (!ls.valid) {
      ++invalid;
      return false;
    }
    const uint32_t li = sc.light_of(ls.prim);
    picked[li] += 1.0;
    // The pdf sample_light reports is the one MIS will recompute when a BSDF ray hits ls.p.
    // (sample_light decides inside/outside from ref offset by a few ulps along ref_n, hence the
    // tolerance.)
    const float pdf = light_pdf(sc.view, li, light_select_pdf(sc.view, li), ref, ls.p, ls.n);
    if (!(std::abs(pdf - ls.pdf) <= 1e-4f * ls.pdf)) ++pdf_mismatch;
    if (ls.prim >= sc.tris.size()) {
      const Sphere& s = sc.spheres[ls.prim - sc.tris.size()];
      if (std::abs(glm::length(ls.p - s.center) - s.radius) > 1e-5f * s.radius) ++off_light;
    } else {
      const TriangleVerts& t = sc.tris[ls.prim];
      const vec3 n = glm::normalize(glm::cross(t.v1 - t.v0, t.v2 - t.v0));
      if (std::abs(glm::dot(ls.p - t.v0, n)) > 1e-5f || glm::length(ls.n - n) > 1e-5f) ++off_light;
    }
    w = glm::normalize(glm::dvec3(ls.p) - glm::dvec3(ref));
    return true;
  };
  auto pdf = [&](glm::dvec3 w) { return sc.direction_pdf(ref, w); };
  const chi2::Result r =
      chi2::sphere_chi_square(sample, pdf, kSamples, bins, kSignificance, kChiSquareTests);
  EXPECT_TRUE(r.passed) << r.message;
  EXPECT_NEAR(r.pdf_integral, 1.0, 2e-3);
  EXPECT_EQ(pdf_mismatch, 0);
  EXPECT_EQ(off_light, 0);
  EXPECT_EQ(invalid, 0);
  return picked;
}

TEST(LightSamplingTest, SphereFromOutsideSamplesTheSubtendedCone) {
  for (float distance : {2.5f, 30.0f}) {  // 23 degrees; 0.95 degrees (the Taylor branch)
    SCOPED_TRACE(testing::Message() << "distance = " << distance);
    LightScene sc;
    const vec3 ref(0.2f, -0.1f, 0.4f);
    const vec3 c = ref + distance * glm::normalize(vec3(0.3f, -0.4f, 1.0f));
    sc.sphere(c, distance > 10.0f ? 0.5f : 1.0f, sc.material(vec3(2.0f)));
    sc.finish();
    const Sphere& s = sc.spheres[0];
    const double d = glm::length(glm::dvec3(c) - glm::dvec3(ref));
    chi2::SphereBins bins;
    bins.basis = chi2::Basis(glm::dvec3(c) - glm::dvec3(ref));
    bins.z_lo = std::sqrt(1.0 - double(s.radius) * s.radius / (d * d));
    check_light_sampling(sc, ref, kRefNormal, bins, distance > 10.0f ? 41 : 40);
    // Every sample is on the near side, facing ref, and emits towards it.
    Uniform rng(42);
    for (int i = 0; i < 10000; ++i) {
      const LightSample ls = sample_light(sc.view, ref, kRefNormal, rng.f(), rng.f2());
      ASSERT_TRUE(ls.valid);
      EXPECT_GT(glm::dot(ls.n, ref - ls.p), -1e-4f);
      EXPECT_EQ(ls.le, vec3(2.0f));
    }
  }
}

TEST(LightSamplingTest, SphereFromInsideSamplesItsArea) {
  LightScene sc;
  const vec3 c(1.0f, -0.5f, 0.25f);
  sc.sphere(c, 2.0f, sc.material(vec3(1.5f), kMaterialTwoSidedEmission));
  sc.finish();
  const vec3 ref = c + vec3(0.5f, -0.8f, 1.1f);  // off centre, so the density is not uniform
  chi2::SphereBins bins;
  bins.basis = chi2::Basis(glm::dvec3(0.2, 0.9, -0.1));
  check_light_sampling(sc, ref, kRefNormal, bins, 43);
  Uniform rng(44);
  for (int i = 0; i < 1000; ++i) {
    const LightSample ls = sample_light(sc.view, ref, kRefNormal, rng.f(), rng.f2());
    ASSERT_TRUE(ls.valid);
    EXPECT_LT(glm::dot(ls.n, ref - ls.p), 0.0f);  // the inside (back) face is what ref sees
    EXPECT_EQ(ls.le, vec3(1.5f));
  }
}

TEST(LightSamplingTest, SphereSeenFromItsOwnInnerSurfaceIsCosineDistributed) {
  // From a point on the inside of a sphere, a uniformly chosen point of the sphere lies in a
  // cosine-weighted direction about the inward normal: d = 2 r cos, so d^2 / (cos A) = cos / pi.
  LightScene sc;
  const vec3 c(0.5f, 0.25f, -1.0f);
  const float radius = 3.0f;
  sc.sphere(c, radius, sc.material(vec3(1.0f), kMaterialTwoSidedEmission));
  sc.finish();
  const vec3 n = glm::normalize(vec3(0.2f, -0.6f, 0.7f));
  const vec3 ref = c + radius * n;
  for (vec3 ref_n : {n, -n}) {  // either orientation of the normal at ref
    Uniform rng(45);
    int bad = 0;
    for (int i = 0; i < 10000; ++i) {
      const LightSample ls = sample_light(sc.view, ref, ref_n, rng.f(), rng.f2());
      if (!ls.valid) continue;  // a point at ref itself
      const vec3 w = glm::normalize(ls.p - ref);
      const float cos_in = glm::dot(w, -n);
      if (!(cos_in > -1e-3f) || std::abs(ls.pdf - cos_in / kPi) > 2e-3f * (1.0f + ls.pdf)) ++bad;
    }
    EXPECT_EQ(bad, 0) << "ref_n = " << ref_n.x << " " << ref_n.y << " " << ref_n.z;
  }
}

TEST(LightSamplingTest, TrianglesAndSpheresChosenByPowerAndSampledByArea) {
  LightScene sc;
  // A non-emissive triangle first, so that light indices and primitive ids differ.
  sc.triangle(vec3(-5, -5, -1), vec3(5, -5, -1), vec3(0, 5, -1), sc.material(vec3(0.0f)));
  // A quad of two triangles facing ref (near the origin), at z = 2.
  const uint32_t quad = sc.material(vec3(1.0f));
  const vec3 q00(-1.0f, -0.5f, 2.0f), q10(1.5f, -0.5f, 2.0f), q11(1.5f, 1.0f, 2.0f),
      q01(-1.0f, 1.0f, 2.0f);
  sc.triangle(q00, q11, q10, quad);  // normal -z, towards ref
  sc.triangle(q00, q01, q11, quad);
  // A brighter triangle to the side and a sphere behind, with different powers.
  sc.triangle(vec3(3.0f, -1.0f, -1.0f), vec3(3.0f, -0.5f, 1.5f), vec3(3.0f, 1.0f, 0.0f),
              sc.material(vec3(4.0f)));
  sc.sphere(vec3(-0.5f, 0.5f, -3.0f), 0.8f, sc.material(vec3(2.5f)));
  sc.finish();
  ASSERT_EQ(sc.lights.size(), 4u);

  const vec3 ref(0.1f, 0.05f, -0.08f);
  chi2::SphereBins bins;
  bins.z_res = 64;
  bins.phi_res = 128;
  bins.basis = chi2::Basis(glm::dvec3(0.1, 0.2, 1.0));
  const std::vector<double> picked = check_light_sampling(sc, ref, kRefNormal, bins, 50);

  // Selection frequencies against light_select_pdf, which must follow the powers.
  double total_power = 0.0;
  for (const Light& l : sc.lights) total_power += l.power;
  std::vector<double> expected;
  double n = 0.0;
  for (double p : picked) n += p;
  for (uint32_t i = 0; i < sc.lights.size(); ++i) {
    EXPECT_NEAR(light_select_pdf(sc.view, i), sc.lights[i].power / total_power, 1e-6);
    expected.push_back(n * light_select_pdf(sc.view, i));
  }
  const chi2::Result r = chi2::chi_square_test(picked, expected, kSignificance, kChiSquareTests);
  EXPECT_TRUE(r.passed) << r.message;

  // The quad faces ref, the side triangle too (its normal is +x or -x; emission is one-sided).
  Uniform rng(51);
  for (int i = 0; i < 10000; ++i) {
    const LightSample ls = sample_light(sc.view, ref, kRefNormal, rng.f(), rng.f2());
    ASSERT_TRUE(ls.valid);
    const Material& m =
        sc.materials[ls.prim < sc.tris.size() ? sc.shading[ls.prim].material
                                              : sc.spheres[ls.prim - sc.tris.size()].material];
    const bool front = glm::dot(ls.n, ref - ls.p) > 0.0f;
    EXPECT_EQ(ls.le, front ? m.emission : vec3(0.0f));
  }
}

TEST(LightSamplingTest, PickLightInvertsTheCdf) {
  LightScene sc;
  sc.sphere(vec3(0, 0, 5), 1.0f, sc.material(vec3(1.0f)));
  sc.sphere(vec3(0, 5, 0), 1.0f, sc.material(vec3(0.0f)));  // not a light
  sc.sphere(vec3(5, 0, 0), 2.0f, sc.material(vec3(1.0f)));
  sc.finish();
  ASSERT_EQ(sc.lights.size(), 2u);
  const float split = sc.cdf[1];  // 1/5: areas 4 pi and 16 pi
  EXPECT_NEAR(split, 0.2f, 1e-6f);
  EXPECT_EQ(pick_light(sc.view, 0.0f), 0u);
  EXPECT_EQ(pick_light(sc.view, std::nextafter(split, 0.0f)), 0u);
  EXPECT_EQ(pick_light(sc.view, split), 1u);
  EXPECT_EQ(pick_light(sc.view, std::nextafter(1.0f, 0.0f)), 1u);
}

}  // namespace
}  // namespace tracer

TEST(MathTest, DivideSmallIsIntegerDivisionForEveryImageSize) {
  // The camera finds a pixel's row with divide_small (a float estimate, then corrected): it must
  // equal n / d for every width and row the CLI allows (up to 16384 x 16384), at the ends of
  // every row in particular.
  std::mt19937 rng(8);
  for (uint32_t d : {1u, 2u, 3u, 7u, 640u, 1080u, 1280u, 1920u, 3840u, 4095u, 12345u, 16384u}) {
    for (uint32_t row : {0u, 1u, 2u, 1079u, 4096u, 8191u, 16383u}) {
      for (int64_t k : {-1, 0, 1}) {
        const int64_t n = int64_t(row) * d + (k < 0 ? int64_t(d) - 1 : k);
        if (n < 0 || n >= int64_t(d) * 16384) continue;
        ASSERT_EQ(tracer::divide_small(uint32_t(n), d), uint32_t(n) / d) << n << " / " << d;
      }
    }
    std::uniform_int_distribution<uint32_t> any(0, d * 16384u - 1u);
    for (int i = 0; i < 20000; ++i) {
      const uint32_t n = any(rng);
      ASSERT_EQ(tracer::divide_small(n, d), n / d) << n << " / " << d;
    }
  }
}
