// The error-against-time analysis: noise/bias split of the error with half buffers and a
// reference variance, time to an error, the log-log slope and its verdict, the SVG plot; and
// `pathtracer bench --error` end to end on the CPU (unbiased vs biased configurations).
#include "image/convergence.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "core/diagnostics.h"
#include "image/svg_plot.h"
#include "test_util.h"

namespace {

using tracer::Checkpoint;
using tracer::ImageRGB;

struct Halves {
  ImageRGB even, odd, mean;
};

// Two independent half estimates of `truth + bias` with Gaussian noise of `sigma` each.
Halves noisy(const ImageRGB& truth, double sigma, double bias, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, sigma);
  Halves h{truth, truth, truth};
  for (size_t i = 0; i < truth.pixels.size(); ++i) {
    h.even.pixels[i] = float(truth.pixels[i] + bias + n(rng));
    h.odd.pixels[i] = float(truth.pixels[i] + bias + n(rng));
    h.mean.pixels[i] = 0.5f * (h.even.pixels[i] + h.odd.pixels[i]);
  }
  return h;
}

TEST(Convergence, VarianceFromHalvesIsUnbiased) {
  const ImageRGB truth = tracer::make_image(200, 200, tracer::vec3(0.5f));
  const Halves h = noisy(truth, 0.1, 0.0, 1);
  const ImageRGB v = tracer::variance_from_halves(h.even, h.odd);
  double mean = 0;
  for (float x : v.pixels) mean += x;
  mean /= v.pixels.size();
  // Var of the mean of two N(0, 0.1^2) halves: 0.005; relative standard error ~ sqrt(2/120000).
  EXPECT_NEAR(mean, 0.005, 0.005 * 0.02);
}

TEST(Convergence, SplitsErrorIntoNoiseAndBias) {
  const ImageRGB truth = tracer::make_image(200, 200, tracer::vec3(0.5f));
  tracer::ReferenceImage ref{truth, {}};
  const double w = 1.0 / (0.51 * 0.51);
  // Unbiased: all error is noise; the bias estimate is within its standard error of 0.
  Halves h = noisy(truth, 0.1, 0.0, 2);
  tracer::ErrorTerms e = tracer::error_terms(h.mean, ref, &h.even, &h.odd);
  EXPECT_NEAR(e.relmse, 0.005 * w, 0.005 * w * 0.03);
  EXPECT_NEAR(e.variance, 0.005 * w, 0.005 * w * 0.03);
  EXPECT_LT(std::abs(e.bias2), 4 * e.bias2_stderr);
  EXPECT_FALSE(e.significant_bias());
  // A bias of 0.05 adds 0.0025 / 0.51^2 and is detected.
  h = noisy(truth, 0.1, 0.05, 3);
  e = tracer::error_terms(h.mean, ref, &h.even, &h.odd);
  EXPECT_NEAR(e.bias2, 0.0025 * w, 0.0025 * w * 0.1);
  EXPECT_TRUE(e.significant_bias());
  // Without halves nothing is claimed about bias.
  e = tracer::error_terms(h.mean, ref);
  EXPECT_FALSE(e.has_variance());
  EXPECT_FALSE(e.significant_bias());
}

// Half estimates that interleave, like the single Sobol sequence's: their mean has noise
// `sigma` while each half has 2.5 sigma more, so their difference overstates the noise.
Halves interleaved(const ImageRGB& truth, double sigma, double bias, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, sigma);
  Halves h{truth, truth, truth};
  for (size_t i = 0; i < truth.pixels.size(); ++i) {
    const double mean = truth.pixels[i] + bias + n(rng), spread = 2.5 * n(rng);
    h.mean.pixels[i] = float(mean);
    h.even.pixels[i] = float(mean + spread);
    h.odd.pixels[i] = float(mean - spread);
  }
  return h;
}

TEST(Convergence, BlockTestFindsABiasWhenTheHalvesOverstateTheNoise) {
  const ImageRGB truth = tracer::make_image(200, 200, tracer::vec3(0.5f));
  tracer::ReferenceImage ref{truth, {}};
  const double w = 1.0 / (0.51 * 0.51);
  // Unbiased: the per-pixel split would read the overstated noise as a negative bias; the block
  // test's estimate is a lower bound, at or below zero, and nothing is flagged.
  Halves h = interleaved(truth, 0.05, 0.0, 5);
  tracer::ErrorTerms e = tracer::error_terms(h.mean, ref, &h.even, &h.odd, false);
  EXPECT_TRUE(e.block_test);
  EXPECT_LT(e.bias2, 4 * e.bias2_stderr);
  EXPECT_FALSE(e.significant_bias());
  EXPECT_NEAR(e.variance, 0.0025 * w, 0.0025 * w * 0.05);  // the rest of the error
  // A bias of 0.03 (0.0009 / 0.51^2, a quarter of the error) is found, and not overstated.
  h = interleaved(truth, 0.05, 0.03, 6);
  e = tracer::error_terms(h.mean, ref, &h.even, &h.odd, false);
  EXPECT_TRUE(e.significant_bias()) << e.bias2 << " +- " << e.bias2_stderr;
  EXPECT_LT(e.bias2, 0.0009 * w * 1.1);
  EXPECT_GT(e.bias2, 0.0009 * w * 0.5);
  // The per-pixel split on the same halves would miss it: their noise reads 6.25x too high.
  e = tracer::error_terms(h.mean, ref, &h.even, &h.odd);
  EXPECT_FALSE(e.significant_bias());
}

TEST(Convergence, SubtractsTheReferenceNoise) {
  // A noisy reference with its variance image: the test (the truth itself) shows error only
  // from the reference, and the floor removes it.
  const ImageRGB truth = tracer::make_image(200, 200, tracer::vec3(0.5f));
  const Halves r = noisy(truth, 0.05, 0.0, 4);
  tracer::ReferenceImage ref{r.mean, tracer::variance_from_halves(r.even, r.odd)};
  const tracer::ErrorTerms e = tracer::error_terms(truth, ref);
  EXPECT_GT(e.relmse_raw, 0.0);
  EXPECT_NEAR(e.reference_floor, e.relmse_raw, 0.05 * e.relmse_raw);
  EXPECT_NEAR(e.relmse, 0.0, 0.05 * e.relmse_raw);
  EXPECT_THROW(tracer::error_terms(tracer::make_image(3, 3), ref), tracer::InputError);
}

// A sweep with relMSE = a / spp at 10 ms per sample, optionally with a bias floor.
std::vector<Checkpoint> sweep(double a, double floor, uint32_t max_spp) {
  std::vector<Checkpoint> out;
  for (uint32_t spp = 1; spp <= max_spp; spp *= 2) {
    Checkpoint c;
    c.spp = spp;
    c.seconds = 0.01 * spp;
    c.error.variance = a / spp;
    c.error.bias2 = floor;
    c.error.bias2_stderr = floor > 0 ? floor / 100 : 1e-9;
    c.error.relmse = a / spp + floor;
    out.push_back(c);
  }
  return out;
}

TEST(Convergence, TimeToErrorInterpolatesAndExtrapolates) {
  // relMSE = 1/spp reaches 1e-2 at 100 spp = 1 s (between the 64 and 128 checkpoints).
  tracer::TimeToError t = tracer::time_to_error(sweep(1.0, 0.0, 1024), 1e-2);
  EXPECT_NEAR(t.seconds, 1.0, 1e-9);
  EXPECT_FALSE(t.extrapolated);
  // 1e-3 needs 1000 spp; the sweep stops at 256 and extrapolates along 1/time.
  t = tracer::time_to_error(sweep(1.0, 0.0, 256), 1e-3);
  EXPECT_NEAR(t.seconds, 10.0, 1e-9);
  EXPECT_TRUE(t.extrapolated);
  // A bias floor below the target: only the noise part (1/spp) falls, so 1e-3 needs
  // 1/spp = 5e-4, i.e. 2,000 spp = 20 s, not the 1.5e-3 x 2.56 / 1e-3 = 3.8 s of error ~ 1/time.
  t = tracer::time_to_error(sweep(1.0, 5e-4, 256), 1e-3);
  EXPECT_NEAR(t.seconds, 20.0, 1e-6);
  EXPECT_TRUE(t.extrapolated);
  // A bias floor above the target: never.
  t = tracer::time_to_error(sweep(1.0, 2e-3, 1024), 1e-3);
  EXPECT_LT(t.seconds, 0.0);
}

TEST(Convergence, SlopeAndVerdict) {
  tracer::ConvergenceSummary s = tracer::summarize(sweep(1.0, 0.0, 1024));
  EXPECT_NEAR(s.slope, -1.0, 1e-9);
  EXPECT_FALSE(s.biased);
  EXPECT_NE(s.verdict.find("unbiased"), std::string::npos) << s.verdict;
  EXPECT_NEAR(s.efficiency, 1.0 / (1.0 / 1024 * 10.24), 1e-9);
  s = tracer::summarize(sweep(1.0, 1e-2, 1024));
  EXPECT_TRUE(s.biased);
  EXPECT_GT(s.slope, -0.8);
  EXPECT_EQ(s.verdict.rfind("biased", 0), 0u) << s.verdict;
  // Stratified samples: relMSE ~ spp^-1.3 with no bias reads as unbiased, steeper than -1.
  std::vector<Checkpoint> qmc = sweep(1.0, 0.0, 1024);
  for (Checkpoint& c : qmc) c.error.relmse = c.error.variance = std::pow(double(c.spp), -1.3);
  s = tracer::summarize(qmc);
  EXPECT_NEAR(s.slope, -1.3, 1e-9);
  EXPECT_FALSE(s.biased);
  EXPECT_EQ(s.verdict.rfind("unbiased (slope -1.30", 0), 0u) << s.verdict;
  EXPECT_NE(s.verdict.find("steeper than -1: stratified samples"), std::string::npos) << s.verdict;
  // Flat (slope -0.5) with no bias in the half-buffer test: not biased, and the verdict says why;
  // the same curve without half buffers (the workbench) is called biased on the slope alone.
  for (Checkpoint& c : qmc) c.error.relmse = c.error.variance = std::pow(double(c.spp), -0.5);
  s = tracer::summarize(qmc);
  EXPECT_FALSE(s.biased) << s.verdict;
  EXPECT_NE(s.verdict.find("no significant bias"), std::string::npos) << s.verdict;
  for (Checkpoint& c : qmc) c.error.variance = -1.0;
  s = tracer::summarize(qmc);
  EXPECT_TRUE(s.biased) << s.verdict;
  // Flatter than -1 but not flat: still flagged as off -1.
  for (Checkpoint& c : qmc) c.error.relmse = c.error.variance = std::pow(double(c.spp), -0.85);
  s = tracer::summarize(qmc);
  EXPECT_NE(s.verdict.find("is off -1"), std::string::npos) << s.verdict;
}

TEST(Convergence, SvgPlotHasEverySeriesAndEscapesNames) {
  tracer::PlotSpec p;
  p.title = "a <title> & more";
  p.series = {{"one", {{0.01, 1.0}, {0.1, 0.1}}}, {"two<", {{0.02, 0.5}, {0.2, 0.0}}}};
  p.y_marks = {{1e-2, "1e-2"}};
  const std::string svg = tracer::loglog_svg(p);
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  EXPECT_NE(svg.find("a &lt;title&gt; &amp; more"), std::string::npos);
  EXPECT_NE(svg.find("two&lt;"), std::string::npos);
  EXPECT_EQ(svg.find("two<"), std::string::npos);
  size_t paths = 0;
  for (size_t i = svg.find("<path"); i != std::string::npos; i = svg.find("<path", i + 1)) ++paths;
  EXPECT_EQ(paths, 2u);  // the zero y of "two" is skipped, its other point still draws
}

TEST(BenchError, CpuSweepSeparatesUnbiasedFromBiased) {
  char tmpl[] = "/tmp/pathtracer_bench_XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  std::string log;
  const std::string cmd =
      test::pathtracer_exe() +
      // 64x64: on 32x32 one early bright sample, which a cumulative sweep carries to every
      // later point and which decays there as 1/N^2, tilts the random sampler's fitted slope
      // to -1.2 in some random streams; four times the pixels average that out (-1.02).
      " bench --error --backend cpu --width 64 --height 64 --reference-spp 512"
      " --max-spp 64 --configs cpu+sampler=random,cpu+max_depth=2,cpu+nee=off+sampler=random,cpu"
      " --out " +
      dir;
  ASSERT_EQ(test::run_command(cmd, &log), 0) << log;
  std::ifstream f(dir + "/bench.json");
  ASSERT_TRUE(f.good()) << log;
  const auto j = nlohmann::json::parse(f);
  ASSERT_EQ(j["configs"].size(), 4u);
  const auto& cpu = j["configs"][0];  // independent samples: relMSE ~ 1/spp
  const auto& shallow = j["configs"][1];
  const auto& no_nee = j["configs"][2];
  const auto& sobol = j["configs"][3];
  EXPECT_FALSE(cpu["biased"].get<bool>()) << cpu["verdict"];
  EXPECT_NEAR(cpu["slope"].get<double>(), -1.0, 0.15);
  EXPECT_FALSE(sobol["biased"].get<bool>()) << sobol["verdict"];
  EXPECT_LT(sobol["slope"].get<double>(), -0.85) << sobol["verdict"];
  EXPECT_TRUE(shallow["biased"].get<bool>()) << shallow["verdict"];  // depth 2 misses light
  EXPECT_FALSE(no_nee["biased"].get<bool>()) << no_nee["verdict"];
  // NEE makes the same error cheaper.
  EXPECT_GT(cpu["efficiency"].get<double>(), 5 * no_nee["efficiency"].get<double>());
  struct stat st;
  for (const char* name :
       {"/error_vs_time.csv", "/summary.csv", "/error_vs_time.svg", "/flip_vs_time.svg"})
    EXPECT_EQ(stat((dir + name).c_str(), &st), 0) << name;
  // The reference is reused on a second run, and a bad configuration is a usage error.
  ASSERT_EQ(test::run_command(cmd, &log), 0) << log;
  EXPECT_NE(log.find("(loaded)"), std::string::npos) << log;
  EXPECT_EQ(test::run_command(test::pathtracer_exe() +
                                  " bench --error --backend cpu --configs "
                                  "cpu+nea=off --out " +
                                  dir,
                              &log),
            2)
      << log;
  EXPECT_NE(log.find("did you mean \"nee\""), std::string::npos) << log;
  // A modifier's value is checked by the settings table, with its message.
  EXPECT_EQ(test::run_command(test::pathtracer_exe() +
                                  " bench --error --backend cpu --configs cpu+max_depth=0 --out " +
                                  dir,
                              &log),
            2)
      << log;
  EXPECT_NE(log.find("\"render.max_depth\" is 0, outside 1..1024"), std::string::npos) << log;
}

TEST(BenchError, RefusesBadReferencesAndSpeedOnlyOptions) {
  char tmpl[] = "/tmp/pathtracer_bench_XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  std::string log;
  const std::string base =
      test::pathtracer_exe() + " bench --error --backend cpu --width 16 --height 16 ";
  // A PNG cannot be a reference; speed-bench options do not combine with --error.
  EXPECT_EQ(test::run_command(base + "--reference " + dir + "/r.png --out " + dir, &log), 2) << log;
  EXPECT_NE(log.find(".exr"), std::string::npos) << log;
  EXPECT_EQ(test::run_command(base + "--nee off --out " + dir, &log), 2) << log;
  EXPECT_EQ(test::run_command(base + "--configs cpu+depth=2.5 --out " + dir, &log), 2) << log;
  // The GPU has no SSE traversal to switch off.
  EXPECT_EQ(test::run_command(base + "--configs megakernel+scalar-bvh --out " + dir, &log), 2)
      << log;
  EXPECT_NE(log.find("cpu configurations only"), std::string::npos) << log;
  // An unwritable --out fails before any rendering.
  EXPECT_EQ(test::run_command(base + "--out /proc/nope", &log), 1) << log;
  EXPECT_NE(log.find("/proc/nope"), std::string::npos) << log;
  // A reference rendered with the render's own seed and sampler is flagged.
  const std::string ref = dir + "/same_seed.exr";
  ASSERT_EQ(test::run_command(test::pathtracer_exe() +
                                  " render -q --backend cpu --width 16 "
                                  "--height 16 --spp 64 --out " +
                                  ref,
                              &log),
            0)
      << log;
  EXPECT_NE(tracer::reference_independence_warning(ref, 0, "sobol"), "");
  EXPECT_EQ(tracer::reference_independence_warning(ref, 1, "sobol"), "");
  EXPECT_EQ(tracer::reference_independence_warning(ref, 0, "random"), "");
  ASSERT_EQ(test::run_command(base + "--reference " + ref +
                                  " --configs cpu --max-spp 2 --flip off "
                                  "--out " +
                                  dir,
                              &log),
            0)
      << log;
  EXPECT_NE(log.find("same seed"), std::string::npos) << log;
}

}  // namespace
