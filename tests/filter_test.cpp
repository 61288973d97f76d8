// Pixel filters (camera/filter.h): the sample offsets follow each filter's profile (chi-square),
// and a render of a sharp edge reproduces the edge convolved with the filter, pixel by pixel.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <random>

#include "camera/filter.h"
#include "chi_square.h"
#include "image/image.h"
#include "test_util.h"

namespace {

using tracer::PixelFilter;

const PixelFilter kFilters[] = {PixelFilter::kBox, PixelFilter::kTent, PixelFilter::kGaussian,
                                PixelFilter::kBlackmanHarris};

// The filter's profile integrated over [a, b], normalised by its integral over the support.
double filter_mass(PixelFilter f, float r, double a, double b) {
  auto integral = [&](double lo, double hi) {
    lo = std::max(lo, -double(r));
    hi = std::min(hi, double(r));
    if (hi <= lo) return 0.0;
    const int n = 2000;
    double sum = 0.0;
    for (int i = 0; i < n; ++i)
      sum += tracer::filter_profile(f, r, float(lo + (i + 0.5) * (hi - lo) / n));
    return sum * (hi - lo) / n;
  };
  return integral(a, b) / integral(-r, r);
}

TEST(PixelFilter, OffsetsFollowTheProfile) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  for (PixelFilter f : kFilters) {
    for (float r : {tracer::default_filter_radius(f), 2.0f}) {
      const int bins = 40, n = 200000;
      std::vector<double> observed(bins, 0.0), expected(bins, 0.0);
      auto next = [&] { return u01(gen); };
      for (int i = 0; i < n; ++i) {
        const float x = tracer::sample_filter_1d(f, r, u01(gen), next);
        ASSERT_LE(std::abs(x), r);
        observed[std::min(bins - 1, int((x + r) / (2 * r) * bins))] += 1.0;
      }
      for (int b = 0; b < bins; ++b)
        expected[b] = n * filter_mass(f, r, -r + 2.0 * r * b / bins, -r + 2.0 * r * (b + 1) / bins);
      const chi2::Result res = chi2::chi_square_test(observed, expected, 0.01, 8);
      EXPECT_TRUE(res.passed) << int(f) << " radius " << r << ": " << res.message;
    }
  }
}

TEST(PixelFilter, ProfilesPeakAtTheCentreAndVanishOutside) {
  for (PixelFilter f : kFilters) {
    const float r = tracer::default_filter_radius(f);
    EXPECT_NEAR(tracer::filter_profile(f, r, 0.0f), 1.0f, 1e-5f);
    EXPECT_EQ(tracer::filter_profile(f, r, 1.01f * r), 0.0f);
    EXPECT_GE(tracer::filter_profile(f, r, 0.99f * r), 0.0f);
  }
}

// A camera at the origin looks down -z at an emitter covering x >= 0: the edge falls exactly on
// the border between pixels 15 and 16 of a 32-pixel row. With depth 1 each pixel's value is the
// filter's mass on the bright side of the edge.
TEST(PixelFilter, AnEdgeRendersAsTheFilteredStep) {
  char tmpl[] = "/tmp/pathtracer_filter_XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  std::ofstream(dir + "/edge.json") << R"({
    "camera": {"position": [0, 0, 0], "look_at": [0, 0, -1], "vfov": 40},
    "render": {"width": 32, "height": 2, "spp": 4096, "max_depth": 1},
    "materials": {"lamp": {"emission": [1, 1, 1]}},
    "objects": [{"type": "quad", "corner": [0, -100, -1], "edge1": [100, 0, 0],
                 "edge2": [0, 200, 0], "material": "lamp"}]})";
  for (PixelFilter f : kFilters) {
    const char* names[] = {"box", "tent", "gaussian", "blackman-harris"};
    const std::string out = dir + "/" + names[int(f)] + ".exr";
    std::string log;
    ASSERT_EQ(test::run_command(test::pathtracer_exe() + " render -q --backend cpu --out " + out +
                                    " --filter " + names[int(f)] + " " + dir + "/edge.json",
                                &log), 0) << log;
    const tracer::ImageRGB img = tracer::read_image(out);
    const float r = tracer::default_filter_radius(f);
    for (int x = 12; x < 20; ++x) {
      // Pixel x covers [x, x + 1); the edge is at 16; the bright side is beyond it.
      const double expect = filter_mass(f, r, 16.0 - (x + 0.5), 1e9);
      for (int y = 0; y < 2; ++y) {
        const double got = img.pixels[3 * size_t(y * 32 + x)];
        const double sigma = std::sqrt(std::max(expect * (1.0 - expect), 1e-4) / 4096.0);
        EXPECT_NEAR(got, expect, 5.0 * sigma + 1e-4) << names[int(f)] << " pixel " << x;
      }
    }
  }
}

}  // namespace
