// Tests for tracer/materials (bsdf.h, fresnel.h): every BSDF gets Mitsuba's tests (eval and pdf
// agree with sample, chi-square of the sampled directions), plus the Fresnel equations against
// their textbook form (dielectric and conductor) and their hemispherical averages, Snell's law,
// reciprocity, R + T = 1 for the smooth dielectric and the thin diffuse transmitter. (The rough
// conductor is in microfacet_test.cpp, the coated diffuse in coated_diffuse_test.cpp.)
#include "materials/bsdf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>
#include <vector>

#include "chi_square.h"
#include "core/math.h"
#include "core/sampling.h"
#include "materials/fresnel.h"
#include "materials/material.h"

namespace tracer {
namespace {

// Sidak correction over all chi-square tests in this executable: 3 diffuse direction tests,
// 9 tests of the dielectric's lobe choice and 6 of the diffuse transmitter's directions.
constexpr double kSignificance = 0.01;
constexpr int kChiSquareTests = 18;
constexpr size_t kSamples = 1000000;

using chi2::Uniform;

using chi2::direction;

Material make(MaterialType type, vec3 albedo = vec3(0.8f), float ior = 1.5f, uint32_t flags = 0) {
  Material m;
  m.type = type;
  m.albedo = albedo;
  m.ior = ior;
  m.flags = flags;
  return m;
}

// Fresnel reflectance from Fresnel's equations in their angle form (Born & Wolf, sec. 1.5.2),
// in double and independent of the code under test. eta = n_t / n_i.
double fresnel_reference(double cos_i, double eta) {
  const double sin_i = std::sqrt(std::max(0.0, 1.0 - cos_i * cos_i));
  const double sin_t = sin_i / eta;
  if (sin_t >= 1.0) return 1.0;
  if (sin_i == 0.0) return ((eta - 1.0) / (eta + 1.0)) * ((eta - 1.0) / (eta + 1.0));
  const double ti = std::asin(sin_i), tt = std::asin(sin_t);
  const double rs = std::sin(ti - tt) / std::sin(ti + tt);
  const double rp = std::tan(ti - tt) / std::tan(ti + tt);
  return 0.5 * (rs * rs + rp * rp);
}

// The conductor's Fresnel reflectance from the complex amplitudes, in double and independent of
// the code under test: cos_t = sqrt(1 - sin^2 / eta_c^2), r_s = (cos - eta_c cos_t) /
// (cos + eta_c cos_t), r_p = (eta_c cos - cos_t) / (eta_c cos + cos_t), R = (|r_s|^2 + |r_p|^2) / 2
// (Born & Wolf sec. 14.2, the form pbrt-v4's FrComplex evaluates).
double conductor_reference(double cos_i, double eta, double k) {
  using C = std::complex<double>;
  const C n(eta, k);
  const double sin2 = 1.0 - cos_i * cos_i;
  const C cos_t = std::sqrt(C(1.0) - sin2 / (n * n));
  const C rs = (cos_i - n * cos_t) / (cos_i + n * cos_t);
  const C rp = (n * cos_i - cos_t) / (n * cos_i + cos_t);
  return 0.5 * (std::norm(rs) + std::norm(rp));
}

// ---------------------------------------------------------------------------------------------
// Diffuse.

TEST(DiffuseBsdfTest, SampledDirectionsFollowThePdf) {
  const Material m = make(MaterialType::kDiffuse, vec3(0.7f, 0.5f, 0.2f));
  uint32_t seed = 1;
  for (float theta : {0.0f, 45.0f, 85.0f}) {
    SCOPED_TRACE(testing::Message() << "theta_o = " << theta);
    const vec3 wo = direction(theta);
    Uniform rng(seed++);
    auto sample = [&](glm::dvec3& w) {
      const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
      w = glm::dvec3(s.wi);
      return s.valid;
    };
    auto pdf = [&](glm::dvec3 w) { return double(bsdf_pdf(m, wo, vec3(w))); };
    const chi2::Result r = chi2::sphere_chi_square(sample, pdf, kSamples, chi2::SphereBins(),
                                                   kSignificance, kChiSquareTests);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
  }
}

TEST(DiffuseBsdfTest, EvalPdfAndSampleAgree) {
  const Material m = make(MaterialType::kDiffuse, vec3(0.7f, 0.5f, 0.2f));
  Uniform rng(4);
  for (float theta : {0.0f, 30.0f, 60.0f, 89.0f}) {
    const vec3 wo = direction(theta, 2.0f);
    int bad = 0;
    for (int i = 0; i < 100000; ++i) {
      const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
      if (!s.valid) continue;
      const vec3 f = bsdf_eval(m, wo, s.wi);
      const float pdf = bsdf_pdf(m, wo, s.wi);
      const vec3 expected_weight = f * s.wi.z / pdf;
      bad += s.specular || std::abs(s.pdf - pdf) > 1e-5f * pdf ||
             glm::length(s.weight - expected_weight) > 1e-5f ||
             std::abs(glm::length(s.wi) - 1.0f) > 1e-5f || s.wi.z < 0.0f;
    }
    EXPECT_EQ(bad, 0) << "theta_o = " << theta;
  }
  // The pdf is the closed form cos/pi, and eval is albedo/pi, reciprocal in wo and wi.
  const vec3 wo = direction(40.0f), wi = direction(70.0f, -1.0f);
  EXPECT_NEAR(bsdf_pdf(m, wo, wi), wi.z / kPi, 1e-6f);
  EXPECT_LT(glm::length(bsdf_eval(m, wo, wi) - m.albedo / kPi), 1e-6f);
  EXPECT_EQ(bsdf_eval(m, wo, wi), bsdf_eval(m, wi, wo));
}

TEST(DiffuseBsdfTest, IsOneSided) {
  const Material m = make(MaterialType::kDiffuse);
  const vec3 up = direction(30.0f), down = -direction(50.0f);
  EXPECT_EQ(bsdf_eval(m, up, down), vec3(0.0f));
  EXPECT_EQ(bsdf_eval(m, down, up), vec3(0.0f));
  EXPECT_EQ(bsdf_pdf(m, up, down), 0.0f);
  EXPECT_EQ(bsdf_pdf(m, down, up), 0.0f);
  EXPECT_FALSE(bsdf_sample(m, down, vec2(0.3f, 0.6f), 0.5f).valid);
}

TEST(DiffuseBsdfTest, ReflectsItsAlbedo) {
  // Directional albedo: integral of f cos over the hemisphere equals the albedo, estimated with
  // uniform hemisphere directions (variance albedo^2 / 3 per sample) to 5 standard errors.
  const vec3 albedo(0.9f, 0.5f, 0.1f);
  const Material m = make(MaterialType::kDiffuse, albedo);
  const vec3 wo = direction(35.0f);
  Uniform rng(5);
  glm::dvec3 sum(0.0), sum2(0.0);
  const size_t n = kSamples;
  for (size_t i = 0; i < n; ++i) {
    const vec3 wi = sample_uniform_hemisphere(rng.f2());
    const glm::dvec3 x = glm::dvec3(bsdf_eval(m, wo, wi)) * double(wi.z) * (2.0 * M_PI);
    sum += x;
    sum2 += x * x;
  }
  for (int c = 0; c < 3; ++c) {
    const double mean = sum[c] / n, se = std::sqrt((sum2[c] / n - mean * mean) / n);
    EXPECT_NEAR(mean, albedo[c], 5.0 * se + 1e-6) << "channel " << c;
    EXPECT_GT(se, 0.0);
  }
}

// ---------------------------------------------------------------------------------------------
// Mirror.

TEST(MirrorBsdfTest, ReflectsExactlyWithItsAlbedo) {
  const vec3 albedo(0.9f, 0.6f, 0.3f);
  const Material m = make(MaterialType::kMirror, albedo);
  Uniform rng(6);
  for (int i = 0; i < 1000; ++i) {
    const vec3 wo = sample_uniform_hemisphere(rng.f2());
    if (wo.z <= 0.0f) continue;
    const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
    ASSERT_TRUE(s.valid);
    EXPECT_TRUE(s.specular);
    EXPECT_EQ(s.wi, vec3(-wo.x, -wo.y, wo.z));
    EXPECT_EQ(s.weight, albedo);
    EXPECT_EQ(s.pdf, 1.0f);  // the discrete probability of the only lobe
    // No part of a delta lobe is visible to eval or pdf.
    EXPECT_EQ(bsdf_eval(m, wo, s.wi), vec3(0.0f));
    EXPECT_EQ(bsdf_pdf(m, wo, s.wi), 0.0f);
  }
  // In a world frame: the sampled direction is 2 (n.wo) n - wo.
  const vec3 n = glm::normalize(vec3(0.3f, -0.8f, 0.2f));
  const vec3 wo_world = glm::normalize(vec3(0.9f, -0.1f, 0.5f));
  ASSERT_GT(glm::dot(n, wo_world), 0.0f);
  const Frame f = Frame::from_normal(n);
  const BsdfSample s = bsdf_sample(m, f.to_local(wo_world), vec2(0.5f), 0.5f);
  const vec3 expected = 2.0f * glm::dot(n, wo_world) * n - wo_world;
  EXPECT_LT(glm::length(f.to_world(s.wi) - expected), 1e-5f);
  EXPECT_FALSE(bsdf_sample(m, vec3(0.0f, 0.6f, -0.8f), vec2(0.5f), 0.5f).valid);
}

// ---------------------------------------------------------------------------------------------
// Smooth conductor (roughness 0; the rough one is tested in microfacet_test.cpp).

TEST(ConductorBsdfTest, SmoothIsAMirrorWeightedBySchlickFresnel) {
  // glTF's metallic model: F = F0 + (1 - F0)(1 - cos)^5 with F0 = albedo, a delta reflection.
  const vec3 f0(0.9f, 0.6f, 0.3f);
  const Material m = make(MaterialType::kConductor, f0);
  EXPECT_TRUE(bsdf_is_delta(m, m.type));
  for (float theta : {0.0f, 30.0f, 60.0f, 85.0f, 89.9f}) {
    const vec3 wo = direction(theta);
    const BsdfSample s = bsdf_sample(m, wo, vec2(0.3f, 0.8f), 0.5f);
    ASSERT_TRUE(s.valid);
    EXPECT_TRUE(s.specular);
    EXPECT_EQ(s.wi, vec3(-wo.x, -wo.y, wo.z));
    EXPECT_EQ(s.pdf, 1.0f);
    const double c = 1.0 - std::cos(theta * M_PI / 180.0), c5 = c * c * c * c * c;
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.weight[k], f0[k] + (1.0 - f0[k]) * c5, 1e-5);
    EXPECT_EQ(bsdf_eval(m, wo, s.wi), vec3(0.0f));
    EXPECT_EQ(bsdf_pdf(m, wo, s.wi), 0.0f);
  }
  EXPECT_EQ(bsdf_sample(m, direction(0.0f), vec2(0.5f), 0.5f).weight, f0);  // F(0 deg) = F0
  EXPECT_FALSE(bsdf_sample(m, direction(100.0f), vec2(0.5f), 0.5f).valid);
}

TEST(ConductorBsdfTest, RoughnessSwitchesOffTheDeltaLobe) {
  Material m = make(MaterialType::kConductor, vec3(0.9f));
  m.roughness = 0.3f;
  EXPECT_FALSE(bsdf_is_delta(m, m.type));
  const BsdfSample s = bsdf_sample(m, direction(30.0f), vec2(0.3f, 0.8f), 0.5f);
  ASSERT_TRUE(s.valid);
  EXPECT_FALSE(s.specular);
  EXPECT_GT(bsdf_pdf(m, direction(30.0f), s.wi), 0.0f);
  // Without specular features in the mask every material is sampled as diffuse.
  const BsdfSample d = bsdf_sample<kFeatureEmissiveMeshes>(m, direction(30.0f), vec2(0.3f), 0.5f);
  ASSERT_TRUE(d.valid);
  EXPECT_FALSE(d.specular);
  EXPECT_EQ(d.weight, m.albedo);
  EXPECT_EQ(bsdf_pdf<kFeatureEmissiveMeshes>(m, direction(30.0f), d.wi), d.wi.z * kInvPi);
  EXPECT_EQ(bsdf_eval<kFeatureEmissiveMeshes>(m, direction(30.0f), d.wi), m.albedo * kInvPi);
}

TEST(SubsurfaceBsdfTest, BoundaryStaysSmoothWhateverTheRoughness) {
  // The subsurface boundary is the smooth dielectric; its roughness field is not used.
  Material m = make(MaterialType::kSubsurface, vec3(1.0f), 1.5f);
  m.roughness = 0.5f;
  EXPECT_TRUE(bsdf_is_delta(m, m.type));
  Material glass = make(MaterialType::kDielectric, vec3(1.0f), 1.5f);
  Uniform rng(40);
  for (int i = 0; i < 200; ++i) {
    const vec3 wo = sample_uniform_sphere(rng.f2());
    const vec2 u = rng.f2();
    const float uc = rng.f();
    const BsdfSample a = bsdf_sample(m, wo, u, uc), b = bsdf_sample(glass, wo, u, uc);
    EXPECT_EQ(a.valid, b.valid);
    EXPECT_TRUE(a.specular);
    EXPECT_EQ(a.wi, b.wi);
    EXPECT_EQ(a.weight, b.weight);
    EXPECT_EQ(a.pdf, b.pdf);
    EXPECT_EQ(bsdf_eval(m, wo, -wo), vec3(0.0f));
    EXPECT_EQ(bsdf_pdf(m, wo, -wo), 0.0f);
  }
}

// ---------------------------------------------------------------------------------------------
// Fresnel equations.

TEST(FresnelTest, NormalIncidenceIsR0) {
  // R0 = ((n - 1) / (n + 1))^2 = 0.04 for glass, from either side.
  EXPECT_NEAR(fresnel_dielectric(1.0f, 1.5f), 0.04f, 1e-6f);
  EXPECT_NEAR(fresnel_dielectric(1.0f, 1.0f / 1.5f), 0.04f, 1e-6f);
  EXPECT_NEAR(fresnel_schlick(1.0f, 1.5f), 0.04f, 1e-6f);
  EXPECT_NEAR(fresnel_schlick(1.0f, 1.0f / 1.5f), 0.04f, 1e-6f);
  EXPECT_NEAR(fresnel_dielectric(1.0f, 2.4f), (1.4 * 1.4) / (3.4 * 3.4), 1e-6);
}

TEST(FresnelTest, MatchesTheTextbookEquations) {
  for (float eta : {1.0f / 2.4f, 1.0f / 1.5f, 1.0f / 1.33f, 1.0f, 1.33f, 1.5f, 2.4f}) {
    for (int i = 0; i <= 1000; ++i) {
      const float cos_i = i / 1000.0f;
      const float f = fresnel_dielectric(cos_i, eta), s = fresnel_schlick(cos_i, eta);
      ASSERT_GE(f, 0.0f);
      ASSERT_LE(f, 1.0f);
      ASSERT_GE(s, 0.0f);
      ASSERT_LE(s, 1.0f);
      // Near the critical angle F climbs steeply to 1, so compare in cos_t's precision there.
      EXPECT_NEAR(f, fresnel_reference(cos_i, eta), 2e-5) << "cos_i " << cos_i << " eta " << eta;
    }
    if (eta != 1.0f) EXPECT_EQ(fresnel_dielectric(0.0f, eta), 1.0f);  // grazing
  }
  EXPECT_NEAR(fresnel_dielectric(0.4f, 1.0f), 0.0f, 1e-7f);  // no interface, no reflection
}

TEST(FresnelTest, TotalInternalReflectionBeyondTheCriticalAngle) {
  const float eta = 1.0f / 1.5f;  // from glass into air
  const float cos_c = std::sqrt(1.0f - eta * eta);
  for (float cos_i : {0.0f, 0.2f, 0.5f, cos_c - 1e-4f}) {
    EXPECT_EQ(fresnel_dielectric(cos_i, eta), 1.0f) << cos_i;
    EXPECT_EQ(fresnel_schlick(cos_i, eta), 1.0f) << cos_i;
    vec3 wt;
    const vec3 w(std::sqrt(1.0f - cos_i * cos_i), 0.0f, cos_i);
    EXPECT_FALSE(refract(w, vec3(0, 0, 1), eta, wt)) << cos_i;
  }
  EXPECT_LT(fresnel_dielectric(cos_c + 1e-3f, eta), 1.0f);
  EXPECT_LT(fresnel_dielectric(0.9f, eta), 0.1f);
}

TEST(FresnelTest, ReflectanceIsTheSameFromBothSides) {
  // Stokes relations: R at the incident angle from outside equals R at the refracted angle from
  // inside. Schlick's variant is built to keep this.
  const float eta = 1.5f;
  for (int i = 1; i <= 100; ++i) {
    const float cos_i = i / 100.0f;
    const double sin_t = std::sqrt(1.0 - double(cos_i) * cos_i) / eta;
    const float cos_t = float(std::sqrt(1.0 - sin_t * sin_t));
    // From inside, cos_i is recovered from 1 - sin^2 in float: cancellation near grazing.
    const float tol = 1e-5f + 1e-6f / cos_i;
    EXPECT_NEAR(fresnel_dielectric(cos_i, eta), fresnel_dielectric(cos_t, 1.0f / eta), tol)
        << cos_i;
    EXPECT_NEAR(fresnel_schlick(cos_i, eta), fresnel_schlick(cos_t, 1.0f / eta), tol) << cos_i;
  }
}

TEST(FresnelTest, HemisphericalAverage) {
  // 2 int_0^{pi/2} F(theta) cos sin dtheta at n = 1.5: 0.0918 with the exact equations; with
  // Schlick, R0 + 2 (1 - R0) B(2, 6) = 0.04 + 0.96 / 21 = 0.0857.
  const int n = 100000;
  const double dt = 0.5 * M_PI / n;
  double exact = 0.0, schlick = 0.0;
  for (int i = 0; i < n; ++i) {
    const double t = (i + 0.5) * dt, w = 2.0 * std::cos(t) * std::sin(t) * dt;
    exact += w * fresnel_dielectric(float(std::cos(t)), 1.5f);
    schlick += w * fresnel_schlick(float(std::cos(t)), 1.5f);
  }
  EXPECT_NEAR(exact, 0.0918, 5e-4);
  EXPECT_NEAR(schlick, 0.0857, 5e-4);
  EXPECT_NEAR(schlick, 0.04 + 0.96 / 21.0, 1e-5);
}

TEST(FresnelTest, ConductorMatchesTheComplexAmplitudes) {
  // Measured metals (RGB channels of gold, silver, aluminium, titanium), a dielectric (k = 0)
  // from either side, and extreme values.
  const double cases[][2] = {{0.1757, 4.8935}, {0.3985, 2.3672}, {1.5856, 1.7183}, {0.1346, 4.4298},
                             {1.4812, 7.8517}, {2.7835, 3.8899}, {1.5, 0.0},       {1.0 / 1.5, 0.0},
                             {0.05, 12.0},     {4.0, 0.01},      {1.0, 1.0}};
  for (const auto& c : cases) {
    double worst = 0.0;
    for (int i = 0; i <= 1000; ++i) {
      const double cos_i = i / 1000.0;
      const float f = fresnel_conductor(float(cos_i), float(c[0]), float(c[1]));
      ASSERT_GE(f, 0.0f);
      ASSERT_LE(f, 1.0f);
      worst = std::max(worst, std::abs(f - conductor_reference(cos_i, c[0], c[1])));
    }
    EXPECT_LT(worst, 2e-5) << "eta " << c[0] << " k " << c[1];
    EXPECT_NEAR(fresnel_conductor(0.0f, float(c[0]), float(c[1])), 1.0f, 1e-6f);  // grazing
    // Normal incidence: ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2).
    const double f0 =
        ((c[0] - 1) * (c[0] - 1) + c[1] * c[1]) / ((c[0] + 1) * (c[0] + 1) + c[1] * c[1]);
    EXPECT_NEAR(fresnel_conductor(1.0f, float(c[0]), float(c[1])), f0, 1e-6);
  }
  // k = 0 is the dielectric, total internal reflection included.
  for (float eta : {1.5f, 1.0f / 1.5f, 2.4f})
    for (int i = 0; i <= 100; ++i)
      EXPECT_NEAR(fresnel_conductor(i / 100.0f, eta, 0.0f), fresnel_dielectric(i / 100.0f, eta),
                  2e-6f);
}

TEST(FresnelTest, HemisphericalAveragesMatchQuadrature) {
  // fresnel_average's closed form against int F(mu) 2 mu dmu by the midpoint rule in double, and
  // the inside average against the same quadrature of the reflectance from inside (eta -> 1/eta),
  // which checks the energy-balance relation 1 - F_in = (1 - F_out) / eta^2.
  auto quad = [](auto f) {
    const int n = 200000;
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
      const double mu = (i + 0.5) / n;
      sum += f(mu) * 2.0 * mu / n;
    }
    return sum;
  };
  for (float eta : {1.001f, 1.01f, 1.05f, 1.099f, 1.1f, 1.33f, 1.5f, 2.0f, 2.4f, 4.0f}) {
    const double out = quad([&](double mu) { return fresnel_reference(mu, eta); });
    const double in = quad([&](double mu) { return fresnel_reference(mu, 1.0 / eta); });
    EXPECT_NEAR(fresnel_average(eta, false), out, 2e-6 + 2e-5 * out) << eta;
    EXPECT_NEAR(fresnel_average_inside(eta, false), in, 2e-5) << eta;
    const double out_s = quad([&](double mu) { return double(fresnel_schlick(float(mu), eta)); });
    const double in_s =
        quad([&](double mu) { return double(fresnel_schlick(float(mu), 1.0f / eta)); });
    EXPECT_NEAR(fresnel_average(eta, true), out_s, 1e-5) << eta;
    EXPECT_NEAR(fresnel_average_inside(eta, true), in_s, 1e-4) << eta;
  }
  EXPECT_NEAR(fresnel_average(1.5f, false), 0.0918, 1e-4);  // the table value, as above
  EXPECT_NEAR(fresnel_average_inside(1.5f, false), 0.5963, 1e-4);
  EXPECT_EQ(fresnel_average(1.0f, false), 0.0f);
  EXPECT_EQ(fresnel_average_inside(1.0f, true), 0.0f);
}

TEST(FresnelTest, RefractionObeysSnellsLaw) {
  Uniform rng(7);
  for (float eta : {1.5f, 1.0f / 1.5f, 1.33f, 2.4f, 1.0f / 2.4f}) {
    int refracted = 0;
    for (int i = 0; i < 2000; ++i) {
      const vec3 n = sample_uniform_sphere(rng.f2());
      vec3 w = sample_uniform_sphere(rng.f2());
      if (glm::dot(w, n) < 0.0f) w = -w;  // on the side of n
      vec3 wt;
      const float cos_i = glm::dot(w, n);
      const bool ok = refract(w, n, eta, wt);
      const float sin_i = std::sqrt(std::max(0.0f, 1.0f - cos_i * cos_i));
      EXPECT_EQ(ok, sin_i / eta < 1.0f) << "eta " << eta << " cos_i " << cos_i;
      if (!ok) continue;
      ++refracted;
      EXPECT_NEAR(glm::length(wt), 1.0f, 1e-5f);
      EXPECT_LT(glm::dot(wt, n), 0.0f);  // crosses to the other side
      const float sin_t = glm::length(glm::cross(wt, n));
      EXPECT_NEAR(sin_i, eta * sin_t, 2e-5f);                               // n1 sin1 = n2 sin2
      EXPECT_NEAR(glm::dot(glm::cross(w, n), wt), 0.0f, 2e-5f);             // plane of incidence
      EXPECT_LE(glm::dot(w - cos_i * n, wt - glm::dot(wt, n) * n), 1e-6f);  // tangent flips
      vec3 back;  // the path reverses (away from grazing, where rounding is amplified)
      if (cos_i > 0.01f && -glm::dot(wt, n) > 0.01f) {
        ASSERT_TRUE(refract(wt, -n, 1.0f / eta, back));
        EXPECT_LT(glm::length(back - w), 1e-4f);
      }
    }
    EXPECT_GT(refracted, 0);
  }
}

// ---------------------------------------------------------------------------------------------
// Smooth dielectric.

// Samples the dielectric n times at wo and checks every sample: the reflected lobe is the mirror
// direction with pdf F and weight 1, the transmitted one is Snell's direction with pdf 1 - F and
// weight albedo / eta^2. Returns the number reflected.
double sample_dielectric(const Material& m, vec3 wo, size_t n, uint32_t seed, double* energy) {
  const bool entering = wo.z > 0.0f;
  const float eta = entering ? m.ior : 1.0f / m.ior;
  const float F = material_fresnel(m, std::abs(wo.z), eta);
  vec3 wt_expected(0.0f);
  const bool can_refract = refract(wo, vec3(0, 0, entering ? 1.0f : -1.0f), eta, wt_expected);
  Uniform rng(seed);
  double reflected = 0.0, r_sum = 0.0, t_sum = 0.0;
  int bad = 0;
  for (size_t i = 0; i < n; ++i) {
    const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
    bad += !s.valid || !s.specular;
    if (s.wi.z * wo.z > 0.0f) {
      reflected += 1.0;
      r_sum += s.weight.x;
      bad +=
          s.wi != vec3(-wo.x, -wo.y, wo.z) || std::abs(s.pdf - F) > 1e-6f || s.weight != vec3(1.0f);
    } else {
      // Radiance scales by 1/eta^2 crossing the interface (pbrt-v4 eq. 9.8); undo it for energy.
      t_sum += s.weight.x * eta * eta / m.albedo.x;
      bad += !can_refract || glm::length(s.wi - wt_expected) > 1e-5f ||
             std::abs(s.pdf - (1.0f - F)) > 1e-6f ||
             glm::length(s.weight - m.albedo / (eta * eta)) > 1e-6f;
    }
  }
  EXPECT_EQ(bad, 0);
  if (energy) *energy = (r_sum + t_sum) / double(n);
  return reflected;
}

TEST(DielectricBsdfTest, ReflectsWithTheFresnelProbabilityAndConservesEnergy) {
  const Material m = make(MaterialType::kDielectric, vec3(1.0f, 0.8f, 0.6f), 1.5f);
  uint32_t seed = 10;
  // Entering at several angles; leaving below and above the critical angle (41.8 degrees).
  for (float theta : {0.0f, 40.0f, 70.0f, 85.0f, 180.0f, 150.0f, 140.0f, 130.0f}) {
    SCOPED_TRACE(testing::Message() << "theta_o = " << theta);
    const vec3 wo = direction(theta);
    const float eta = wo.z > 0.0f ? 1.5f : 1.0f / 1.5f;
    const double F = fresnel_dielectric(std::abs(wo.z), eta);
    double energy = 0.0;
    const double reflected = sample_dielectric(m, wo, kSamples, seed++, &energy);
    // R + T = 1: each lobe's weight times its probability sums to one.
    EXPECT_NEAR(energy, 1.0, 1e-5);
    if (F >= 1.0) {
      EXPECT_EQ(reflected, double(kSamples));  // total internal reflection
      continue;
    }
    const chi2::Result r = chi2::chi_square_test({reflected, kSamples - reflected},
                                                 {kSamples * F, kSamples * (1.0 - F)},
                                                 kSignificance, kChiSquareTests, 0.0);
    EXPECT_TRUE(r.passed) << "reflected " << reflected / kSamples << " vs F = " << F << ": "
                          << r.message;
  }
  EXPECT_EQ(bsdf_eval(m, direction(30.0f), direction(150.0f)), vec3(0.0f));
  EXPECT_EQ(bsdf_pdf(m, direction(30.0f), direction(30.0f, 0.7f + kPi)), 0.0f);
}

TEST(DielectricBsdfTest, TransmissionWeightsAreReciprocalAcrossTheInterface) {
  // Radiance crossing in and back out is unchanged: (1/eta^2) * eta^2 = 1 for a clear glass.
  const Material m = make(MaterialType::kDielectric, vec3(1.0f), 1.5f);
  const vec3 wo = direction(35.0f);
  BsdfSample in = bsdf_sample(m, wo, vec2(0.5f), 0.999f);  // uc above F: transmit
  ASSERT_TRUE(in.valid);
  ASSERT_LT(in.wi.z, 0.0f);
  BsdfSample out = bsdf_sample(m, in.wi, vec2(0.5f), 0.999f);
  ASSERT_TRUE(out.valid);
  ASSERT_GT(out.wi.z, 0.0f);
  EXPECT_LT(glm::length(out.wi - wo), 1e-5f);
  EXPECT_NEAR(in.weight.x * out.weight.x, 1.0f, 1e-5f);
  EXPECT_NEAR(in.weight.x, 1.0f / 2.25f, 1e-6f);
}

TEST(DielectricBsdfTest, SchlickFlagChoosesLobesBySchlick) {
  const Material m = make(MaterialType::kDielectric, vec3(1.0f), 1.5f, kMaterialSchlickFresnel);
  uint32_t seed = 30;
  // Angles where Schlick and the exact equations differ by far more than the statistics resolve.
  for (float theta : {80.0f, 139.0f}) {
    SCOPED_TRACE(testing::Message() << "theta_o = " << theta);
    const vec3 wo = direction(theta);
    const float eta = wo.z > 0.0f ? 1.5f : 1.0f / 1.5f;
    const double schlick = fresnel_schlick(std::abs(wo.z), eta);
    const double exact = fresnel_dielectric(std::abs(wo.z), eta);
    ASSERT_GT(std::abs(schlick - exact), 20.0 * std::sqrt(0.25 / kSamples));
    double energy = 0.0;
    const double reflected = sample_dielectric(m, wo, kSamples, seed++, &energy);
    EXPECT_NEAR(energy, 1.0, 1e-5);
    const chi2::Result r = chi2::chi_square_test({reflected, kSamples - reflected},
                                                 {kSamples * schlick, kSamples * (1.0 - schlick)},
                                                 kSignificance, kChiSquareTests, 0.0);
    EXPECT_TRUE(r.passed) << "reflected " << reflected / kSamples << " vs Schlick " << schlick
                          << " (exact " << exact << "): " << r.message;
  }
}

// ---------------------------------------------------------------------------------------------
// Diffuse transmission.

Material sheet(vec3 reflectance, vec3 transmittance) {
  Material m = make(MaterialType::kDiffuseTransmission, reflectance);
  m.transmittance = transmittance;
  return m;
}

TEST(DiffuseTransmissionTest, SampledDirectionsFollowThePdf) {
  uint32_t seed = 60;
  for (const Material& m :
       {sheet(vec3(0.5f, 0.3f, 0.1f), vec3(0.3f, 0.5f, 0.6f)), sheet(vec3(0.05f), vec3(0.9f))}) {
    for (float theta : {10.0f, 70.0f, 160.0f}) {  // from both sides
      SCOPED_TRACE(testing::Message() << "theta_o = " << theta);
      const vec3 wo = direction(theta);
      Uniform rng(seed++);
      auto sample = [&](glm::dvec3& w) {
        const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
        w = glm::dvec3(s.wi);
        return s.valid;
      };
      auto pdf = [&](glm::dvec3 w) { return double(bsdf_pdf(m, wo, vec3(w))); };
      const chi2::Result r = chi2::sphere_chi_square(sample, pdf, kSamples, chi2::SphereBins(),
                                                     kSignificance, kChiSquareTests);
      EXPECT_TRUE(r.passed) << r.message;
      EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
    }
  }
}

TEST(DiffuseTransmissionTest, EvalPdfAndSampleAgreeAndAreReciprocal) {
  const Material m = sheet(vec3(0.5f, 0.3f, 0.1f), vec3(0.3f, 0.5f, 0.6f));
  EXPECT_FALSE(bsdf_is_delta(m, m.type));
  EXPECT_TRUE(bsdf_transmits(m.type));
  EXPECT_TRUE(bsdf_chooses_lobe(m.type));
  Uniform rng(70);
  int bad = 0, reflected = 0, transmitted = 0;
  for (float theta : {0.0f, 30.0f, 89.0f, 91.0f, 150.0f, 180.0f}) {
    const vec3 wo = direction(theta, 2.0f);
    for (int i = 0; i < 20000; ++i) {
      const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
      if (!s.valid) continue;
      const vec3 f = bsdf_eval(m, wo, s.wi);
      const float pdf = bsdf_pdf(m, wo, s.wi);
      const vec3 expected = f * std::abs(s.wi.z) / pdf;
      const bool same_side = s.wi.z * wo.z > 0.0f;
      (same_side ? reflected : transmitted)++;
      bad += s.specular || std::abs(s.pdf - pdf) > 1e-5f * pdf ||
             glm::length(s.weight - expected) > 1e-5f ||
             f != (same_side ? m.albedo : m.transmittance) * kInvPi;
    }
  }
  EXPECT_EQ(bad, 0);
  EXPECT_GT(reflected, 1000);
  EXPECT_GT(transmitted, 1000);
  for (int i = 0; i < 1000; ++i) {
    const vec3 a = sample_uniform_sphere(rng.f2()), b = sample_uniform_sphere(rng.f2());
    EXPECT_EQ(bsdf_eval(m, a, b), bsdf_eval(m, b, a));
  }
}

TEST(DiffuseTransmissionTest, ReflectsAndTransmitsItsColours) {
  // The mean sample weight on each side is that side's colour: R + T of incident light leaves,
  // so R + T = 1 loses nothing (the furnace test renders it) and a black sheet absorbs all.
  const Material m = sheet(vec3(0.6f, 0.2f, 0.1f), vec3(0.4f, 0.5f, 0.9f));
  Uniform rng(80);
  for (float theta : {20.0f, 75.0f, 120.0f}) {
    const vec3 wo = direction(theta);
    glm::dvec3 r(0.0), t(0.0);
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
      const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
      ASSERT_TRUE(s.valid);
      (s.wi.z * wo.z > 0.0f ? r : t) += glm::dvec3(s.weight);
    }
    for (int c = 0; c < 3; ++c) {
      // Each weight is the colour over its lobe's probability: a Bernoulli mean, 5 sigma.
      const double p = double(diffuse_reflect_probability(m));
      const double se_r = m.albedo[c] / p * std::sqrt(p * (1 - p) / n);
      const double se_t = m.transmittance[c] / (1 - p) * std::sqrt(p * (1 - p) / n);
      EXPECT_NEAR(r[c] / n, m.albedo[c], 5 * se_r) << theta << " channel " << c;
      EXPECT_NEAR(t[c] / n, m.transmittance[c], 5 * se_t) << theta << " channel " << c;
    }
  }
  const Material black = sheet(vec3(0.0f), vec3(0.0f));
  EXPECT_EQ(diffuse_reflect_probability(black), 1.0f);
  const BsdfSample s = bsdf_sample(black, direction(30.0f), vec2(0.3f, 0.4f), 0.5f);
  EXPECT_TRUE(!s.valid || s.weight == vec3(0.0f));
  EXPECT_FALSE(bsdf_sample(m, vec3(1.0f, 0.0f, 0.0f), vec2(0.3f), 0.5f).valid);  // grazing wo
}

}  // namespace
}  // namespace tracer
