// Tests for LDR-FLIP (tracer/image/flip.h): exact zero on identical images, an independent
// double-precision computation of the colour pipeline on flat images, values printed by the
// reference implementation, and the properties the metric is built to have.
#include "image/flip.h"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/diagnostics.h"
#include "test_util.h"

namespace tracer {
namespace {

// An image of sRGB-encoded values, stored linear as ImageRGB expects.
ImageRGB from_srgb(int w, int h, vec3 (*f)(int x, int y)) {
  ImageRGB img = make_image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const vec3 s = f(x, y);
      img.set(x, y, vec3(srgb_to_linear(s.x), srgb_to_linear(s.y), srgb_to_linear(s.z)));
    }
  }
  return img;
}

ImageRGB flat_srgb(int w, int h, vec3 s) {
  return make_image(w, h, vec3(srgb_to_linear(s.x), srgb_to_linear(s.y), srgb_to_linear(s.z)));
}

// A textured image with edges, points and colour, for the tests that need "some image".
ImageRGB busy_image(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  ImageRGB img = make_image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float checker = ((x / 7 + y / 5) % 2) ? 0.8f : 0.1f;
      img.set(x, y, vec3(checker, 0.5f * u(rng), static_cast<float>(x) / w));
    }
  }
  return img;
}

// ---- An independent computation of the colour pipeline for two flat colours --------------------
// On a flat image the CSF filters (which sum to 1) leave every pixel unchanged and the feature
// detectors (whose lobes sum to +1 and -1) give 0, so FLIP = ΔEc = remap(HyAB^q_c) of the two
// colours. Done here in double, from the definitions rather than from flip.cpp's constants: the
// sRGB matrix is derived from the primaries' and D65's chromaticities (IEC 61966-2-1).
struct Vec {
  double v[3];
};

double srgb_eotf(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

void invert3(const double m[3][3], double out[3][3]) {
  const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                     m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      // Cofactor of (j, i) over the determinant.
      const int r0 = (j + 1) % 3, r1 = (j + 2) % 3, c0 = (i + 1) % 3, c1 = (i + 2) % 3;
      out[i][j] = (m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]) / det;
    }
  }
}

struct ReferenceColour {
  double rgb_to_xyz[3][3], xyz_to_rgb[3][3];
  // FLIP's D65 white. Not exactly the matrix's white (0.95046, 1, 1.08906): the reference
  // implementation uses these values, and they move the result by ~1e-5.
  double white[3] = {0.950428545, 1.0, 1.088900371};

  ReferenceColour() {
    const double xy[4][2] = {{0.64, 0.33}, {0.30, 0.60}, {0.15, 0.06}, {0.3127, 0.3290}};
    double p[3][3];  // columns: XYZ of each primary with Y = 1
    for (int c = 0; c < 3; ++c) {
      p[0][c] = xy[c][0] / xy[c][1];
      p[1][c] = 1.0;
      p[2][c] = (1.0 - xy[c][0] - xy[c][1]) / xy[c][1];
    }
    const double w[3] = {xy[3][0] / xy[3][1], 1.0, (1.0 - xy[3][0] - xy[3][1]) / xy[3][1]};
    double pinv[3][3];
    invert3(p, pinv);
    for (int c = 0; c < 3; ++c) {
      const double s = pinv[c][0] * w[0] + pinv[c][1] * w[1] + pinv[c][2] * w[2];
      for (int r = 0; r < 3; ++r) rgb_to_xyz[r][c] = p[r][c] * s;
    }
    invert3(rgb_to_xyz, xyz_to_rgb);
  }

  static Vec mul(const double m[3][3], Vec a) {
    Vec o;
    for (int i = 0; i < 3; ++i) o.v[i] = m[i][0] * a.v[0] + m[i][1] * a.v[1] + m[i][2] * a.v[2];
    return o;
  }
  Vec ycxcz(Vec xyz) const {
    const double x = xyz.v[0] / white[0], y = xyz.v[1] / white[1], z = xyz.v[2] / white[2];
    return {{116 * y - 16, 500 * (x - y), 200 * (y - z)}};
  }
  Vec ycxcz_inverse(Vec c) const {
    const double y = (c.v[0] + 16) / 116;
    return {{(y + c.v[1] / 500) * white[0], y * white[1], (y - c.v[2] / 200) * white[2]}};
  }
  Vec hunt_lab(Vec rgb) const {
    const Vec xyz = mul(rgb_to_xyz, rgb);
    double f[3];
    const double d = 6.0 / 29.0;
    for (int i = 0; i < 3; ++i) {
      const double t = xyz.v[i] / white[i];
      f[i] = t > d * d * d ? std::cbrt(t) : t / (3 * d * d) + 4.0 / 29.0;
    }
    const double L = 116 * f[1] - 16;
    return {{L, 0.01 * L * 500 * (f[0] - f[1]), 0.01 * L * 200 * (f[1] - f[2])}};
  }
  static double hyab(Vec a, Vec b) {
    return std::fabs(a.v[0] - b.v[0]) + std::hypot(a.v[1] - b.v[1], a.v[2] - b.v[2]);
  }
  // sRGB -> linear -> XYZ -> YCxCz -> (flat: unfiltered) -> XYZ -> linear RGB clamped ->
  // Hunt-adjusted L*a*b* -> HyAB -> ^0.7 -> remap with p_c = 0.4, p_t = 0.95.
  double flip(vec3 srgb_a, vec3 srgb_b) const {
    Vec lab[2];
    for (int i = 0; i < 2; ++i) {
      const vec3 s = i == 0 ? srgb_a : srgb_b;
      const Vec lin = {{srgb_eotf(s.x), srgb_eotf(s.y), srgb_eotf(s.z)}};
      Vec rgb = mul(xyz_to_rgb, ycxcz_inverse(ycxcz(mul(rgb_to_xyz, lin))));
      for (double& c : rgb.v) c = std::fmin(1.0, std::fmax(0.0, c));
      lab[i] = hunt_lab(rgb);
    }
    const double cmax = std::pow(hyab(hunt_lab({{0, 1, 0}}), hunt_lab({{0, 0, 1}})), 0.7);
    const double pccmax = 0.4 * cmax;
    const double d = std::pow(hyab(lab[0], lab[1]), 0.7);
    return d < pccmax ? d * 0.95 / pccmax : 0.95 + (d - pccmax) / (cmax - pccmax) * 0.05;
  }
};

TEST(Flip, FlatColourPairsMatchAnIndependentComputation) {
  const ReferenceColour ref;
  // The derived matrix is the standard one (IEC 61966-2-1 prints 0.4124, 0.3576, 0.1805).
  EXPECT_NEAR(ref.rgb_to_xyz[0][0], 0.4124, 1e-4);
  EXPECT_NEAR(ref.rgb_to_xyz[1][1], 0.7152, 1e-4);
  const vec3 pairs[][2] = {
      {{0.5f, 0.5f, 0.5f}, {0.52f, 0.5f, 0.5f}},     // small grey step
      {{0.2f, 0.5f, 0.8f}, {0.25f, 0.5f, 0.8f}},     // small hue change
      {{0.9f, 0.1f, 0.3f}, {0.8f, 0.2f, 0.35f}},     // larger, still below p_c c_max
      {{0.0f, 0.0f, 0.0f}, {1.0f, 1.0f, 1.0f}},      // above p_c c_max: the upper branch
      {{0.0f, 1.0f, 0.0f}, {0.0f, 0.0f, 1.0f}},      // the pair that defines c_max: exactly 1
      {{0.02f, 0.01f, 0.0f}, {0.0f, 0.02f, 0.01f}},  // dark: the linear segment of L*a*b*
  };
  for (const auto& p : pairs) {
    const double expected = ref.flip(p[0], p[1]);
    const FlipResult r = ldr_flip(flat_srgb(24, 16, p[1]), flat_srgb(24, 16, p[0]));
    for (float v : r.per_pixel) ASSERT_NEAR(v, expected, 1e-4) << p[0].x << " vs " << p[1].x;
    EXPECT_NEAR(r.mean, expected, 1e-4);
  }
  EXPECT_NEAR(ref.flip({0, 1, 0}, {0, 0, 1}), 1.0, 1e-12);
}

TEST(Flip, IdenticalImagesGiveExactlyZero) {
  const ImageRGB a = busy_image(70, 45, 1);
  const FlipResult r = ldr_flip(a, a);
  ASSERT_EQ(r.per_pixel.size(), 70u * 45u);
  EXPECT_EQ(r.width, 70);
  EXPECT_EQ(r.height, 45);
  for (float v : r.per_pixel) ASSERT_EQ(v, 0.0f);
  EXPECT_EQ(r.mean, 0.0);
}

TEST(Flip, BlackVersusWhiteIsNearOne) {
  // HyAB(black, white) = 100 in Hunt-adjusted L*a*b*, 100^0.7 = 25.1 > p_c c_max = 16.5, so the
  // upper branch gives 0.95 + 0.05 (25.1 - 16.5) / (41.3 - 16.5) = 0.96738. The reference
  // implementation (flip-evaluator 1.7) prints a mean of 0.967391 for a 16x16 pair.
  const FlipResult r = ldr_flip(make_image(32, 32, vec3(1.0f)), make_image(32, 32, vec3(0.0f)));
  for (float v : r.per_pixel) ASSERT_NEAR(v, 0.96738, 2e-5);
  EXPECT_NEAR(r.mean, 0.967391, 2e-5);
}

// A red step edge across columns 60/61 and a green one across rows 50/51 in the reference; the
// test has the red edge 3 columns further right. 160x120, sRGB.
vec3 edges_reference(int x, int y) {
  return vec3(x > 60 ? 0.9f : 0.1f, y > 50 ? 0.7f : 0.2f, 0.5f);
}
vec3 edges_test(int x, int y) {
  return vec3(x > 63 ? 0.9f : 0.1f, y > 50 ? 0.7f : 0.2f, 0.5f);
}

TEST(Flip, MatchesTheReferenceImplementationOnStepEdges) {
  // The mean and pixels printed by NVlabs' flip-evaluator 1.7 (the pip package of the reference
  // implementation, LDR mode, default 67.02 ppd) for exactly these images given as float sRGB.
  const ImageRGB ref = from_srgb(160, 120, edges_reference);
  const ImageRGB test = from_srgb(160, 120, edges_test);
  const FlipResult r = ldr_flip(test, ref);
  EXPECT_NEAR(r.mean, 0.0320601, 1e-5);
  struct Pixel {
    int x, y;
    float flip;
  };
  const Pixel expected[] = {{10, 10, 0.0f},       {55, 20, 0.0337562f}, {58, 20, 0.1504187f},
                            {62, 20, 0.9087501f}, {64, 20, 0.5071309f}, {68, 20, 0.0866906f},
                            {62, 50, 0.8538805f}, {62, 51, 0.8308124f}, {100, 51, 0.0f},
                            {159, 119, 0.0f}};
  for (const Pixel& p : expected) {
    EXPECT_NEAR(r.per_pixel[p.y * 160 + p.x], p.flip, 1e-4) << p.x << "," << p.y;
  }
  // The same pair at 30 ppd (flip-evaluator: 0.0251611): the filters follow the viewing distance.
  EXPECT_NEAR(ldr_flip(test, ref, 30.0).mean, 0.0251611, 1e-5);
}

TEST(Flip, IsSymmetric) {
  // Every step treats the two images alike (the same filters on both, then HyAB and the absolute
  // difference of feature magnitudes, both symmetric), so LDR-FLIP(a, b) = LDR-FLIP(b, a); the
  // reference implementation also returns identical maps with its arguments swapped. (HDR-FLIP is
  // not symmetric: its exposure range comes from the reference alone.)
  const ImageRGB a = busy_image(64, 40, 2), b = busy_image(64, 40, 3);
  const FlipResult ab = ldr_flip(a, b), ba = ldr_flip(b, a);
  ASSERT_EQ(ab.per_pixel.size(), ba.per_pixel.size());
  for (size_t i = 0; i < ab.per_pixel.size(); ++i) ASSERT_EQ(ab.per_pixel[i], ba.per_pixel[i]);
  EXPECT_GT(ab.mean, 0.05);
}

TEST(Flip, GrowsMonotonicallyWithAUniformColourDifference) {
  double previous = 0.0;
  for (float d : {0.002f, 0.005f, 0.01f, 0.02f, 0.05f, 0.1f, 0.2f, 0.4f}) {
    const FlipResult r =
        ldr_flip(flat_srgb(16, 16, vec3(0.5f + d, 0.5f, 0.5f - d)), flat_srgb(16, 16, vec3(0.5f)));
    EXPECT_GT(r.mean, previous) << d;
    if (d <= 0.005f) EXPECT_LT(r.mean, 0.05) << d;  // a barely visible difference scores low
    previous = r.mean;
  }
  EXPECT_LT(previous, 1.0);
}

TEST(Flip, AFeatureDifferenceRaisesTheErrorAboveTheColourError) {
  // Reference: dark left, light right, with the column x = 32 exactly halfway in linear RGB; the
  // test is uniformly dark. By symmetry the CSF-filtered reference at x = 32 is the halfway colour
  // itself, so the colour error there equals that of a flat halfway-vs-dark pair. Only the edge,
  // present in the reference and absent in the test, differs: FLIP = ΔEc^(1 - ΔEf) must be larger.
  const vec3 dark(0.05f), light(0.6f), mid = 0.5f * (dark + light);
  ImageRGB edge = make_image(65, 8);
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 65; ++x) edge.set(x, y, x < 32 ? dark : x > 32 ? light : mid);
  }
  const FlipResult with_edge = ldr_flip(make_image(65, 8, dark), edge);
  const FlipResult flat = ldr_flip(make_image(65, 8, dark), make_image(65, 8, mid));
  const float colour_only = flat.per_pixel[4 * 65 + 32];
  const float at_edge = with_edge.per_pixel[4 * 65 + 32];
  EXPECT_GT(colour_only, 0.1f);
  EXPECT_GT(at_edge, colour_only + 0.1f) << "colour error alone " << colour_only;
  // And at_edge = colour_only^(1 - ΔEf) for a ΔEf in (0, 1).
  const double ef = 1.0 - std::log(at_edge) / std::log(colour_only);
  EXPECT_GT(ef, 0.1);
  EXPECT_LT(ef, 1.0);
}

TEST(Flip, MeanFallsAsNoiseFalls) {
  const int w = 96, h = 64;
  ImageRGB ref = make_image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) ref.set(x, y, vec3(0.2f + 0.5f * x / w, 0.3f, 0.2f + 0.4f * y / h));
  }
  double previous = 1.0;
  for (float sigma : {0.2f, 0.1f, 0.05f, 0.02f, 0.005f}) {
    std::mt19937 rng(7);
    std::normal_distribution<float> noise(0.0f, sigma);
    ImageRGB test = ref;
    for (float& v : test.pixels) v += noise(rng);
    const double mean = ldr_flip(test, ref).mean;
    EXPECT_LT(mean, previous) << "sigma " << sigma;
    previous = mean;
  }
  EXPECT_GT(previous, 0.0);
}

TEST(Flip, NoiseIsLessVisibleWithMorePixelsPerDegree) {
  // Farther away (more pixels per degree), the CSFs blur fine noise more: the reference
  // implementation gives 0.315, 0.175 and 0.120 for one noisy pair at 30, 67 and 120 ppd.
  const ImageRGB a = busy_image(80, 60, 4);
  ImageRGB b = a;
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.0f, 0.1f);
  for (float& v : b.pixels) v += noise(rng);
  const double near = ldr_flip(b, a, 30.0).mean, mid = ldr_flip(b, a).mean,
               far = ldr_flip(b, a, 120.0).mean;
  EXPECT_GT(near, mid);
  EXPECT_GT(mid, far);
}

TEST(Flip, ExposureScalesBeforeTheDisplayClamp) {
  const ImageRGB a = busy_image(40, 30, 6), b = busy_image(40, 30, 8);
  ImageRGB a4 = a, b4 = b;
  for (float& v : a4.pixels) v *= 4.0f;
  for (float& v : b4.pixels) v *= 4.0f;
  const FlipResult plain = ldr_flip(a, b), exposed = ldr_flip(a4, b4, kFlipDefaultPpd, -2.0f);
  for (size_t i = 0; i < plain.per_pixel.size(); ++i) {
    ASSERT_NEAR(plain.per_pixel[i], exposed.per_pixel[i], 1e-6);
  }
  // Both clamp to white: no visible difference. NaN and negatives show as black.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(ldr_flip(make_image(8, 8, vec3(2.0f)), make_image(8, 8, vec3(1.0f))).mean, 0.0);
  EXPECT_EQ(ldr_flip(make_image(8, 8, vec3(nan)), make_image(8, 8, vec3(-1.0f))).mean, 0.0);
}

TEST(Flip, StaysFiniteAtExtremeViewingDistances) {
  // At 0.5 ppd the feature Gaussian underflows to a single tap; at 400 ppd the filters are wider
  // than the image. Either way every value must stay in [0, 1].
  const ImageRGB a = busy_image(40, 30, 9), b = busy_image(40, 30, 10);
  for (double ppd : {0.5, 400.0}) {
    const FlipResult r = ldr_flip(a, b, ppd);
    for (float v : r.per_pixel) ASSERT_TRUE(v >= 0.0f && v <= 1.0f) << ppd << ": " << v;
  }
}

TEST(Flip, RejectsMismatchedSizes) {
  EXPECT_THROW(ldr_flip(make_image(4, 4), make_image(4, 5)), InputError);
  const FlipResult empty = ldr_flip(make_image(0, 0), make_image(0, 0));
  EXPECT_TRUE(std::isnan(empty.mean));
  EXPECT_TRUE(empty.per_pixel.empty());
}

TEST(Flip, ErrorMapUsesMagma) {
  FlipResult r;
  r.width = 2;
  r.height = 1;
  r.per_pixel = {0.0f, 1.0f};
  const ImageRGB map = flip_error_map(r);
  ASSERT_EQ(map.width, 2);
  // magma's ends: #000004 and #FCFDBF, stored linear.
  EXPECT_NEAR(map.at(0, 0).z, srgb_to_linear(4.0f / 255.0f), 1e-6);
  EXPECT_NEAR(map.at(1, 0).x, srgb_to_linear(252.0f / 255.0f), 1e-6);
  EXPECT_NEAR(map.at(1, 0).z, srgb_to_linear(191.0f / 255.0f), 1e-6);
  // Brighter for larger errors.
  float prev = -1.0f;
  for (float t = 0.0f; t <= 1.0f; t += 0.125f) {
    const vec3 c = magma(t);
    const float lum = 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z;
    EXPECT_GT(lum, prev) << t;
    prev = lum;
  }
}

TEST(Flip, CompareCommandReportsFlipAndWritesTheMap) {
  std::string dir = testing::TempDir() + "flip_test_XXXXXX";
  ASSERT_NE(mkdtemp(dir.data()), nullptr);
  const std::string a = dir + "/a.exr", b = dir + "/b.exr", map = dir + "/map.png";
  const ImageRGB img_a = from_srgb(160, 120, edges_reference);
  const ImageRGB img_b = from_srgb(160, 120, edges_test);
  write_image(a, img_a);  // EXR keeps the float values exactly
  write_image(b, img_b);
  std::string log;
  const std::string exe = test::pathtracer_exe();
  ASSERT_EQ(test::run_command(exe + " compare --json " + a + " " + a, &log), 0) << log;
  EXPECT_EQ(nlohmann::json::parse(log.substr(log.find('{')))["flip"].get<double>(), 0.0);
  ASSERT_EQ(test::run_command(exe + " compare --json --flip-map " + map + " " + b + " " + a, &log),
            0)
      << log;
  const auto j = nlohmann::json::parse(log.substr(log.find('{')));
  const FlipResult r = ldr_flip(img_b, img_a);
  EXPECT_NEAR(j["flip"].get<double>(), r.mean, 1e-8);
  EXPECT_GT(j["relmse"].get<double>(), 0.0);  // the other metrics are still there
  // The map: magma of each pixel's FLIP, through an 8-bit PNG.
  const ImageRGB shown = read_image(map);
  ASSERT_EQ(shown.width, 160);
  ASSERT_EQ(shown.height, 120);
  for (int i : {10 * 160 + 10, 20 * 160 + 62, 50 * 160 + 62}) {
    const vec3 expected = magma(r.per_pixel[i]);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(linear_to_srgb(shown.pixels[3 * i + c]), linear_to_srgb(expected[c]), 1.0 / 255);
    }
  }
  EXPECT_NE(test::run_command(exe + " compare --ppd 0 " + a + " " + b, &log), 0);
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}

}  // namespace
}  // namespace tracer
