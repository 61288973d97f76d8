// Tests for tracer/core/rng.h: Pcg32 matches the reference PCG32, next_float is uniform on
// [0, 1) and never 1, and the per-path-vertex streams of make_path_rng are deterministic,
// distinct and uncorrelated across pixels, samples and bounces.
#include "core/rng.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <utility>
#include <vector>

#include "chi_square.h"

namespace tracer {
namespace {

constexpr double kSignificance = 0.01;
constexpr int kChiSquareTests = 3;
constexpr int kDraws = 1000000;

TEST(RngTest, MatchesReferencePcg32) {
  // pcg32-demo from pcg-random.org (pcg32_srandom_r(&rng, 42u, 54u)) prints these first words.
  Pcg32 rng(42u, 54u);
  const uint32_t expected[] = {0xa15c02b7, 0x7b47f409, 0xba1d3330,
                               0x83d2f293, 0xbfa4784b, 0xcbed606e};
  for (uint32_t e : expected) EXPECT_EQ(rng.next_u32(), e);
}

// A state whose next output is 0xffffffff: the output is rotr(((s >> 18) ^ s) >> 27, s >> 59),
// so with s >> 59 = 0 we need bits 27..58 of s ^ (s >> 18) all set; fill them from the top.
uint64_t state_for_all_ones() {
  uint64_t s = 0;
  for (int i = 58; i >= 27; --i) {
    const uint64_t above = i + 18 <= 63 ? (s >> (i + 18)) & 1u : 0u;
    s |= (1u ^ above) << i;
  }
  return s;
}

TEST(RngTest, NextFloatIsInUnitIntervalAndNeverOne) {
  Pcg32 rng;
  rng.state = state_for_all_ones();
  Pcg32 probe = rng;
  ASSERT_EQ(probe.next_u32(), 0xffffffffu);
  const float largest = rng.next_float();
  EXPECT_LT(largest, 1.0f);
  EXPECT_EQ(largest, 1.0f - 0x1p-24f);  // all 24 mantissa bits used

  Pcg32 r(7u, 3u);
  float lo = 1.0f, hi = 0.0f;
  for (int i = 0; i < 10 * kDraws; ++i) {
    const float x = r.next_float();
    ASSERT_GE(x, 0.0f);
    ASSERT_LT(x, 1.0f);
    lo = std::min(lo, x);
    hi = std::max(hi, x);
  }
  EXPECT_LT(lo, 1e-6f);  // the whole interval is reached
  EXPECT_GT(hi, 1.0f - 1e-6f);
}

TEST(RngTest, MeanAndVarianceOfUniform) {
  // Mean 1/2 with standard error sqrt(1/12 / n); variance 1/12 with standard error
  // sqrt((1/80 - 1/144) / n) = sqrt(1/180 / n). Five standard errors each.
  Pcg32 rng(12345u, 678u);
  double sum = 0.0, sum2 = 0.0;
  for (int i = 0; i < kDraws; ++i) {
    const double x = rng.next_float();
    sum += x;
    sum2 += x * x;
  }
  const double mean = sum / kDraws, var = sum2 / kDraws - mean * mean;
  EXPECT_NEAR(mean, 0.5, 5.0 * std::sqrt(1.0 / 12.0 / kDraws));
  EXPECT_NEAR(var, 1.0 / 12.0, 5.0 * std::sqrt(1.0 / 180.0 / kDraws));
}

TEST(RngTest, HistogramsOfSinglesAndPairsAreUniform) {
  // 1000 bins of single draws; 100 x 100 bins of consecutive pairs (next_2d), which catches
  // serial correlation that the mean and variance cannot.
  Pcg32 rng(99u, 1u);
  std::vector<double> singles(1000, 0.0), pairs(100 * 100, 0.0);
  for (int i = 0; i < kDraws; ++i) singles[int(rng.next_float() * 1000)] += 1.0;
  for (int i = 0; i < kDraws; ++i) {
    const vec2 u = rng.next_2d();
    pairs[int(u.y * 100) * 100 + int(u.x * 100)] += 1.0;
  }
  const chi2::Result a = chi2::chi_square_test(singles, std::vector<double>(1000, kDraws / 1000.0),
                                               kSignificance, kChiSquareTests);
  EXPECT_TRUE(a.passed) << a.message;
  const chi2::Result b = chi2::chi_square_test(pairs, std::vector<double>(10000, kDraws / 10000.0),
                                               kSignificance, kChiSquareTests);
  EXPECT_TRUE(b.passed) << b.message;
}

TEST(RngTest, PathStreamsAreDeterministic) {
  for (uint32_t seed : {0u, 1u, 2024u}) {
    Pcg32 a = make_path_rng(1234u, 17u, 3u, seed), b = make_path_rng(1234u, 17u, 3u, seed);
    for (int i = 0; i < 1000; ++i) ASSERT_EQ(a.next_u32(), b.next_u32());
    // A copy continues the same sequence.
    Pcg32 c = a;
    for (int i = 0; i < 100; ++i) ASSERT_EQ(a.next_float(), c.next_float());
  }
  Pcg32 x(5u, 6u), y(5u, 6u);
  EXPECT_EQ(x.next_2d(), y.next_2d());
}

TEST(RngTest, PathStreamsAreDistinct) {
  // Every (pixel, sample, bounce, seed) in a block starts a different sequence.
  std::set<std::pair<uint64_t, uint64_t>> starts;
  int streams = 0;
  for (uint32_t seed : {0u, 1u})
    for (uint32_t pixel = 0; pixel < 64; ++pixel)
      for (uint32_t sample = 0; sample < 16; ++sample)
        for (uint32_t bounce = 0; bounce < 8; ++bounce) {
          Pcg32 r = make_path_rng(pixel, sample, bounce, seed);
          uint64_t w0 = r.next_u32();
          w0 = (w0 << 32) | r.next_u32();
          uint64_t w1 = r.next_u32();
          w1 = (w1 << 32) | r.next_u32();
          starts.insert({w0, w1});
          ++streams;
        }
  EXPECT_EQ(starts.size(), size_t(streams));
  // Swapping the roles of the indices gives different streams too.
  EXPECT_NE(make_path_rng(1, 2, 3, 4).next_u32(), make_path_rng(2, 1, 3, 4).next_u32());
  EXPECT_NE(make_path_rng(1, 2, 3, 4).next_u32(), make_path_rng(1, 3, 2, 4).next_u32());
}

// Pearson correlation of the k-th draw of stream(i) and stream(i + 1) over n neighbours.
template <class Make>
double neighbour_correlation(Make make, int n, int draw) {
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  auto nth = [&](uint32_t i) {
    Pcg32 r = make(i);
    float x = 0.0f;
    for (int k = 0; k <= draw; ++k) x = r.next_float();
    return double(x);
  };
  double prev = nth(0);
  for (int i = 0; i < n; ++i) {
    const double next = nth(uint32_t(i + 1));
    sx += prev;
    sy += next;
    sxx += prev * prev;
    syy += next * next;
    sxy += prev * next;
    prev = next;
  }
  const double cov = sxy / n - (sx / n) * (sy / n);
  return cov / std::sqrt((sxx / n - (sx / n) * (sx / n)) * (syy / n - (sy / n) * (sy / n)));
}

TEST(RngTest, NeighbouringStreamsAreUncorrelated) {
  // With 1e6 pairs the correlation of independent streams has standard deviation 0.001, so
  // |r| < 0.01 is a 10-sigma bound that any systematic coupling of neighbours breaks.
  const int n = kDraws;
  for (int draw : {0, 1, 7}) {
    SCOPED_TRACE(testing::Message() << "draw " << draw);
    EXPECT_LT(std::abs(neighbour_correlation([](uint32_t i) { return make_path_rng(i, 0, 0, 0); },
                                             n, draw)),
              0.01);
    EXPECT_LT(std::abs(neighbour_correlation([](uint32_t i) { return make_path_rng(777, i, 1, 3); },
                                             n, draw)),
              0.01);
    EXPECT_LT(std::abs(neighbour_correlation(
                  [](uint32_t i) { return make_path_rng(4242, 9, i, 0); }, n, draw)),
              0.01);
    EXPECT_LT(std::abs(neighbour_correlation(
                  [](uint32_t i) { return make_path_rng(4242, 9, 2, i); }, n, draw)),
              0.01);
  }
  // The first draws of neighbouring pixels also fill the unit square evenly (a lattice
  // structure would leave it patchy while keeping the correlation near zero).
  std::vector<double> cells(50 * 50, 0.0);
  float prev = make_path_rng(0, 5, 0, 1).next_float();
  for (int i = 1; i <= n; ++i) {
    const float next = make_path_rng(uint32_t(i), 5, 0, 1).next_float();
    cells[int(next * 50) * 50 + int(prev * 50)] += 1.0;
    prev = next;
  }
  const chi2::Result r = chi2::chi_square_test(cells, std::vector<double>(2500, n / 2500.0),
                                               kSignificance, kChiSquareTests);
  EXPECT_TRUE(r.passed) << r.message;
}

}  // namespace
}  // namespace tracer
