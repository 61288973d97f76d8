// Statistical image tests on the built-in Cornell box: a render agrees with an independent
// high-spp reference (per-pixel z-test, chi-square of the z-scores and a relMSE bound) while a
// deliberately wrong scene fails the same checks; NEE/MIS/roulette never move the mean; the CPU
// backend is deterministic for any thread count.
#include <gtest/gtest.h>

#include <cstdio>

#include "cpu/cpu_backend.h"
#include "image/convergence.h"
#include "image/image.h"
#include "scene/loader.h"
#include "scene_builders.h"

namespace {
using namespace test;

struct Agreement {
  double chi2_per_dof;  // mean of z^2: 1 for agreement
  double chi2_limit;    // 1 + 5 standard deviations of that mean under agreement
  int outliers;         // pixels beyond the Sidak-corrected |z|
  double relmse, relmse_expected;
};

// Compares two independent renders block by block (4x4 pixels): block means are close to normal
// even where single pixels see rare bright paths, and their variances are well estimated, so
// the z-scores follow the normal law when both renders have the same expectation.
Agreement agreement(const PixelStats& a, const PixelStats& b) {
  constexpr int kBlock = 4;
  Agreement g{};
  const int bw = a.width / kBlock, bh = a.height / kBlock;
  const size_t n = size_t(bw) * bh * 3;
  const double zmax = sidak_z(1e-3, n);
  double z2 = 0.0, rel = 0.0, rel_exp = 0.0;
  for (int by = 0; by < bh; ++by) {
    for (int bx = 0; bx < bw; ++bx) {
      for (int c = 0; c < 3; ++c) {
        double ma = 0, mb = 0, va = 0, vb = 0;
        for (int y = by * kBlock; y < (by + 1) * kBlock; ++y) {
          for (int x = bx * kBlock; x < (bx + 1) * kBlock; ++x) {
            const size_t i = size_t(y) * a.width + x;
            ma += a.mean[i][c];
            mb += b.mean[i][c];
            va += a.var[i][c] / a.spp;
            vb += b.var[i][c] / b.spp;
          }
        }
        constexpr double k2 = kBlock * kBlock;
        ma /= k2;
        mb /= k2;
        va /= k2 * k2;
        vb /= k2 * k2;
        const double d = ma - mb, se2 = std::max(va + vb, 1e-12);
        z2 += d * d / se2;
        if (std::abs(d) / std::sqrt(se2) > zmax) g.outliers++;
        const double w = 1.0 / ((mb + 0.01) * (mb + 0.01));
        rel += d * d * w;
        rel_exp += (va + vb) * w;
      }
    }
  }
  g.chi2_per_dof = z2 / n;
  g.chi2_limit = 1.0 + 5.0 * std::sqrt(2.0 / n);
  g.relmse = rel / n;
  g.relmse_expected = rel_exp / n;
  return g;
}

// The z-tests below take each pixel's sample variance over spp as the variance of its mean,
// which holds for independent samples only: they use the random sampler. Stratified (Sobol)
// samples are checked against independent replicas instead (SobolSamplerKeepsTheMean).
RenderSettings small(const Scene& s) {
  RenderSettings rs = s.settings;
  rs.width = 32;
  rs.height = 32;
  rs.sampler = kSamplerRandom;
  return rs;
}

const PixelStats& reference() {
  static const PixelStats ref = [] {
    const Scene s = builtin_default_scene();
    return render_pixel_stats(s, small(s), 2048, 1u << 20);  // samples disjoint from the tests
  }();
  return ref;
}

// The GPU wavefront's choice of the bounce its megakernel tail takes over (host logic, tested
// here; the tail itself is tested on the GPU by cuda_test's TailRunsTheSamePaths).
TEST(Render, WavefrontTailStartsAtTheFirstShortQueue) {
  const uint32_t n = 1000;
  const std::vector<uint32_t> open_box = {1000, 530, 380, 310, 105, 47, 24, 13};
  EXPECT_EQ(wavefront_tail_bounce(open_box, 0.25f, n, 8), 4u);
  EXPECT_EQ(wavefront_tail_bounce(open_box, 0.4f, n, 8), 2u);
  EXPECT_EQ(wavefront_tail_bounce(open_box, 0.6f, n, 8), 1u);
  EXPECT_EQ(wavefront_tail_bounce(open_box, 0.01f, n, 8), 0u);  // no queue that short
  EXPECT_EQ(wavefront_tail_bounce(open_box, 0.0f, n, 8), 0u);   // off
  EXPECT_EQ(wavefront_tail_bounce({}, 0.25f, n, 8), 0u);        // nothing measured yet
  // Never the camera rays' bounce, and never past the bounces the stages would run.
  EXPECT_EQ(wavefront_tail_bounce({1000, 900}, 0.99f, n, 8), 1u);
  EXPECT_EQ(wavefront_tail_bounce(open_box, 0.25f, n, 3), 0u);
  // The counts of a sample that had a tail from bounce 4 end there (zeros): the next one starts
  // at 4 again, or one later when bounce 4's queue has grown past the limit.
  const std::vector<uint32_t> tailed = {1000, 990, 980, 970, 320, 0, 0, 0};
  EXPECT_EQ(wavefront_tail_bounce(tailed, 0.25f, n, 8), 5u);
  EXPECT_EQ(wavefront_tail_bounce(tailed, 0.4f, n, 8), 4u);
  EXPECT_EQ(wavefront_tail_bounce({1000, 990}, 0.5f, n, 8), 2u);  // past the estimate's end
}

TEST(Render, BuiltinSceneAgreesWithHighSppReference) {
  const Scene s = builtin_default_scene();
  const PixelStats test = render_pixel_stats(s, small(s), 256);
  EXPECT_EQ(test.nonfinite, 0u);
  const Agreement g = agreement(test, reference());
  EXPECT_LT(g.chi2_per_dof, g.chi2_limit);
  EXPECT_GT(g.chi2_per_dof, 2.0 - g.chi2_limit);
  EXPECT_LE(g.outliers, 1);
  // relMSE of the 4x4-block image against the reference: within what the noise explains.
  EXPECT_LT(g.relmse, 1.5 * g.relmse_expected);
  std::printf("chi2/dof %.3f (limit %.3f), relMSE %.3g (noise alone %.3g)\n", g.chi2_per_dof,
              g.chi2_limit, g.relmse, g.relmse_expected);
  // The image is not black: the box is lit.
  EXPECT_GT(test.image_mean().x, 0.05f);
}

TEST(Render, WrongSceneFailsTheSameChecks) {
  // A light 10% too dim and a red wall 10% too dark must both be caught.
  for (int variant = 0; variant < 2; ++variant) {
    Scene s = builtin_default_scene();
    bool changed = false;
    for (auto& m : s.materials) {
      if (variant == 0 && m.material.is_emissive()) {
        m.material.emission *= 0.9f;
        changed = true;
      }
      if (variant == 1 && m.material.albedo.x > 0.5f && m.material.albedo.y < 0.2f) {
        m.material.albedo *= 0.9f;
        changed = true;
      }
    }
    ASSERT_TRUE(changed) << "variant " << variant;
    const PixelStats test = render_pixel_stats(s, small(s), 256);
    const Agreement g = agreement(test, reference());
    EXPECT_GT(g.chi2_per_dof, g.chi2_limit) << "variant " << variant << " was not detected";
    EXPECT_GT(g.relmse, 1.5 * g.relmse_expected) << "variant " << variant;
    std::printf("wrong scene %d: chi2/dof %.3f, relMSE %.3g (noise alone %.3g)\n", variant,
                g.chi2_per_dof, g.relmse, g.relmse_expected);
  }
}

TEST(Render, EstimatorsShareOneMean) {
  // Naive path tracing, NEE, NEE + MIS and no roulette are unbiased: same expected image.
  const Scene s = builtin_default_scene();
  struct V {
    bool nee, mis, rr;
  };
  for (V v : {V{false, false, true}, V{true, false, true}, V{true, true, false}}) {
    RenderSettings rs = small(s);
    rs.nee = v.nee;
    rs.mis = v.mis;
    rs.russian_roulette = v.rr;
    const PixelStats test = render_pixel_stats(s, rs, v.nee ? 256 : 1024, 7u << 20);
    const Agreement g = agreement(test, reference());
    EXPECT_LT(g.chi2_per_dof, g.chi2_limit) << "nee " << v.nee << " mis " << v.mis << " rr " << v.rr;
    std::printf("nee %d mis %d rr %d: chi2/dof %.3f (limit %.3f)\n", v.nee, v.mis, v.rr,
                g.chi2_per_dof, g.chi2_limit);
    EXPECT_LE(g.outliers, 1);
  }
}

TEST(Render, CpuBackendMatchesSharedPathCodeAndIsDeterministic) {
  const Scene s = builtin_default_scene();
  const RenderSettings rs = small(s);
  const CompiledScene cs(s, rs.width, rs.height);
  ImageRGB images[2];
  for (int threads : {1, 2}) {
    CpuRenderer r(threads);
    r.set_scene(cs, make_integrator_settings(rs));
    r.render(8);
    r.render(8);  // progressive: two passes equal one of 16
    EXPECT_EQ(r.samples_done(), 16u);
    images[threads - 1] = r.image();
  }
  EXPECT_EQ(images[0].pixels, images[1].pixels) << "thread count changed the image";
  const PixelStats ps = render_pixel_stats(s, rs, 16);
  for (size_t i = 0; i < ps.mean.size(); ++i)
    ASSERT_NEAR(images[0].pixels[3 * i], ps.mean[i].x, 1e-4f * (1.0f + ps.mean[i].x));
  // A different seed gives a different (but statistically equal) image.
  CpuRenderer r(2);
  RenderSettings rs2 = rs;
  rs2.seed = 99;
  r.set_scene(cs, make_integrator_settings(rs2));
  r.render(16);
  EXPECT_NE(r.image().pixels, images[0].pixels);
}

}  // namespace

namespace {
using namespace test;

TEST(Render, EditsThatKeepTheGeometryShareTheBvh) {
  Scene s = builtin_default_scene();
  const RenderSettings rs = small(s);
  const CompiledScene before(s, rs.width, rs.height);
  EXPECT_FALSE(before.shares_bvh());
  s.materials[0].material.albedo = vec3(0.2f, 0.6f, 0.3f);  // a material edit
  s.camera.vfov_deg += 5.0f;                                  // and a camera edit
  const CompiledScene shared(s, rs.width, rs.height, &before), fresh(s, rs.width, rs.height);
  EXPECT_TRUE(shared.shares_bvh());
  EXPECT_EQ(&shared.nodes(), &before.nodes()) << "the same BVH, not a copy";
  EXPECT_EQ(&shared.cpu_bvh(), &before.cpu_bvh());
  ImageRGB img[2];
  int k = 0;
  for (const CompiledScene* cs : {&shared, &fresh}) {
    CpuRenderer r(2);
    r.set_scene(*cs, make_integrator_settings(rs));
    r.render(4);
    img[k++] = r.image();
  }
  EXPECT_EQ(img[0].pixels, img[1].pixels) << "the shared BVH renders as a rebuilt one";
  // Other primitives: built anew.
  Scene more = s;
  more.spheres.push_back({vec3(0.0f), 1.0f, 0});
  EXPECT_FALSE(CompiledScene(more, rs.width, rs.height, &before).shares_bvh());
}

TEST(Render, RadianceClampReportsTheBiasItIntroduces) {
  // Same seed, same paths: the clamped image differs from the plain one by exactly the luminance
  // the clamp says it removed, and no pixel exceeds the clamp.
  const Scene s = builtin_default_scene();
  RenderSettings rs = s.settings;
  rs.width = rs.height = 24;
  const CompiledScene cs(s, rs.width, rs.height);
  CpuRenderer plain(2), clamped(2);
  plain.set_scene(cs, make_integrator_settings(rs));
  rs.clamp = 1.0f;
  clamped.set_scene(cs, make_integrator_settings(rs));
  plain.render(32);
  const FrameStats st = clamped.render(32);
  EXPECT_GT(st.clamped, 0u);
  const ImageRGB a = plain.image(), b = clamped.image();
  double diff = 0.0;
  for (size_t i = 0; i < a.pixels.size(); i += 3) {
    const vec3 pa(a.pixels[i], a.pixels[i + 1], a.pixels[i + 2]);
    const vec3 pb(b.pixels[i], b.pixels[i + 1], b.pixels[i + 2]);
    EXPECT_LE(max_component(pb), 1.0f + 1e-5f);
    diff += luminance(pa - pb);
  }
  EXPECT_NEAR(diff * 32.0, st.clamped_luminance, 1e-3 * st.clamped_luminance);
  // A clamp above every sample changes nothing.
  CpuRenderer loose(2);
  rs.clamp = 1e30f;
  loose.set_scene(cs, make_integrator_settings(rs));
  EXPECT_EQ(loose.render(32).clamped, 0u);
  EXPECT_EQ(loose.image().pixels, a.pixels);
}

}  // namespace

namespace {
using namespace test;

// The mean of `replicas` renders of `spp` samples with independent randomizations (seeds), as
// PixelStats whose var / spp is the variance of that mean: the spread of the replica means.
// Unlike the spread of single samples, this holds for stratified samples too.
PixelStats replica_stats(const Scene& s, RenderSettings rs, int replicas, uint32_t spp) {
  std::vector<PixelStats> runs;
  for (int r = 0; r < replicas; ++r) {
    rs.seed = 1000u + uint32_t(r);
    runs.push_back(render_pixel_stats(s, rs, spp));
  }
  PixelStats ps = runs[0];
  ps.spp = uint32_t(replicas);
  for (size_t i = 0; i < ps.mean.size(); ++i) {
    glm::dvec3 m(0.0), m2(0.0);
    for (const PixelStats& r : runs) {
      m += glm::dvec3(r.mean[i]);
      m2 += glm::dvec3(r.mean[i]) * glm::dvec3(r.mean[i]);
    }
    m /= double(replicas);
    ps.mean[i] = vec3(m);
    ps.var[i] =
        vec3(glm::max((m2 - double(replicas) * m * m) / double(replicas - 1), glm::dvec3(0.0)));
  }
  for (size_t k = 1; k < runs.size(); ++k) ps.nonfinite += runs[k].nonfinite;
  return ps;
}

TEST(Render, SobolSamplersKeepTheMean) {
  // 64 replicas: the spread of 16 replica means underestimates a variance whose tail (a rare
  // bright path) the stratification does not thin out.
  const Scene s = builtin_default_scene();
  for (uint32_t sampler : {kSamplerSobol, kSamplerSobolPairs}) {
    RenderSettings rs = small(s);
    rs.sampler = sampler;
    const PixelStats test = replica_stats(s, rs, 64, 16);
    EXPECT_EQ(test.nonfinite, 0u);
    const Agreement g = agreement(test, reference());
    EXPECT_LT(g.chi2_per_dof, g.chi2_limit) << sampler_name(sampler);
    EXPECT_GT(g.chi2_per_dof, 2.0 - g.chi2_limit) << sampler_name(sampler);
    EXPECT_LE(g.outliers, 1) << sampler_name(sampler);
    EXPECT_LT(g.relmse, 1.5 * g.relmse_expected) << sampler_name(sampler);
    std::printf("%s: chi2/dof %.3f (limit %.3f), relMSE %.3g (noise alone %.3g)\n",
                sampler_name(sampler), g.chi2_per_dof, g.chi2_limit, g.relmse, g.relmse_expected);
  }
}

struct SamplerError {
  double relmse = 0;     // against the reference, its own noise subtracted
  double predicted = 0;  // from the even/odd half buffers
};

// relMSE of `seeds` renders of the 64x64 box at 64 spp, summed over the renders.
SamplerError sampler_error(const CompiledScene& cs, RenderSettings rs, const ReferenceImage& ref,
                           int seeds) {
  SamplerError e;
  for (int k = 0; k < seeds; ++k) {
    rs.seed = 77u + uint32_t(k);
    CpuRenderer r;
    r.set_scene(cs, make_integrator_settings(rs));
    r.render(64);
    ImageRGB even, odd;
    r.half_images(&even, &odd);
    const ErrorTerms t = error_terms(r.image(), ref, &even, &odd);
    e.relmse += t.relmse / seeds;
    e.predicted += t.variance / seeds;
  }
  return e;
}

TEST(Render, SobolSamplersLowerTheErrorAndHalfBuffersBoundIt) {
  const Scene s = builtin_default_scene();
  RenderSettings rs = s.settings;
  rs.width = rs.height = 64;
  const CompiledScene cs(s, rs.width, rs.height);
  ReferenceImage ref;
  {
    RenderSettings rr = rs;
    rr.sampler = kSamplerRandom;
    rr.seed = 0x5EED0001u;
    CpuRenderer r;
    r.set_scene(cs, make_integrator_settings(rr));
    r.render(4096);
    ref.mean = r.image();
    ImageRGB even, odd;
    r.half_images(&even, &odd);
    ref.variance = variance_from_halves(even, odd);
  }
  constexpr int kSeeds = 4;
  rs.sampler = kSamplerRandom;
  const SamplerError random = sampler_error(cs, rs, ref, kSeeds);
  rs.sampler = kSamplerSobolPairs;
  const SamplerError pairs = sampler_error(cs, rs, ref, kSeeds);
  rs.sampler = kSamplerSobol;
  const SamplerError sobol = sampler_error(cs, rs, ref, kSeeds);
  std::printf(
      "64x64, 64 spp: relMSE random %.4g (halves %.4g), sobol-pairs %.4g (halves %.4g), "
      "sobol %.4g (halves %.4g)\n",
      random.relmse, random.predicted, pairs.relmse, pairs.predicted, sobol.relmse,
      sobol.predicted);
  EXPECT_GT(random.relmse, 1.3 * pairs.relmse);
  // One sequence of 64 points is better stratified than two independent ones of 32.
  EXPECT_LT(sobol.relmse, 0.95 * pairs.relmse);
  // Independent halves: their difference measures the error.
  EXPECT_NEAR(pairs.predicted / pairs.relmse, 1.0, 0.3);
  EXPECT_NEAR(random.predicted / random.relmse, 1.0, 0.3);
  // The single sequence's halves are anti-correlated: their difference overstates the error,
  // never understates it.
  EXPECT_GT(sobol.predicted / sobol.relmse, 1.0);
}

}  // namespace
