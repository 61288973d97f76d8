// Tests for the GGX microfacet distribution (materials/microfacet.h), isotropic and anisotropic,
// and the rough conductor (Schlick or complex-IOR Fresnel) and rough dielectric built on it
// (materials/bsdf.h): normalisation of D and of the visible-normal distribution, chi-square of
// every sampler, eval/pdf/sample agreement, white furnace, the limit roughness -> 0 against the
// smooth materials, reciprocity, and that anisotropy turns with the frame.
#include "materials/microfacet.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "chi_square.h"
#include "core/math.h"
#include "materials/bsdf.h"
#include "materials/fresnel.h"
#include "materials/material.h"

namespace tracer {
namespace {

// Sidak correction over all chi-square tests in this executable: 6 + 4 visible-normal sampler
// tests (isotropic, anisotropic), 9 + 4 rough conductor tests (Schlick; complex IOR and
// anisotropic) and 11 rough dielectric tests.
constexpr double kSignificance = 0.01;
constexpr int kChiSquareTests = 34;
constexpr size_t kChiSamples = 1000000;

using chi2::Uniform;

using chi2::direction;

Material conductor(float roughness, vec3 f0 = vec3(1.0f)) {
  Material m;
  m.type = MaterialType::kConductor;
  m.albedo = f0;
  m.roughness = roughness;
  return m;
}

// A conductor with a complex index (gold's) and roughness u, v (v < 0: isotropic).
Material ior_conductor(float u, float v = -1.0f) {
  Material m = conductor(u, vec3(1.0f));
  m.flags |= kMaterialConductorIor;
  m.eta = vec3(0.1757f, 0.3985f, 1.5856f);
  m.k = vec3(4.8935f, 2.3672f, 1.7183f);
  m.roughness_v = v;
  return m;
}

Material dielectric(float roughness, float ior = 1.5f, vec3 albedo = vec3(1.0f),
                    uint32_t flags = 0) {
  Material m;
  m.type = MaterialType::kDielectric;
  m.albedo = albedo;
  m.ior = ior;
  m.roughness = roughness;
  m.flags = flags;
  return m;
}

// eta = n(other side) / n(wo's side), as the BSDF defines it.
float eta_of(const Material& m, vec3 wo) {
  return wo.z > 0.0f ? m.ior : 1.0f / m.ior;
}

double angle_deg(glm::dvec3 a, glm::dvec3 b) {
  return std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0, 1.0)) * 180.0 /
         M_PI;
}

// Integral of g(m) over the upper hemisphere of m, by the midpoint rule in (s, phi) after the
// substitution theta = atan(alpha tan s), which spreads the nodes evenly over D's mass for any
// alpha (d theta / d s = alpha (1 + tan^2 s) / (1 + alpha^2 tan^2 s)).
template <class G>
double integrate_normals(const G& g, double alpha, int ns, int nphi) {
  double sum = 0.0;
  const double ds = 0.5 * M_PI / ns, dphi = 2.0 * M_PI / nphi;
  for (int i = 0; i < ns; ++i) {
    const double s = (i + 0.5) * ds, t = std::tan(s);
    const double theta = std::atan(alpha * t);
    const double jac = alpha * (1.0 + t * t) / (1.0 + alpha * alpha * t * t);
    const double st = std::sin(theta), ct = std::cos(theta);
    const double w = st * jac * ds * dphi;
    for (int j = 0; j < nphi; ++j) {
      const double phi = (j + 0.5) * dphi;
      sum += w * g(glm::dvec3(st * std::cos(phi), st * std::sin(phi), ct));
    }
  }
  return sum;
}

// Refraction in double, independent of fresnel.h: w on the side of n, eta = n_t / n_i.
bool refract_ref(glm::dvec3 w, glm::dvec3 n, double eta, glm::dvec3& wt) {
  const double c = glm::dot(w, n);
  const double s2t = (1.0 - c * c) / (eta * eta);
  if (s2t >= 1.0) return false;
  wt = -w / eta + (c / eta - std::sqrt(1.0 - s2t)) * n;
  return true;
}

// The chi-square bins lie about an axis perpendicular to the plane of incidence, so that the
// reflected and transmitted lobes (which straddle that plane) sit on the bins' equator, where the
// cells are squarest and smallest in angle. 96 x 192 cells are about 1.2 x 1.9 degrees there,
// several across the narrowest lobe tested (alpha = 0.04), each integrated on a 6 x 6 grid.
chi2::SphereBins bins_for(vec3 wo) {
  chi2::SphereBins bins;
  bins.z_res = 96;
  bins.phi_res = 192;
  bins.integration_res = 6;
  const double len = std::hypot(double(wo.x), double(wo.y));
  const glm::dvec3 axis = len > 1e-6 ? glm::dvec3(-wo.y / len, wo.x / len, 0.0)
                                     : glm::dvec3(-std::sin(0.7), std::cos(0.7), 0.0);
  bins.basis = chi2::Basis(axis);
  return bins;
}

// Chi-square of bsdf_sample's directions against bsdf_pdf; also checks that the pdf integrates
// to the fraction of valid samples (the sampler drops directions that leave through the wrong
// side, and the pdf must not count them).
void expect_bsdf_sampling_matches_pdf(const Material& m, vec3 wo, uint32_t seed) {
  Uniform rng(seed);
  size_t valid = 0;
  auto sample = [&](glm::dvec3& w) {
    const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
    w = glm::dvec3(s.wi);
    valid += s.valid;
    return s.valid;
  };
  auto pdf = [&](glm::dvec3 w) { return double(bsdf_pdf(m, wo, vec3(w))); };
  const chi2::Result r = chi2::sphere_chi_square(sample, pdf, kChiSamples, bins_for(wo),
                                                 kSignificance, kChiSquareTests);
  EXPECT_TRUE(r.passed) << r.message;
  const double frac = double(valid) / kChiSamples;
  const double se = std::sqrt(frac * (1.0 - frac) / kChiSamples);
  EXPECT_NEAR(r.pdf_integral, frac, 5.0 * se + 2e-3) << r.message;
  EXPECT_GT(frac, 0.5);
}

// ---------------------------------------------------------------------------------------------
// The distribution.

TEST(GgxTest, DistributionIsNormalised) {
  // The projected microfacet area equals the macro-surface area: int D(m) (m.n) dm = 1.
  for (double alpha : {0.05, 0.2, 0.5, 1.0}) {
    const double total = integrate_normals(
        [&](glm::dvec3 m) { return double(ggx_d(vec3(m), float(alpha))) * m.z; }, alpha, 4096, 16);
    EXPECT_NEAR(total, 1.0, 1e-4) << "alpha " << alpha;
  }
  // Roughness 0.005 hits the alpha clamp and still integrates to one.
  EXPECT_EQ(ggx_alpha(0.005f), kMinGgxAlpha);
  const double clamped =
      integrate_normals([&](glm::dvec3 m) { return double(ggx_d(vec3(m), kMinGgxAlpha)) * m.z; },
                        kMinGgxAlpha, 4096, 4);
  EXPECT_NEAR(clamped, 1.0, 1e-3);
  EXPECT_EQ(ggx_d(vec3(0.0f, 0.6f, -0.8f), 0.3f), 0.0f);
}

TEST(GgxTest, VisibleNormalsIntegrateToOne) {
  // Heitz 2014's weak white furnace: int G1(wo) max(0, wo.m) D(m) / wo.z dm = 1, i.e. the
  // projected area of the visible microfacets equals that of the macro-surface, for any wo.
  for (double alpha : {0.05, 0.2, 0.5, 1.0}) {
    for (float theta : {0.0f, 30.0f, 60.0f, 80.0f, 89.0f}) {
      const vec3 wo = direction(theta);
      const double total = integrate_normals(
          [&](glm::dvec3 m) { return double(ggx_vndf_pdf(wo, vec3(m), float(alpha))); }, alpha,
          1024, 512);
      EXPECT_NEAR(total, 1.0, 1e-3) << "alpha " << alpha << " theta " << theta;
    }
  }
}

TEST(GgxTest, MaskingFunctions) {
  const float alpha = 0.4f;
  EXPECT_EQ(ggx_lambda(vec3(0, 0, 1), alpha), 0.0f);
  EXPECT_EQ(ggx_g1(vec3(0, 0, 1), alpha), 1.0f);
  EXPECT_EQ(ggx_g1(vec3(1, 0, 0), alpha), 0.0f);  // grazing: fully masked
  for (float theta : {10.0f, 45.0f, 80.0f}) {
    const vec3 w = direction(theta);
    // Lambda = (-1 + sqrt(1 + alpha^2 tan^2)) / 2 in double, and the same for -w.
    const double t = std::tan(theta * M_PI / 180.0);
    const double lambda = 0.5 * (-1.0 + std::sqrt(1.0 + double(alpha) * alpha * t * t));
    EXPECT_NEAR(ggx_lambda(w, alpha), lambda, 1e-6 * (1.0 + lambda));
    EXPECT_EQ(ggx_lambda(-w, alpha), ggx_lambda(w, alpha));
    const vec3 v = direction(70.0f, 2.0f);
    // Height correlation: G2 >= G1 G1 (the uncorrelated product) and G2 <= min(G1, G1).
    const float g2 = ggx_g2(w, v, alpha);
    EXPECT_GE(g2, ggx_g1(w, alpha) * ggx_g1(v, alpha));
    EXPECT_LE(g2, std::min(ggx_g1(w, alpha), ggx_g1(v, alpha)));
    EXPECT_EQ(g2, ggx_g2(v, w, alpha));
  }
}

TEST(GgxTest, VisibleNormalSamplingMatchesItsPdf) {
  uint32_t seed = 100;
  for (float alpha : {0.3f, 0.8f}) {
    for (float theta : {0.0f, 60.0f, 85.0f}) {
      SCOPED_TRACE(testing::Message() << "alpha " << alpha << " theta_o " << theta);
      const vec3 wo = direction(theta);
      Uniform rng(seed++);
      auto sample = [&](glm::dvec3& m) {
        m = glm::dvec3(ggx_sample_vndf(wo, alpha, rng.f2()));
        return true;
      };
      auto pdf = [&](glm::dvec3 m) { return double(ggx_vndf_pdf(wo, vec3(m), alpha)); };
      const chi2::Result r = chi2::sphere_chi_square(sample, pdf, kChiSamples, bins_for(wo),
                                                     kSignificance, kChiSquareTests);
      EXPECT_TRUE(r.passed) << r.message;
      EXPECT_NEAR(r.pdf_integral, 1.0, 2e-3);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Rough conductor.

TEST(RoughConductorTest, SampledDirectionsFollowThePdf) {
  uint32_t seed = 200;
  for (float roughness : {0.2f, 0.5f, 0.9f}) {
    for (float theta : {0.0f, 45.0f, 80.0f}) {
      SCOPED_TRACE(testing::Message() << "roughness " << roughness << " theta_o " << theta);
      expect_bsdf_sampling_matches_pdf(conductor(roughness, vec3(0.9f, 0.6f, 0.3f)),
                                       direction(theta), seed++);
    }
  }
}

// Every sample's weight is f |cos| / pdf and its pdf is bsdf_pdf's, to a relative 1e-3. Returns
// the number of valid samples.
int expect_samples_agree_with_eval(const Material& m, vec3 wo, uint32_t seed, int n) {
  Uniform rng(seed);
  int valid = 0, bad = 0;
  for (int i = 0; i < n; ++i) {
    const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
    if (!s.valid) continue;
    ++valid;
    EXPECT_FALSE(s.specular);
    const float pdf = bsdf_pdf(m, wo, s.wi);
    const vec3 f = bsdf_eval(m, wo, s.wi);
    const bool pdf_ok = std::abs(pdf - s.pdf) <= 1e-3f * s.pdf;
    bool weight_ok = pdf > 0.0f;
    for (int c = 0; c < 3 && weight_ok; ++c) {
      const float expected = f[c] * std::abs(s.wi.z) / pdf;
      weight_ok = std::abs(s.weight[c] - expected) <= 1e-3f * std::max(expected, 1e-6f);
    }
    if (!(pdf_ok && weight_ok) && ++bad <= 3) {
      ADD_FAILURE() << "wi " << s.wi.x << " " << s.wi.y << " " << s.wi.z << ": sample pdf " << s.pdf
                    << " vs bsdf_pdf " << pdf << ", weight " << s.weight.x << " vs f cos / pdf "
                    << f.x * std::abs(s.wi.z) / pdf;
    }
  }
  EXPECT_EQ(bad, 0);
  return valid;
}

TEST(RoughConductorTest, SamplesAgreeWithEvalAndPdf) {
  uint32_t seed = 300;
  for (float roughness : {0.05f, 0.2f, 0.5f, 0.9f, 1.0f})
    for (float theta : {0.0f, 30.0f, 60.0f, 80.0f, 88.0f}) {
      SCOPED_TRACE(testing::Message() << "roughness " << roughness << " theta_o " << theta);
      const Material m = conductor(roughness, vec3(0.9f, 0.6f, 0.3f));
      EXPECT_FALSE(bsdf_is_delta(m, m.type));
      EXPECT_GT(expect_samples_agree_with_eval(m, direction(theta), seed++, 20000), 10000);
    }
  const Material m = conductor(0.5f);
  EXPECT_EQ(bsdf_eval(m, direction(30.0f), direction(120.0f)), vec3(0.0f));
  EXPECT_EQ(bsdf_pdf(m, direction(30.0f), direction(120.0f)), 0.0f);
  EXPECT_FALSE(bsdf_sample(m, direction(120.0f), vec2(0.3f), 0.5f).valid);
}

// Directional albedo int f(wo, wi) cos(wi) dwi of the conductor, by quadrature over the half
// vector m (dwi = 4 |wo.m| dm, Walter et al. 2007 eq. 14).
double conductor_albedo(const Material& m, vec3 wo, int ns = 512, int nphi = 256) {
  const vec2 a = conductor_alpha(m);  // spread the nodes over the wider of the two directions
  const double alpha = std::max(a.x, a.y);
  return integrate_normals(
      [&](glm::dvec3 h) {
        const double wo_h = glm::dot(glm::dvec3(wo), h);
        if (wo_h <= 0.0) return 0.0;
        const glm::dvec3 wi = 2.0 * wo_h * h - glm::dvec3(wo);
        if (wi.z <= 0.0) return 0.0;
        return double(bsdf_eval(m, wo, vec3(wi)).x) * wi.z * 4.0 * wo_h;
      },
      alpha, ns, nphi);
}

TEST(RoughConductorTest, WhiteFurnace) {
  // With F0 = 1 the Fresnel term is 1 and f cos integrates to int D_wo(m) G2 / G1(wo) dm <= 1:
  // what single scattering loses is the light that the microsurface sends into itself.
  const std::vector<float> roughnesses = {0.05f, 0.1f, 0.2f, 0.3f, 0.5f, 0.7f, 0.9f, 1.0f};
  const std::vector<float> thetas = {0.0f, 30.0f, 60.0f, 75.0f, 85.0f, 89.0f};
  std::printf("  conductor directional albedo, F0 = 1 (rows: roughness; columns: theta_o)\n      ");
  for (float t : thetas) std::printf("%8.0f", t);
  std::printf("\n");
  std::vector<double> normal;
  for (float r : roughnesses) {
    std::printf("  %4.2f", r);
    for (float t : thetas) {
      const double e = conductor_albedo(conductor(r), direction(t));
      std::printf("%8.4f", e);
      EXPECT_LE(e, 1.0 + 1e-3) << "roughness " << r << " theta " << t;
      EXPECT_GT(e, 0.0);
      if (t == 0.0f) normal.push_back(e);
    }
    std::printf("\n");
  }
  EXPECT_GT(normal.front(), 0.99);  // roughness 0.05 at normal incidence
  for (size_t i = 1; i < normal.size(); ++i) EXPECT_LT(normal[i], normal[i - 1] + 1e-4);
  // The sampler's mean weight estimates the same integral.
  uint32_t seed = 400;
  for (float r : {0.05f, 0.5f, 1.0f})
    for (float t : {0.0f, 60.0f, 85.0f}) {
      const Material m = conductor(r);
      const vec3 wo = direction(t);
      Uniform rng(seed++);
      double sum = 0.0, sum2 = 0.0;
      const int n = 200000;
      for (int i = 0; i < n; ++i) {
        const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
        const double w = s.valid ? s.weight.x : 0.0;
        sum += w;
        sum2 += w * w;
      }
      const double mean = sum / n, se = std::sqrt(std::max(0.0, sum2 / n - mean * mean) / n);
      EXPECT_NEAR(mean, conductor_albedo(m, wo), 5.0 * se + 1e-4)
          << "roughness " << r << " theta " << t;
    }
}

TEST(RoughConductorTest, IsReciprocal) {
  Uniform rng(500);
  for (float roughness : {0.1f, 0.4f, 0.9f}) {
    const Material m = conductor(roughness, vec3(0.9f, 0.6f, 0.3f));
    for (int i = 0; i < 2000; ++i) {
      const vec3 wo = sample_uniform_hemisphere(rng.f2()), wi = sample_uniform_hemisphere(rng.f2());
      if (wo.z < 0.02f || wi.z < 0.02f) continue;
      const vec3 a = bsdf_eval(m, wo, wi), b = bsdf_eval(m, wi, wo);
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(a[c], b[c], 1e-4f * a[c] + 1e-12f);
    }
  }
}

TEST(RoughConductorTest, TendsToTheSmoothConductor) {
  // roughness 0.001 (alpha clamped to 1e-4): directions within 2 degrees of the mirror direction,
  // mean weight within 1% of the smooth conductor's delta weight F(cos theta_o).
  const vec3 f0(0.9f, 0.6f, 0.3f);
  const Material rough = conductor(0.001f, f0), smooth = conductor(0.0f, f0);
  uint32_t seed = 600;
  for (float theta : {0.0f, 45.0f, 75.0f}) {
    SCOPED_TRACE(testing::Message() << "theta_o " << theta);
    const vec3 wo = direction(theta);
    const BsdfSample ref = bsdf_sample(smooth, wo, vec2(0.5f), 0.5f);
    ASSERT_TRUE(ref.valid && ref.specular);
    const vec3 mirror(-wo.x, -wo.y, wo.z);
    EXPECT_EQ(ref.wi, mirror);
    Uniform rng(seed++);
    const int n = 100000;
    int near = 0;
    glm::dvec3 sum(0.0);
    for (int i = 0; i < n; ++i) {
      const BsdfSample s = bsdf_sample(rough, wo, rng.f2(), rng.f());
      if (!s.valid) continue;
      near += angle_deg(glm::dvec3(s.wi), glm::dvec3(mirror)) < 2.0;
      sum += glm::dvec3(s.weight);
    }
    EXPECT_GE(near, 0.99 * n);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(sum[c] / n, ref.weight[c], 0.01 * ref.weight[c]);
  }
}

// ---------------------------------------------------------------------------------------------
// Rough dielectric.

struct DielectricCase {
  float ior, theta;
};
// Entering glass, leaving it below and beyond the critical angle (41.8 degrees from -z), and an
// air bubble in glass (ior < 1) entered from outside.
const DielectricCase kDielectricCases[] = {
    {1.5f, 20.0f}, {1.5f, 70.0f}, {1.5f, 160.0f}, {1.5f, 135.0f}, {1.0f / 1.5f, 30.0f}};

TEST(RoughDielectricTest, SampledDirectionsFollowThePdf) {
  uint32_t seed = 700;
  for (float roughness : {0.3f, 0.7f})
    for (const DielectricCase& c : kDielectricCases) {
      SCOPED_TRACE(testing::Message()
                   << "roughness " << roughness << " ior " << c.ior << " theta_o " << c.theta);
      expect_bsdf_sampling_matches_pdf(dielectric(roughness, c.ior, vec3(1.0f, 0.8f, 0.6f)),
                                       direction(c.theta), seed++);
    }
  SCOPED_TRACE("Schlick Fresnel");
  expect_bsdf_sampling_matches_pdf(dielectric(0.3f, 1.5f, vec3(1.0f), kMaterialSchlickFresnel),
                                   direction(70.0f), seed++);
}

TEST(RoughDielectricTest, SamplesAgreeWithEvalAndPdf) {
  uint32_t seed = 800;
  for (float roughness : {0.05f, 0.3f, 0.7f, 1.0f})
    for (float ior : {1.5f, 1.0f / 1.5f, 2.4f})
      for (float theta : {0.0f, 40.0f, 80.0f, 100.0f, 140.0f, 180.0f}) {
        SCOPED_TRACE(testing::Message()
                     << "roughness " << roughness << " ior " << ior << " theta_o " << theta);
        for (uint32_t flags : {0u, uint32_t(kMaterialSchlickFresnel)}) {
          const Material m = dielectric(roughness, ior, vec3(1.0f, 0.8f, 0.6f), flags);
          EXPECT_FALSE(bsdf_is_delta(m, m.type));
          // Inside a dense glass at roughness 1 over half the samples leave on the wrong side.
          EXPECT_GT(expect_samples_agree_with_eval(m, direction(theta), seed++, 5000), 1000);
        }
      }
}

struct Energy {
  double r = 0.0, t = 0.0;  // reflectance and transmittance, the latter with eta^2 undone
};

// int f cos dwi over each lobe by quadrature over the microfacet normal seen from wo's side, with
// dwi = 4 |wo.m| dm for reflection and dwi = (wi.m + wo.m / eta)^2 / |wi.m| dm for transmission
// (Walter et al. 2007, eq. 14 and 17); refraction here is computed in double, not by the BSDF.
Energy dielectric_energy(const Material& m, vec3 wo, int ns = 512, int nphi = 256) {
  const double alpha = ggx_alpha(m.roughness);
  const double eta = eta_of(m, wo);
  const glm::dvec3 o(wo);
  const double side = wo.z > 0.0f ? 1.0 : -1.0;
  Energy e;
  e.r = integrate_normals(
      [&](glm::dvec3 h) {
        const double o_h = glm::dot(o, h);
        const glm::dvec3 wi = 2.0 * o_h * h - o;
        if (o_h * side <= 0.0 || wi.z * side <= 0.0) return 0.0;
        return double(bsdf_eval(m, wo, vec3(wi)).x) * std::abs(wi.z) * 4.0 * std::abs(o_h);
      },
      alpha, ns, nphi);
  e.t = integrate_normals(
      [&](glm::dvec3 h) {
        const double o_h = glm::dot(o, h);
        if (o_h * side <= 0.0) return 0.0;
        glm::dvec3 wi;
        if (!refract_ref(o, side * h, eta, wi) || wi.z * side >= 0.0) return 0.0;
        const double i_h = glm::dot(wi, h), denom = i_h + o_h / eta;
        return double(bsdf_eval(m, wo, vec3(wi)).x) * std::abs(wi.z) * denom * denom /
               std::abs(i_h) * eta * eta;
      },
      alpha, ns, nphi);
  return e;
}

TEST(RoughDielectricTest, WhiteFurnace) {
  // R + T (radiance scaling undone) = int D_wo(m) [F + (1 - F)] G2 / G1(wo) dm over the normals
  // whose lobe leaves on the right side, so it is <= 1, and it tends to 1 as roughness -> 0.
  const std::vector<float> roughnesses = {0.01f, 0.05f, 0.1f, 0.2f, 0.3f, 0.5f, 0.7f, 0.9f, 1.0f};
  const std::vector<float> thetas = {0.0f, 45.0f, 80.0f, 180.0f, 150.0f, 120.0f};
  std::printf(
      "  dielectric ior 1.5: R + T eta^2 (rows: roughness; columns: theta_o; > 90 inside)"
      "\n      ");
  for (float t : thetas) std::printf("%8.0f", t);
  std::printf("\n");
  std::vector<std::vector<double>> table;
  for (float r : roughnesses) {
    std::printf("  %4.2f", r);
    table.emplace_back();
    for (float t : thetas) {
      const Energy e = dielectric_energy(dielectric(r), direction(t));
      const double total = e.r + e.t;
      table.back().push_back(total);
      std::printf("%8.4f", total);
      EXPECT_LE(total, 1.0 + 1e-3) << "roughness " << r << " theta " << t;
    }
    std::printf("\n");
  }
  // Energy -> 1 as roughness -> 0 (at roughness 0.01 the loss is below 1e-4 at every angle), and
  // at normal incidence from either side the loss grows with roughness. That is not a theorem,
  // but holds for GGX, whose microsurface only gets steeper; these are regression bounds on the
  // quadrature of a deterministic function, with 1e-4 of slack for the quadrature.
  for (size_t j = 0; j < thetas.size(); ++j) {
    EXPECT_GT(table[0][j], 0.999) << "theta " << thetas[j];
  }
  for (size_t j : {size_t(0), size_t(3)}) {
    for (size_t i = 1; i < roughnesses.size(); ++i)
      EXPECT_LT(table[i][j], table[i - 1][j] + 1e-4)
          << "roughness " << roughnesses[i] << " theta " << thetas[j];
  }
  // From outside at normal incidence the loss at roughness 1 (alpha 1) stays below 15% (it is
  // 10.7%). From inside it is far larger (58%): F = 1 beyond the critical angle of each facet, and
  // much of what the facets reflect or refract heads back into the surface, which a single-
  // scattering model drops (the conductor's table shows the same effect: 69% at alpha = 1).
  EXPECT_GT(table.back()[0], 0.85);
  EXPECT_GT(table.back()[3], 0.35);
  // The sampler's mean weight estimates the same integrals, lobe by lobe.
  uint32_t seed = 900;
  for (float r : {0.05f, 0.5f, 1.0f})
    for (float t : {0.0f, 70.0f, 170.0f, 130.0f}) {
      SCOPED_TRACE(testing::Message() << "roughness " << r << " theta " << t);
      const Material m = dielectric(r);
      const vec3 wo = direction(t);
      const float eta = eta_of(m, wo);
      const Energy e = dielectric_energy(m, wo);
      Uniform rng(seed++);
      double sr = 0.0, sr2 = 0.0, st = 0.0, st2 = 0.0;
      const int n = 200000;
      for (int i = 0; i < n; ++i) {
        const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
        if (!s.valid) continue;
        const double w = s.weight.x;
        if (s.wi.z * wo.z > 0.0f) {
          sr += w;
          sr2 += w * w;
        } else {
          st += w * eta * eta;
          st2 += (w * eta * eta) * (w * eta * eta);
        }
      }
      const double mr = sr / n, mt = st / n;
      const double ser = std::sqrt(std::max(0.0, sr2 / n - mr * mr) / n);
      const double set = std::sqrt(std::max(0.0, st2 / n - mt * mt) / n);
      EXPECT_NEAR(mr, e.r, 5.0 * ser + 1e-4);
      EXPECT_NEAR(mt, e.t, 5.0 * set + 1e-4);
    }
}

TEST(RoughDielectricTest, TendsToTheSmoothDielectric) {
  // roughness 0.001: 99% of the directions within 2 degrees of the mirror or Snell direction, the
  // reflected fraction is F, and the mean weight is the smooth dielectric's expected weight
  // F + (1 - F) albedo / eta^2 within 1%.
  const vec3 albedo(1.0f, 0.8f, 0.6f);
  const Material rough = dielectric(0.001f, 1.5f, albedo);
  uint32_t seed = 1000;
  for (float theta : {0.0f, 40.0f, 70.0f, 180.0f, 150.0f, 130.0f}) {
    SCOPED_TRACE(testing::Message() << "theta_o " << theta);
    const vec3 wo = direction(theta);
    const double eta = eta_of(rough, wo);
    const double F = fresnel_dielectric(std::abs(wo.z), float(eta));
    const glm::dvec3 mirror(-wo.x, -wo.y, wo.z);
    glm::dvec3 snell(0.0);
    const bool can_refract =
        refract_ref(glm::dvec3(wo), glm::dvec3(0, 0, wo.z > 0.0f ? 1 : -1), eta, snell);
    Uniform rng(seed++);
    const int n = 100000;
    int near = 0, reflected = 0;
    glm::dvec3 sum(0.0);
    for (int i = 0; i < n; ++i) {
      const BsdfSample s = bsdf_sample(rough, wo, rng.f2(), rng.f());
      if (!s.valid) continue;
      sum += glm::dvec3(s.weight);
      if (s.wi.z * wo.z > 0.0f) {
        ++reflected;
        near += angle_deg(glm::dvec3(s.wi), mirror) < 2.0;
      } else {
        near += can_refract && angle_deg(glm::dvec3(s.wi), snell) < 2.0;
      }
    }
    EXPECT_GE(near, 0.99 * n);
    EXPECT_NEAR(double(reflected) / n, F, 5.0 * std::sqrt(F * (1.0 - F) / n) + 1e-3);
    for (int c = 0; c < 3; ++c) {
      const double expected = F + (1.0 - F) * albedo[c] / (eta * eta);
      EXPECT_NEAR(sum[c] / n, expected, 0.01 * expected) << "channel " << c;
    }
  }
}

TEST(RoughDielectricTest, IsReciprocal) {
  // Reflection: f(wo, wi) = f(wi, wo). Transmission, in the radiance form used here (Veach 1997,
  // sec. 5.2): f(wo, wi) / n(wo)^2 = f(wi, wo) / n(wi)^2, n(w) the index of the medium w lies in.
  Uniform rng(1100);
  for (float roughness : {0.1f, 0.4f, 0.9f})
    for (uint32_t flags : {0u, uint32_t(kMaterialSchlickFresnel)}) {
      const Material m = dielectric(roughness, 1.5f, vec3(0.9f, 0.7f, 0.5f), flags);
      int checked_r = 0, checked_t = 0;
      for (int i = 0; i < 4000; ++i) {
        const vec3 wo = sample_uniform_sphere(rng.f2()), wi = sample_uniform_sphere(rng.f2());
        if (std::abs(wo.z) < 0.05f || std::abs(wi.z) < 0.05f) continue;
        const vec3 a = bsdf_eval(m, wo, wi), b = bsdf_eval(m, wi, wo);
        const float n_o = wo.z > 0.0f ? 1.0f : m.ior, n_i = wi.z > 0.0f ? 1.0f : m.ior;
        const bool reflect = wo.z * wi.z > 0.0f;
        (reflect ? checked_r : checked_t) += a.x > 0.0f;
        for (int c = 0; c < 3; ++c) {
          const float lhs = a[c] / (n_o * n_o), rhs = b[c] / (n_i * n_i);
          // Relative 2e-3, or 1e-6 absolute: where a facet sits at the critical angle on the
          // dense side, 1 - F there is a difference of nearly equal floats (F ~ 0.998), while
          // from the thin side it is computed at grazing; both give values ~1e-9 there.
          ASSERT_NEAR(lhs, rhs, 2e-3f * std::max(lhs, rhs) + 1e-6f)
              << (reflect ? "reflection" : "transmission") << " roughness " << roughness << " wo "
              << wo.z << " wi " << wi.z;
        }
      }
      EXPECT_GT(checked_r, 100);
      EXPECT_GT(checked_t, 100);
    }
}

// ---------------------------------------------------------------------------------------------
// Anisotropic GGX and the complex-IOR conductor.

TEST(AnisotropicGgxTest, DistributionAndVisibleNormalsIntegrateToOne) {
  const vec2 alphas[] = {vec2(0.05f, 0.4f), vec2(0.5f, 0.1f), vec2(0.3f, 1.0f)};
  for (const vec2 a : alphas) {
    const double lo = std::min(a.x, a.y);
    const double total = integrate_normals(
        [&](glm::dvec3 m) { return double(ggx_d(vec3(m), a)) * m.z; }, lo, 2048, 1024);
    EXPECT_NEAR(total, 1.0, 1e-3) << a.x << " " << a.y;
    for (float theta : {0.0f, 45.0f, 80.0f})
      for (float phi : {0.0f, 0.7f, 1.5708f}) {
        const vec3 wo = direction(theta, phi);
        const double vis = integrate_normals(
            [&](glm::dvec3 m) { return double(ggx_vndf_pdf(wo, vec3(m), a)); }, lo, 1024, 1024);
        EXPECT_NEAR(vis, 1.0, 2e-3) << a.x << " " << a.y << " theta " << theta << " phi " << phi;
      }
  }
  // Isotropic alpha pairs are the isotropic functions.
  const vec3 m = glm::normalize(vec3(0.3f, -0.2f, 0.9f)), w = direction(50.0f);
  EXPECT_NEAR(ggx_d(m, vec2(0.3f)), ggx_d(m, 0.3f), 1e-6f * ggx_d(m, 0.3f));
  EXPECT_NEAR(ggx_lambda(w, vec2(0.3f)), ggx_lambda(w, 0.3f), 1e-7f);
}

TEST(AnisotropicGgxTest, VisibleNormalSamplingMatchesItsPdf) {
  uint32_t seed = 1200;
  for (const vec2 a : {vec2(0.1f, 0.6f), vec2(0.8f, 0.2f)})
    for (float theta : {30.0f, 75.0f}) {
      SCOPED_TRACE(testing::Message() << "alpha " << a.x << ", " << a.y << " theta " << theta);
      const vec3 wo = direction(theta, 0.4f);
      Uniform rng(seed++);
      auto sample = [&](glm::dvec3& m) {
        m = glm::dvec3(ggx_sample_vndf(wo, a, rng.f2()));
        return true;
      };
      auto pdf = [&](glm::dvec3 m) { return double(ggx_vndf_pdf(wo, vec3(m), a)); };
      const chi2::Result r = chi2::sphere_chi_square(sample, pdf, kChiSamples, bins_for(wo),
                                                     kSignificance, kChiSquareTests);
      EXPECT_TRUE(r.passed) << r.message;
      EXPECT_NEAR(r.pdf_integral, 1.0, 2e-3);
    }
}

TEST(IorConductorTest, SampledDirectionsFollowThePdf) {
  uint32_t seed = 1300;
  const Material cases[] = {ior_conductor(0.3f), ior_conductor(0.2f, 0.7f),
                            ior_conductor(0.8f, 0.25f), ior_conductor(0.5f, 0.2f)};
  for (const Material& m : cases) {
    SCOPED_TRACE(testing::Message() << "roughness " << m.roughness << ", " << m.roughness_v);
    expect_bsdf_sampling_matches_pdf(m, direction(50.0f, 1.1f), seed++);
  }
}

TEST(IorConductorTest, SamplesAgreeWithEvalAndPdf) {
  uint32_t seed = 1400;
  for (const vec2 r : {vec2(0.05f, 0.05f), vec2(0.3f, -1.0f), vec2(0.1f, 0.6f), vec2(0.9f, 0.2f)})
    for (float theta : {0.0f, 40.0f, 80.0f})
      for (float phi : {0.0f, 0.8f, 1.5708f}) {
        SCOPED_TRACE(testing::Message() << "roughness " << r.x << ", " << r.y << " theta_o "
                                        << theta << " phi " << phi);
        const Material m = ior_conductor(r.x, r.y);
        EXPECT_FALSE(bsdf_is_delta(m, m.type));
        EXPECT_GT(expect_samples_agree_with_eval(m, direction(theta, phi), seed++, 5000), 2500);
      }
}

TEST(IorConductorTest, SmoothReflectsTheExactFresnelTintedByAlbedo) {
  Material m = ior_conductor(0.0f);
  m.albedo = vec3(1.0f, 0.5f, 0.25f);
  EXPECT_TRUE(bsdf_is_delta(m, m.type));
  for (float theta : {0.0f, 45.0f, 80.0f, 89.0f}) {
    const vec3 wo = direction(theta);
    const BsdfSample s = bsdf_sample(m, wo, vec2(0.5f), 0.5f);
    ASSERT_TRUE(s.valid && s.specular);
    EXPECT_EQ(s.wi, vec3(-wo.x, -wo.y, wo.z));
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(s.weight[c], m.albedo[c] * fresnel_conductor(wo.z, m.eta[c], m.k[c]), 1e-6f);
  }
  // Gold at normal incidence: the F0 its RGB triple was fitted to (metals.h).
  const BsdfSample s = bsdf_sample(ior_conductor(0.0f), direction(0.0f), vec2(0.5f), 0.5f);
  EXPECT_NEAR(s.weight.x, 0.972f, 1e-3f);
  EXPECT_NEAR(s.weight.y, 0.789f, 1e-3f);
  EXPECT_NEAR(s.weight.z, 0.342f, 1e-3f);
}

TEST(IorConductorTest, AnisotropyTurnsWithTheFrame) {
  // Swapping u and v is a quarter turn of the frame: f_{u,v}(R wo, R wi) = f_{v,u}(wo, wi) with R
  // the rotation by 90 degrees about z. And the lobe does depend on the azimuth: the albedo at
  // 70 degrees differs between looking along u and along v.
  const Material uv = ior_conductor(0.15f, 0.6f), vu = ior_conductor(0.6f, 0.15f);
  EXPECT_TRUE(uv.is_anisotropic());
  EXPECT_FALSE(ior_conductor(0.3f, 0.3f).is_anisotropic());
  EXPECT_FALSE(ior_conductor(0.3f).is_anisotropic());
  auto rot = [](vec3 w) { return vec3(-w.y, w.x, w.z); };
  Uniform rng(1500);
  for (int i = 0; i < 2000; ++i) {
    const vec3 wo = sample_uniform_hemisphere(rng.f2()), wi = sample_uniform_hemisphere(rng.f2());
    if (wo.z < 0.02f || wi.z < 0.02f) continue;
    const vec3 a = bsdf_eval(uv, rot(wo), rot(wi)), b = bsdf_eval(vu, wo, wi);
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(a[c], b[c], 1e-4f * b[c] + 1e-9f);
    ASSERT_NEAR(bsdf_pdf(uv, rot(wo), rot(wi)), bsdf_pdf(vu, wo, wi),
                1e-4f * bsdf_pdf(vu, wo, wi) + 1e-9f);
    // Reciprocal, as the isotropic one.
    const vec3 r = bsdf_eval(uv, wi, wo);
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(bsdf_eval(uv, wo, wi)[c], r[c], 1e-4f * r[c] + 1e-9f);
  }
  // Smooth along u, rough along v: the lobe of a view along u is narrow, along v wide.
  Material f1 = conductor(0.15f);
  f1.roughness_v = 0.6f;
  const double along_u = conductor_albedo(f1, direction(75.0f, 0.0f));
  const double along_v = conductor_albedo(f1, direction(75.0f, 1.5708f));
  EXPECT_GT(along_u - along_v, 0.02) << along_u << " vs " << along_v;  // 0.901 vs 0.865
  // The shading frame of an anisotropic material follows the world y axis on the surface.
  const vec3 n = glm::normalize(vec3(0.3f, 0.2f, 0.9f));
  const Frame fr = bsdf_frame(uv, uv.type, n);
  EXPECT_NEAR(glm::dot(fr.t, glm::normalize(kAnisotropyAxis - glm::dot(kAnisotropyAxis, n) * n)),
              1.0f, 1e-5f);
  EXPECT_NEAR(glm::dot(glm::cross(fr.t, fr.b), n), 1.0f, 1e-5f);
  const Frame iso = bsdf_frame(conductor(0.3f), MaterialType::kConductor, n);
  const Frame plain = Frame::from_normal(n);
  EXPECT_EQ(iso.t, plain.t);
}

TEST(IorConductorTest, WhiteFurnaceAnisotropic) {
  // With F = 1 (Schlick F0 = 1) anisotropic GGX loses only what single scattering loses: the
  // albedo stays <= 1, and the sampler's mean weight estimates the same integral. (It is not
  // bounded by the isotropic albedos of its two roughnesses: at 85 degrees along the smooth
  // direction of (0.3, 0.9) it is 0.619, below both 0.886 and 0.816.)
  uint32_t seed = 1600;
  for (const vec2 r : {vec2(0.1f, 0.5f), vec2(0.3f, 0.9f)})
    for (float theta : {0.0f, 60.0f, 85.0f})
      for (float phi : {0.0f, 0.8f, 1.5708f}) {
        SCOPED_TRACE(testing::Message()
                     << "roughness " << r.x << ", " << r.y << " theta " << theta << " phi " << phi);
        Material m = conductor(r.x);
        m.roughness_v = r.y;
        const vec3 wo = direction(theta, phi);
        // The lobe is a ridge along the rough direction: many azimuths resolve it.
        const double e = conductor_albedo(m, wo, 512, 4096);
        EXPECT_LE(e, 1.0 + 1e-3);
        EXPECT_GT(e, 0.5);
        Uniform rng(seed++);
        double sum = 0.0, sum2 = 0.0;
        const int n = 100000;
        for (int i = 0; i < n; ++i) {
          const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
          const double w = s.valid ? s.weight.x : 0.0;
          sum += w;
          sum2 += w * w;
        }
        const double mean = sum / n, se = std::sqrt(std::max(0.0, sum2 / n - mean * mean) / n);
        EXPECT_NEAR(mean, e, 5.0 * se + 1e-3);
      }
}

}  // namespace
}  // namespace tracer
