// Path guiding (integrator/guide.h): the guide's sampler against its density (chi-square, and
// the density integrates to 1), the grid and the training schedule, and the integrator with a
// trained guide: the same mean as without (block z-test), less noise on a caustic at equal
// samples, and the CPU renderer's progress report.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <random>

#include "chi_square.h"
#include "cpu/cpu_backend.h"
#include "scene/loader.h"
#include "scene_builders.h"

namespace {
using namespace test;

// A learned cell from a histogram: one bright lobe, a dim band and empty bins.
void make_cell(std::vector<float>& hist, std::vector<uint32_t>& counts, std::vector<float>& dist) {
  hist.assign(kGuideHistFloats, 0.0f);
  counts.assign(1, 1000u);
  dist.assign(kGuideDistFloats, 0.0f);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (uint32_t b = 0; b < kGuideBins; ++b) {
    const uint32_t x = b % kGuideSide, y = b / kGuideSide;
    if (x >= 3 && x <= 5 && y >= 9 && y <= 11) hist[b] = 50.0f + 50.0f * u(rng);  // the lobe
    else if (y == 2) hist[b] = 2.0f * u(rng);                                     // a band
  }
  ASSERT_TRUE(guide_build_cell(hist.data(), counts.data(), dist.data(), 0));
}

TEST(Guide, SamplerMatchesItsDensity) {
  std::vector<float> hist, dist;
  std::vector<uint32_t> counts;
  make_cell(hist, counts, dist);
  GuideView g;
  g.dist = dist.data();
  ASSERT_TRUE(guide_learned(g, 0));
  // The density integrates to 1 over the sphere (bins of equal solid angle, 4 pi / 256 each).
  double integral = 0.0;
  for (uint32_t b = 0; b < kGuideBins; ++b) {
    const vec2 centre((b % kGuideSide + 0.5f) / kGuideSide, (b / kGuideSide + 0.5f) / kGuideSide);
    integral += guide_pdf(g, 0, equal_area_square_to_sphere(centre)) * (4.0 * kPi / kGuideBins);
  }
  EXPECT_NEAR(integral, 1.0, 1e-5);
  // Samples histogrammed on a 64 x 64 equal-area grid (4 x 4 cells per bin) against the density.
  constexpr int kSide = 64;
  constexpr int kN = 400000;
  std::vector<double> observed(kSide * kSide, 0.0), expected(kSide * kSide, 0.0);
  for (int c = 0; c < kSide * kSide; ++c) {
    const vec2 centre((c % kSide + 0.5f) / kSide, (c / kSide + 0.5f) / kSide);
    expected[c] = kN * guide_pdf(g, 0, equal_area_square_to_sphere(centre)) *
                  (4.0 * kPi / (kSide * kSide));
  }
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  int mismatched = 0;
  for (int i = 0; i < kN; ++i) {
    float pdf = 0.0f;
    const vec3 d = guide_sample(g, 0, vec2(u(rng), u(rng)), &pdf);
    ASSERT_NEAR(glm::length(d), 1.0f, 1e-4f);
    ASSERT_GT(pdf, 0.0f);
    if (std::abs(pdf - guide_pdf(g, 0, d)) > 1e-6f * pdf) ++mismatched;
    const vec2 q = equal_area_sphere_to_square(d);
    const int x = std::min(int(q.x * kSide), kSide - 1), y = std::min(int(q.y * kSide), kSide - 1);
    observed[y * kSide + x] += 1.0;
  }
  EXPECT_EQ(mismatched, 0);
  const chi2::Result r = chi2::chi_square_test(observed, expected, 0.01, 1);
  EXPECT_TRUE(r.passed) << r.message;
}

TEST(Guide, CellNeedsRecordsAndRadiance) {
  std::vector<float> hist(kGuideHistFloats, 1.0f), dist(kGuideDistFloats, 0.5f);
  std::vector<uint32_t> counts = {kGuideMinRecords - 1};
  GuideView g;
  g.dist = dist.data();
  EXPECT_FALSE(guide_build_cell(hist.data(), counts.data(), dist.data(), 0));
  EXPECT_FALSE(guide_learned(g, 0));  // not learned: the integrator samples the BSDF alone
  EXPECT_EQ(guide_mix(g, 0), 0.0f);
  counts[0] = kGuideMinRecords;
  std::fill(hist.begin(), hist.end(), 0.0f);
  EXPECT_FALSE(guide_build_cell(hist.data(), counts.data(), dist.data(), 0));
  hist[3] = std::numeric_limits<float>::infinity();
  EXPECT_FALSE(guide_build_cell(hist.data(), counts.data(), dist.data(), 0));
  hist[3] = 1.0f;
  EXPECT_TRUE(guide_build_cell(hist.data(), counts.data(), dist.data(), 0));
  EXPECT_TRUE(guide_learned(g, 0));
  EXPECT_EQ(guide_mix(g, 0), kGuideMix);  // no guided records yet: the default share
  // Every bin keeps the uniform share.
  EXPECT_NEAR(guide_pdf(g, 0, vec3(0, 0, -1)), kGuideUniform / (4.0f * kPi), 1e-6f);
}

// The share of the guide a cell learns: one vertex in one cell, sampled from the mixture with the
// default share and a uniform "BSDF" (f cos = 1 / (4 pi) everywhere, density 1 / (4 pi)), its
// records trained and the cell rebuilt. Where the incident radiance is the guide's lobe, the
// largest share has the least variance; where it is uniform (the BSDF alone is exact), share 0.
float learned_share(bool radiance_in_lobe) {
  std::vector<float> hist, dist;
  std::vector<uint32_t> counts;
  make_cell(hist, counts, dist);
  std::vector<GuideRecord> records(kGuideRecords, GuideRecord{0, 0, 0, kInvalid, 0, 0, 0, 0});
  GuideView g;
  g.dist = dist.data();
  g.hist = hist.data();
  g.counts = counts.data();
  g.records = records.data();
  std::fill(hist.begin(), hist.end(), 0.0f);  // the distribution stays; the sums start again
  auto radiance = [&](vec3 d) {
    if (!radiance_in_lobe) return 1.0f;
    const uint32_t b = guide_bin(d), x = b % kGuideSide, y = b / kGuideSide;
    return x >= 3 && x <= 5 && y >= 9 && y <= 11 ? 100.0f : 0.0f;
  };
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float mix = guide_mix(g, 0), pb = 1.0f / (4.0f * kPi), f_cos = pb;
  EXPECT_EQ(mix, kGuideMix);
  for (uint32_t i = 0; i < 20000; ++i) {
    vec3 d;
    float pg;
    if (u(rng) < mix) {
      d = guide_sample(g, 0, vec2(u(rng), u(rng)), &pg);
    } else {
      d = equal_area_square_to_sphere(vec2(u(rng), u(rng)));
      pg = guide_pdf(g, 0, d);
    }
    const float q = mix * pg + (1.0f - mix) * pb;
    const vec3 throughput(f_cos / q);
    guide_record(g, 0, i, 1, 0, d, q, throughput, 0.0f, f_cos, pg, pb);
    guide_train_path(g, 0, i, throughput * radiance(d));
  }
  EXPECT_GE(hist[kGuideBins + kGuideShares], float(kGuideMinShareRecords));
  EXPECT_TRUE(guide_build_cell(hist.data(), counts.data(), dist.data(), 0));
  for (uint32_t i = 0; i <= kGuideShares; ++i)  // each pass chooses from its own records
    EXPECT_EQ(hist[kGuideBins + i], 0.0f);
  return guide_mix(g, 0);
}

TEST(Guide, CellLearnsItsShareOfTheMixture) {
  EXPECT_EQ(learned_share(true), guide_share(kGuideShares - 1));
  EXPECT_EQ(learned_share(false), 0.0f);
  // A cell whose share is 0 is still learned (its training records keep the guide's density).
  std::vector<float> hist, dist;
  std::vector<uint32_t> counts;
  make_cell(hist, counts, dist);
  hist[kGuideBins + kGuideShares] = float(kGuideMinShareRecords);
  hist[kGuideBins + 1] = 1.0f;  // share 0 has the least
  hist[kGuideBins + 2] = hist[kGuideBins + 3] = 2.0f;
  ASSERT_TRUE(guide_build_cell(hist.data(), counts.data(), dist.data(), 0));
  GuideView g;
  g.dist = dist.data();
  EXPECT_TRUE(guide_learned(g, 0));
  EXPECT_EQ(guide_mix(g, 0), 0.0f);
  // A share must gain kGuideMinGain over the BSDF alone to be taken.
  auto choose = [&](float m0, float m1, float m2, float m3) {
    hist[kGuideBins + kGuideShares] = float(kGuideMinShareRecords);
    hist[kGuideBins + 0] = m0;
    hist[kGuideBins + 1] = m1;
    hist[kGuideBins + 2] = m2;
    hist[kGuideBins + 3] = m3;
    EXPECT_TRUE(guide_build_cell(hist.data(), counts.data(), dist.data(), 0));
    return guide_mix(g, 0);
  };
  EXPECT_EQ(choose(1.0f, 0.9f, 0.95f, 1.2f), 0.0f);  // 10% less: not worth a guided vertex
  EXPECT_EQ(choose(1.0f, 0.9f, 0.5f, 0.6f), guide_share(2));
  EXPECT_EQ(choose(1.0f, 0.8f, 0.7f, 0.74f), guide_share(2));  // 30% less
}

TEST(Guide, GridAndSchedule) {
  const GuideGrid g = guide_grid(vec3(-1.0f, 0.0f, -0.5f), vec3(1.0f, 4.0f, 0.5f));
  EXPECT_EQ(g.ny, kGuideMaxSide);
  EXPECT_NEAR(g.nx, kGuideMaxSide / 2, 1);  // (the margin may add one)
  EXPECT_NEAR(g.nz, kGuideMaxSide / 4, 1);
  const GuideView v = guide_view_for(g, GuideArrays(), 0, 0, GuideCalibration());
  EXPECT_EQ(guide_cell(v, vec3(-1.0f, 0.0f, -0.5f)), 0u);
  EXPECT_EQ(guide_cell(v, vec3(1.0f, 4.0f, 0.5f)), g.cells() - 1);
  EXPECT_EQ(guide_cell(v, vec3(-100.0f)), 0u);  // outside: the nearest cell
  const GuideGrid flat = guide_grid(vec3(0.0f), vec3(1.0f, 0.0f, 1.0f));
  EXPECT_EQ(flat.ny, 1u);
  EXPECT_EQ(guide_grid(vec3(kInfinity), vec3(-kInfinity)).cells(), 1u);  // empty scene
  std::vector<uint32_t> builds;
  for (uint32_t s = 0; s < 1000; ++s)
    if (guide_builds_after(s)) builds.push_back(s);
  EXPECT_EQ(builds, (std::vector<uint32_t>{0, 2, 6, 14, 30, 62, 126, 254}));
  EXPECT_EQ(guide_pass_end(0), 0u);
  EXPECT_EQ(guide_pass_end(1), 2u);
  EXPECT_EQ(guide_pass_end(100), 126u);
  EXPECT_EQ(guide_builds_done(7), 3u);
  EXPECT_EQ(guide_builds_done(1000), 8u);
}

// After training, calibration: a block of unguided samples, then a block of guided ones; the
// guide stays if its variance times its time is at least 10% below the unguided one's.
TEST(Guide, CalibrationKeepsTheGuideOnlyWhereItPays) {
  std::vector<uint32_t> calibrating, guided, starts, ends;
  for (uint32_t s = 0; s < 1000; ++s) {
    if (guide_calibrates(s)) calibrating.push_back(s);
    if (guide_calibrates(s) && guide_calibration_guided(s)) guided.push_back(s);
    if (guide_calibration_block_starts(s)) starts.push_back(s);
    if (guide_calibration_block_ends(s)) ends.push_back(s);
  }
  ASSERT_EQ(calibrating.size(), kGuideCalibrationSamples);
  EXPECT_EQ(calibrating.front(), 256u);  // after the last training pass, at a block of Sobol's
  EXPECT_EQ(guided, (std::vector<uint32_t>{264, 265, 266, 267, 268, 269, 270, 271}));
  EXPECT_EQ(starts, (std::vector<uint32_t>{256, 264}));
  EXPECT_EQ(ends, (std::vector<uint32_t>{263, 271}));

  // Guided: half the variance for 1.5x the time (0.75 at equal time): kept.
  auto calibration = [](double guided_seconds, double guided_noise) {
    GuideCalibration c;
    for (uint32_t k = 0; k < kGuideCalibrationBlock; ++k) c.add_time(false, 0.002);
    c.noise[0] = 40.0;
    for (uint32_t k = 0; k < kGuideCalibrationBlock; ++k) {
      EXPECT_FALSE(c.done());
      c.add_time(true, guided_seconds);
    }
    EXPECT_FALSE(c.done());  // until the guided block's noise is measured
    c.noise[1] = guided_noise;
    EXPECT_TRUE(c.done());
    return c;
  };
  const GuideCalibration c = calibration(0.003, 20.0);
  EXPECT_NEAR(c.time_ratio(), 1.5, 1e-12);
  EXPECT_NEAR(c.variance_ratio(), 0.5, 1e-12);
  EXPECT_TRUE(c.keeps());
  // 0.9x the variance for 1.5x the time (1.35): retired; exactly even: retired too (the guide
  // must win by 10%); 0.45 x 2 = 0.9: kept.
  const GuideCalibration worse = calibration(0.003, 36.0);
  EXPECT_FALSE(worse.keeps());
  EXPECT_FALSE(calibration(0.004, 20.0).keeps());
  EXPECT_TRUE(calibration(0.004, 18.0).keeps());
  EXPECT_EQ(GuideCalibration().time_ratio(), 1.0);  // nothing measured yet
  EXPECT_EQ(GuideCalibration().variance_ratio(), 1.0);
  // Times by their medians: a first sample that loads the kernels does not decide.
  GuideCalibration slow_start;
  for (uint32_t k = 0; k < kGuideCalibrationBlock; ++k) {
    slow_start.add_time(false, k == 0 ? 0.05 : 0.002);
    slow_start.add_time(true, k == 0 ? 0.05 : 0.003);
  }
  EXPECT_NEAR(slow_start.time_ratio(), 1.5, 1e-12);

  // The noise measure: a block of 2 samples whose mean is (1, 3), against a mean of (1, 1)
  // (sums of 4 samples before the calibration).
  const double now[2] = {5.0, 11.0}, then[2] = {3.0, 5.0}, base[2] = {4.0, 4.0};
  EXPECT_NEAR(guide_block_noise(now, then, base, 0.5, 0.25, 2), 4.0 / (1.01 * 1.01), 1e-12);

  // The CPU guide hands out no distribution for the unguided block and none at all once retired.
  HostGuide guide;
  guide.setup(guide_grid(vec3(0.0f), vec3(1.0f), 1), 1);
  guide.build(1);
  EXPECT_NE(guide.view(kGuideTrainSamples).dist, nullptr);
  EXPECT_EQ(guide.view(256).dist, nullptr);
  EXPECT_EQ(guide.view(263).dist, nullptr);
  EXPECT_NE(guide.view(264).dist, nullptr);
  EXPECT_NE(guide.view(272).dist, nullptr);
  guide.calibration() = worse;
  EXPECT_EQ(guide.view(272).dist, nullptr);
  EXPECT_TRUE(guide.status(272).retired());
  EXPECT_NE(guide.status(300).describe().find("retired (unguided from here): 0.90x the variance "
                                              "for 1.50x the time per sample"),
            std::string::npos)
      << guide.status(300).describe();
  guide.clear();  // a new render calibrates anew
  EXPECT_FALSE(guide.calibration().done());
}

// A small box lit only through glass: its light hangs behind a glass plate, so every path to it
// refracts twice and next-event estimation reaches none (Veach's "light through a window"), and a
// rough metal ball in the room. BSDF sampling finds the light where it points at it; the guide
// learns where that is.
Scene caustic_box() {
  Scene s;
  const uint32_t white = s.add_material("white", diffuse(vec3(0.7f)));
  const uint32_t light = s.add_material("light", diffuse(vec3(0.0f), vec3(40.0f)));
  Material glass;
  glass.type = MaterialType::kDielectric;
  glass.ior = 1.5f;
  const uint32_t g = s.add_material("glass", glass);
  Material metal;
  metal.type = MaterialType::kConductor;
  metal.roughness = metal.roughness_v = 0.1f;
  const uint32_t m = s.add_material("metal", metal);
  add_box(s.mesh, vec3(-1.0f, 0.0f, -1.0f), vec3(1.0f, 2.0f, 1.0f), white);
  for (uvec3& t : s.mesh.indices) std::swap(t.y, t.z);  // seen from inside
  add_quad(s.mesh, vec3(-0.2f, 1.99f, -0.2f), vec3(0.4f, 0.0f, 0.0f), vec3(0.0f, 0.0f, 0.4f),
           light);
  add_box(s.mesh, vec3(-0.3f, 1.9f, -0.3f), vec3(0.3f, 1.95f, 0.3f), g);
  s.spheres.push_back({vec3(0.5f, 0.3f, -0.4f), 0.3f, m});
  s.camera.position = vec3(0.0f, 1.0f, 0.99f);
  s.camera.look_at = vec3(0.0f, 0.6f, -1.0f);
  return s;
}

// Trains a guide over the schedule's 255 samples on the CPU (the renderer's own loop).
void train(const CompiledScene& cs, IntegratorSettings cfg, HostGuide& guide) {
  guide.setup(guide_grid(cs, cfg.width * cfg.height), cfg.width * cfg.height);
  for (uint32_t s = 0; s < kGuideTrainSamples; ++s) {
    cfg.guide = guide.view(s);
    for (uint32_t p = 0; p < cfg.width * cfg.height; ++p) trace_path(cs.view(), cfg, p, s);
    if (guide_builds_after(s)) guide.build(2);
  }
}

// A whole number from the environment, or `fallback`.
uint32_t env_number(const char* name, uint32_t fallback) {
  const char* v = std::getenv(name);
  return v && std::atoi(v) > 0 ? uint32_t(std::atoi(v)) : fallback;
}

// Also the measurement behind docs/PERFORMANCE.md's guiding rows: with GUIDE_SCENE=FILE (and
// GUIDE_SIZE, GUIDE_SPP, GUIDE_DEPTH) it trains on that scene at that size (default render
// settings, depth 8 unless GUIDE_DEPTH says otherwise: the gain by path length) and prints the
// ratios at equal samples; only the built-in caustic box is held to a limit.
TEST(Guide, TrainedGuideKeepsTheMeanAndLowersCausticNoise) {
  const char* file = std::getenv("GUIDE_SCENE");
  const int kW = int(env_number("GUIDE_SIZE", 48)), kH = kW;
  const uint32_t spp = env_number("GUIDE_SPP", 512);
  const Scene scene = file ? load_scene(file) : caustic_box();
  const CompiledScene cs(scene, kW, kH);
  RenderSettings rs;
  rs.width = kW;
  rs.height = kH;
  rs.max_depth = int(env_number("GUIDE_DEPTH", uint32_t(rs.max_depth)));
  IntegratorSettings cfg = make_integrator_settings(rs);
  HostGuide guide;
  train(cs, cfg, guide);
  const GuideStatus st = guide.status(kGuideTrainSamples);
  EXPECT_EQ(st.builds, 8u);
  EXPECT_GT(st.learned_cells, 20u) << st.describe();
  EXPECT_GT(st.guiding_cells, 10u) << st.describe();
  EXPECT_TRUE(st.frozen());
  IntegratorSettings guided = cfg;
  guided.guide = guide.view(kGuideTrainSamples + kGuideCalibrationSamples);  // guided
  const auto t0 = std::chrono::steady_clock::now();
  const PixelStats a = pixel_stats_of(cs, cfg, spp, 1000);
  const auto t1 = std::chrono::steady_clock::now();
  const PixelStats b = pixel_stats_of(cs, guided, spp, 5000);
  const auto t2 = std::chrono::steady_clock::now();
  expect_same_means(b, a, "guided vs unguided");
  // Noise: the summed per-pixel variance, guided against unguided, at equal samples; plain, and
  // relative to the unguided mean as relMSE weighs it (var / (mean^2 + 0.01)).
  const glm::dvec4 v = variance_ratios(b, a);
  std::printf("  variance per sample, guided / unguided: %.3f, relative %.3f; time %.2f s / %.2f s"
              " (%s)\n",
              v.x, v.y, std::chrono::duration<double>(t2 - t1).count(),
              std::chrono::duration<double>(t1 - t0).count(), st.describe().c_str());
  // 0.82 measured: at 48x48 few cells gather enough records to show kGuideMinGain (0.61 at
  // 96x96, 0.66 here without that margin).
  if (!file) EXPECT_LT(v.x, 0.87);  // guided / unguided summed variance
}

TEST(Guide, RendererTrainsInPassesAndReports) {
  const Scene scene = caustic_box();
  RenderSettings rs;
  rs.width = 16;
  rs.height = 16;
  rs.guiding = true;
  const CompiledScene cs(scene, rs.width, rs.height);
  CpuRenderer r(2);
  r.set_scene(cs, make_integrator_settings(rs));
  EXPECT_TRUE(r.guide_status().on);
  EXPECT_EQ(r.guide_status().builds, 0u);
  r.render(5);  // passes 1 and 2, into pass 3
  EXPECT_EQ(r.guide_status().builds, 2u);
  EXPECT_NE(r.guide_status().describe().find("training: pass 3 of 8"), std::string::npos)
      << r.guide_status().describe();
  r.render(255);
  EXPECT_EQ(r.samples_done(), 260u);
  EXPECT_EQ(r.guide_status().builds, 8u);
  EXPECT_NE(r.guide_status().describe().find("frozen after 255 spp"), std::string::npos);
  EXPECT_NE(r.guide_status().describe().find("calibrating (4 of 16 spp)"), std::string::npos)
      << r.guide_status().describe();
  r.render(45);
  EXPECT_EQ(r.samples_done(), 305u);
  // Calibrated: both kinds of sample measured, and the decision follows from the ratios.
  const GuideCalibration& c = r.guide_status().calibration;
  ASSERT_TRUE(c.done());
  EXPECT_EQ(c.samples[0], kGuideCalibrationSamples / 2);
  EXPECT_EQ(c.samples[1], kGuideCalibrationSamples / 2);
  EXPECT_GT(c.time_ratio(), 0.0);
  EXPECT_GT(c.variance_ratio(), 0.0);
  EXPECT_TRUE(std::isfinite(c.time_ratio() * c.variance_ratio()));
  EXPECT_NE(r.guide_status().describe().find(c.keeps() ? "; kept: " : "; retired"),
            std::string::npos)
      << r.guide_status().describe();
  // The cells that guide are among the learned ones, and the status says how many.
  const GuideStatus st = r.guide_status();
  EXPECT_LE(st.guiding_cells, st.learned_cells);
  EXPECT_NE(st.describe().find(std::to_string(st.guiding_cells) + " guide"), std::string::npos)
      << st.describe();
  r.reset();  // a new render forgets the guide
  EXPECT_EQ(r.guide_status().builds, 0u);
  rs.guiding = false;
  r.set_settings(make_integrator_settings(rs));
  EXPECT_FALSE(r.guide_status().on);
  EXPECT_EQ(r.guide_status().describe(), "off");
}

}  // namespace
