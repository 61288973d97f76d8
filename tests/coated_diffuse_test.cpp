// Tests for the coated diffuse ("plastic") of materials/bsdf.h: Mitsuba's three (eval and pdf
// agree with sample, chi-square of sampling, for smooth and rough coats), reciprocity, and the
// model's energy: with a clear smooth coat over a white base the directional albedo is 1, an
// absorbing coat loses what the model's formula says, and a rough coat's error is measured and
// bounded (the table is printed; the model and its stated error are in bsdf.h).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "chi_square.h"
#include "core/math.h"
#include "core/sampling.h"
#include "materials/bsdf.h"
#include "materials/fresnel.h"
#include "materials/material.h"

namespace tracer {
namespace {

// Sidak correction over all chi-square tests in this executable: 8 direction tests and 4 tests
// of the smooth coat's lobe choice.
constexpr double kSignificance = 0.01;
constexpr int kChiSquareTests = 12;
constexpr size_t kSamples = 1000000;

using chi2::direction;
using chi2::Uniform;

Material plastic(vec3 albedo, float roughness = 0.0f, float ior = 1.5f) {
  Material m;
  m.type = MaterialType::kCoatedDiffuse;
  m.albedo = albedo;
  m.roughness = roughness;
  m.ior = ior;
  return m;
}

// Fresnel reflectance of a dielectric in double, independent of fresnel.h (the angle form).
double fresnel_ref(double cos_i, double eta) {
  const double sin_i = std::sqrt(std::max(0.0, 1.0 - cos_i * cos_i));
  const double sin_t = sin_i / eta;
  if (sin_t >= 1.0) return 1.0;
  if (sin_i == 0.0) return ((eta - 1.0) / (eta + 1.0)) * ((eta - 1.0) / (eta + 1.0));
  const double ti = std::asin(sin_i), tt = std::asin(sin_t);
  const double rs = std::sin(ti - tt) / std::sin(ti + tt);
  const double rp = std::tan(ti - tt) / std::tan(ti + tt);
  return 0.5 * (rs * rs + rp * rp);
}

// int f(wo, wi) cos dwi over the hemisphere of the non-delta lobes, channel c: the base by the
// midpoint rule in (cos, phi), a rough coat's lobe by quadrature over the half vector (dwi =
// 4 |wo.m| dm, Walter et al. 2007 eq. 14) with the substitution theta = atan(alpha tan s).
double base_albedo(const Material& m, vec3 wo, int c, int n = 400) {
  Material base = m;
  base.roughness = 0.0f;  // the base term alone
  double sum = 0.0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < 2 * n; ++j) {
      const double mu = (i + 0.5) / n, phi = (j + 0.5) * M_PI / n;
      const double s = std::sqrt(1.0 - mu * mu);
      const vec3 wi(float(s * std::cos(phi)), float(s * std::sin(phi)), float(mu));
      sum += double(bsdf_eval(base, wo, wi)[c]) * mu;
    }
  return sum * (1.0 / n) * (M_PI / n);
}

double coat_albedo(const Material& m, vec3 wo, int ns = 512, int nphi = 256) {
  if (m.roughness <= 0.0f) return fresnel_ref(wo.z, m.ior);  // the delta lobe's weight
  const double alpha = ggx_alpha(m.roughness);
  Material rough = m, smooth = m;  // white, so that channel 0 is the coat lobe's (grey) albedo
  rough.albedo = smooth.albedo = vec3(1.0f);
  smooth.roughness = 0.0f;
  double sum = 0.0;
  const double ds = 0.5 * M_PI / ns, dphi = 2.0 * M_PI / nphi;
  for (int i = 0; i < ns; ++i) {
    const double s = (i + 0.5) * ds, t = std::tan(s);
    const double theta = std::atan(alpha * t);
    const double jac = alpha * (1.0 + t * t) / (1.0 + alpha * alpha * t * t);
    const double st = std::sin(theta), ct = std::cos(theta);
    for (int j = 0; j < nphi; ++j) {
      const double phi = (j + 0.5) * dphi;
      const glm::dvec3 h(st * std::cos(phi), st * std::sin(phi), ct);
      const double wo_h = glm::dot(glm::dvec3(wo), h);
      if (wo_h <= 0.0) continue;
      const glm::dvec3 wi = 2.0 * wo_h * h - glm::dvec3(wo);
      if (wi.z <= 0.0) continue;
      // The coat lobe alone: f less the base term (which does not depend on the roughness).
      const double coat =
          double(bsdf_eval(rough, wo, vec3(wi)).x) - double(bsdf_eval(smooth, wo, vec3(wi)).x);
      sum += coat * wi.z * 4.0 * wo_h * st * jac * ds * dphi;
    }
  }
  return sum;
}

double albedo(const Material& m, vec3 wo, int c) {
  return coat_albedo(m, wo) + base_albedo(m, wo, c);
}

chi2::SphereBins upper_bins() {
  chi2::SphereBins bins;
  bins.z_res = 48;
  bins.phi_res = 96;
  bins.z_lo = 0.0;  // every direction lies above the surface
  bins.integration_res = 6;
  return bins;
}

// ---------------------------------------------------------------------------------------------

TEST(CoatedDiffuseTest, SampledDirectionsFollowThePdf) {
  // Rough coats: the mixture of the coat's visible-normal lobe and the cosine. Smooth coats: the
  // samples that are not the delta lobe follow pdf, which integrates to 1 - P.
  uint32_t seed = 1;
  const Material cases[] = {plastic(vec3(0.8f, 0.1f, 0.1f), 0.3f),
                            plastic(vec3(0.05f), 0.15f, 1.8f),
                            plastic(vec3(0.9f, 0.9f, 0.2f), 0.7f), plastic(vec3(0.6f), 0.0f)};
  for (const Material& m : cases)
    for (float theta : {10.0f, 70.0f}) {
      SCOPED_TRACE(testing::Message() << "roughness " << m.roughness << " theta_o " << theta);
      const vec3 wo = direction(theta);
      Uniform rng(seed++);
      size_t kept = 0;
      auto sample = [&](glm::dvec3& w) {
        const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
        w = glm::dvec3(s.wi);
        const bool keep = s.valid && !s.specular;
        kept += keep;
        return keep;
      };
      auto pdf = [&](glm::dvec3 w) { return double(bsdf_pdf(m, wo, vec3(w))); };
      chi2::SphereBins bins = upper_bins();
      if (m.roughness > 0.0f && m.roughness < 0.2f) {  // a narrow coat lobe: finer cells
        bins.z_res = 96;
        bins.phi_res = 192;
      }
      const chi2::Result r =
          chi2::sphere_chi_square(sample, pdf, kSamples, bins, kSignificance, kChiSquareTests);
      EXPECT_TRUE(r.passed) << r.message;
      const double frac = double(kept) / kSamples;
      EXPECT_NEAR(r.pdf_integral, frac, 5.0 * std::sqrt(frac * (1.0 - frac) / kSamples) + 2e-3)
          << r.message;
    }
}

TEST(CoatedDiffuseTest, SmoothCoatIsChosenWithItsProbability) {
  // The delta lobe is taken with probability P = F / (F + (1 - F) B), and its weight is F / P, so
  // that its expected contribution is F whatever P.
  uint32_t seed = 20;
  for (const Material& m : {plastic(vec3(0.7f, 0.2f, 0.1f)), plastic(vec3(0.02f), 0.0f, 1.3f)})
    for (float theta : {0.0f, 80.0f}) {
      const vec3 wo = direction(theta);
      const double p = coat_at_wo(m, wo).p;
      const double f = fresnel_ref(wo.z, m.ior);
      Uniform rng(seed++);
      double coat = 0.0;
      int bad = 0;
      for (size_t i = 0; i < kSamples; ++i) {
        const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
        if (!s.specular) continue;
        coat += 1.0;
        bad += s.wi != vec3(-wo.x, -wo.y, wo.z) || std::abs(s.pdf - p) > 1e-6 ||
               std::abs(s.weight.x - f / p) > 1e-4 * f / p;
      }
      EXPECT_EQ(bad, 0);
      const chi2::Result r =
          chi2::chi_square_test({coat, kSamples - coat}, {kSamples * p, kSamples * (1.0 - p)},
                                kSignificance, kChiSquareTests, 0.0);
      EXPECT_TRUE(r.passed) << "coat chosen " << coat / kSamples << " vs P " << p << ": "
                            << r.message;
    }
}

TEST(CoatedDiffuseTest, SamplesAgreeWithEvalAndPdf) {
  Uniform rng(30);
  for (float roughness : {0.0f, 0.05f, 0.3f, 1.0f})
    for (uint32_t flags : {0u, uint32_t(kMaterialSchlickFresnel)})
      for (float theta : {0.0f, 45.0f, 85.0f}) {
        SCOPED_TRACE(testing::Message()
                     << "roughness " << roughness << " flags " << flags << " theta " << theta);
        Material m = plastic(vec3(0.8f, 0.3f, 0.05f), roughness);
        m.flags = flags;
        m.absorption = vec3(0.0f, 0.5f, 2.0f);
        m.thickness = 0.3f;
        EXPECT_FALSE(bsdf_is_delta(m, m.type));
        EXPECT_TRUE(bsdf_chooses_lobe(m.type));
        const vec3 wo = direction(theta, 1.3f);
        int bad = 0, diffuse = 0;
        for (int i = 0; i < 20000; ++i) {
          const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
          if (!s.valid || s.specular) continue;
          ++diffuse;
          const float pdf = bsdf_pdf(m, wo, s.wi);
          const vec3 f = bsdf_eval(m, wo, s.wi);
          bool ok = std::abs(pdf - s.pdf) <= 1e-4f * s.pdf && s.wi.z > 0.0f;
          for (int c = 0; c < 3; ++c) {
            const float expected = f[c] * s.wi.z / pdf;
            ok = ok && std::abs(s.weight[c] - expected) <= 1e-4f * std::max(expected, 1e-6f);
          }
          bad += !ok;
        }
        EXPECT_EQ(bad, 0);
        EXPECT_GT(diffuse, 2000);
      }
  // One-sided: nothing below the surface, from either direction.
  const Material m = plastic(vec3(0.5f), 0.3f);
  EXPECT_EQ(bsdf_eval(m, direction(30.0f), direction(120.0f)), vec3(0.0f));
  EXPECT_EQ(bsdf_pdf(m, direction(120.0f), direction(30.0f)), 0.0f);
  EXPECT_FALSE(bsdf_sample(m, direction(120.0f), vec2(0.3f), 0.5f).valid);
}

TEST(CoatedDiffuseTest, IsReciprocal) {
  Uniform rng(40);
  for (float roughness : {0.0f, 0.2f, 0.8f}) {
    Material m = plastic(vec3(0.9f, 0.5f, 0.1f), roughness, 1.6f);
    m.absorption = vec3(0.2f, 0.0f, 1.0f);
    for (int i = 0; i < 2000; ++i) {
      const vec3 wo = sample_uniform_hemisphere(rng.f2()), wi = sample_uniform_hemisphere(rng.f2());
      if (wo.z < 0.02f || wi.z < 0.02f) continue;
      const vec3 a = bsdf_eval(m, wo, wi), b = bsdf_eval(m, wi, wo);
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(a[c], b[c], 1e-5f * std::max(a[c], b[c]) + 1e-9f);
    }
  }
}

TEST(CoatedDiffuseTest, ClearSmoothCoatOverWhiteConservesEnergy) {
  // The white furnace of the model: rho = 1, no absorption: F + int f_base cos = 1 at every
  // angle, for any index and with Schlick's Fresnel too (quadrature to 2e-4).
  for (float ior : {1.1f, 1.33f, 1.5f, 2.0f, 3.0f})
    for (uint32_t flags : {0u, uint32_t(kMaterialSchlickFresnel)})
      for (float theta : {0.0f, 30.0f, 60.0f, 80.0f, 89.0f}) {
        Material m = plastic(vec3(1.0f), 0.0f, ior);
        m.flags = flags;
        const vec3 wo = direction(theta);
        const double f = flags ? double(fresnel_schlick(wo.z, ior)) : fresnel_ref(wo.z, ior);
        const double e = f + base_albedo(m, wo, 0);
        EXPECT_NEAR(e, 1.0, 2e-4) << "ior " << ior << " schlick " << flags << " theta " << theta;
      }
  // A grey base keeps rho (1 - F_in) / (1 - rho F_in) of what enters: less than rho, since light
  // bounces between base and coat.
  const Material grey = plastic(vec3(0.5f));
  const double f_in = fresnel_average_inside(1.5f, false);
  const vec3 wo = direction(20.0f);
  const double entered = 1.0 - fresnel_ref(wo.z, 1.5);
  EXPECT_NEAR(base_albedo(grey, wo, 0), entered * 0.5 * (1.0 - f_in) / (1.0 - 0.5 * f_in), 2e-4);
}

TEST(CoatedDiffuseTest, AbsorbingCoatLosesWhatTheModelSays) {
  // T(w) = exp(-sigma_a d / cos_t) on the way in and out: the base's albedo is
  // (1 - F(wo)) T(wo) rho / (1 - rho F_in) * int (1 - F(mu)) T(mu) 2 mu dmu / eta^2, computed
  // here from Snell's law and Fresnel's equations in double.
  for (float sigma : {0.1f, 0.5f, 2.0f}) {
    Material m = plastic(vec3(1.0f, 0.6f, 0.2f));
    m.absorption = vec3(sigma, 0.0f, 4.0f * sigma);
    m.thickness = 0.5f;
    const double eta = 1.5, f_in = fresnel_average_inside(1.5f, false);
    auto trans = [&](double mu, int c) {
      const double cos_t = std::sqrt(1.0 - (1.0 - mu * mu) / (eta * eta));
      return std::exp(-double(m.absorption[c]) * m.thickness / cos_t);
    };
    for (float theta : {0.0f, 50.0f, 85.0f}) {
      const vec3 wo = direction(theta);
      for (int c = 0; c < 3; ++c) {
        const double rho = m.albedo[c];
        double out = 0.0;
        const int n = 100000;
        for (int i = 0; i < n; ++i) {
          const double mu = (i + 0.5) / n;
          out += (1.0 - fresnel_ref(mu, eta)) * trans(mu, c) * 2.0 * mu / n;
        }
        const double expected = (1.0 - fresnel_ref(wo.z, eta)) * trans(wo.z, c) * rho /
                                (1.0 - rho * f_in) * out / (eta * eta);
        EXPECT_NEAR(base_albedo(m, wo, c), expected, 2e-4 + 1e-3 * expected)
            << "sigma " << sigma << " theta " << theta << " channel " << c;
        if (c == 0 && theta == 0.0f) {
          std::printf("  absorption %.1f x thickness 0.5: base albedo %.4f (clear: %.4f)\n", sigma,
                      expected, 1.0 - fresnel_ref(1.0, eta));
        }
      }
    }
  }
}

TEST(CoatedDiffuseTest, RoughCoatErrorIsBounded) {
  // A rough coat's lobe reflects the rough dielectric's directional albedo while the base still
  // receives 1 - F(wo.z) of the smooth interface: with rho = 1 the total is not exactly 1. Near
  // normal incidence the two nearly agree; toward grazing the rough lobe loses much of F to
  // masking and to directions under the horizon. The table is the model's stated error (bsdf.h,
  // docs/SCENE_FORMAT.md); the last column is the cosine-weighted average over all directions,
  // what a white furnace of uniform light sees. The bounds are regression bounds of a
  // deterministic quadrature.
  const std::vector<float> roughnesses = {0.05f, 0.1f, 0.2f, 0.3f, 0.5f, 0.7f, 1.0f};
  const std::vector<float> thetas = {0.0f, 30.0f, 60.0f, 75.0f, 85.0f};
  std::printf("  coated diffuse, rho = 1, ior 1.5: directional albedo (rows: roughness)\n      ");
  for (float t : thetas) std::printf("%8.0f", t);
  std::printf("     avg\n");
  for (float r : roughnesses) {
    std::printf("  %4.2f", r);
    const Material m = plastic(vec3(1.0f), r);
    double worst_gain = 0.0, worst_loss_60 = 0.0;
    for (float t : thetas) {
      const double e = albedo(m, direction(t), 0);
      std::printf("%8.4f", e);
      worst_gain = std::max(worst_gain, e - 1.0);
      if (t <= 60.0f) worst_loss_60 = std::max(worst_loss_60, 1.0 - e);
    }
    // int E(mu) 2 mu dmu by the midpoint rule in mu (E is smooth in mu).
    double avg = 0.0;
    const int n = 16;
    for (int i = 0; i < n; ++i) {
      const double mu = (i + 0.5) / n;
      avg += albedo(m, vec3(float(std::sqrt(1.0 - mu * mu)), 0.0f, float(mu)), 0) * 2.0 * mu / n;
    }
    std::printf("%8.4f\n", avg);
    EXPECT_LT(worst_gain, 1e-3) << "roughness " << r;
    // Up to 60 degrees the loss stays small (0.3% at roughness 0.3, 6.6% at 1).
    EXPECT_LT(worst_loss_60, r <= 0.3f ? 0.005 : 0.07) << "roughness " << r;
    EXPECT_GT(avg, r <= 0.3f ? 0.97 : 0.85) << "roughness " << r;
  }
}

TEST(CoatedDiffuseTest, SamplerWeightsEstimateTheAlbedo) {
  // The mean sample weight (delta lobe included) is the directional albedo, for smooth and rough
  // coats, coloured and absorbing.
  uint32_t seed = 50;
  for (float roughness : {0.0f, 0.1f, 0.6f})
    for (float theta : {0.0f, 60.0f, 85.0f}) {
      Material m = plastic(vec3(0.9f, 0.4f, 0.05f), roughness);
      m.absorption = vec3(0.0f, 0.3f, 0.0f);
      const vec3 wo = direction(theta);
      Uniform rng(seed++);
      glm::dvec3 sum(0.0), sum2(0.0);
      const int n = 200000;
      for (int i = 0; i < n; ++i) {
        const BsdfSample s = bsdf_sample(m, wo, rng.f2(), rng.f());
        const glm::dvec3 w = s.valid ? glm::dvec3(s.weight) : glm::dvec3(0.0);
        sum += w;
        sum2 += w * w;
      }
      for (int c = 0; c < 3; ++c) {
        const double mean = sum[c] / n;
        const double se = std::sqrt(std::max(0.0, sum2[c] / n - mean * mean) / n);
        EXPECT_NEAR(mean, albedo(m, wo, c), 5.0 * se + 5e-4)
            << "roughness " << roughness << " theta " << theta << " channel " << c;
      }
    }
}

}  // namespace
}  // namespace tracer
