// Tests for tracer/core/sobol.h: the samples of one (pixel, bounce, dimension pair) are a
// (0,m,2)-net for every m up to 8 (the single sequence: every aligned block of 2^m samples; the
// paired sampler: each half, even- or odd-numbered); each coordinate is uniform over pixels;
// pixels, dimension pairs and bounces are uncorrelated, and so are the two halves of the paired
// sampler, while those of the single sequence interleave; the same inputs give the same numbers.
#include "core/sobol.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "chi_square.h"

namespace tracer {
namespace {

vec2 point(uint32_t pixel, uint32_t sample, uint32_t bounce, uint32_t pair, uint32_t seed = 0,
           bool pairs = false) {
  return SobolVertex(pixel, sample, bounce, seed, pairs).get_2d(pair);
}

// Whether the 2^m points are a (0,m,2)-net: every elementary interval [i 2^-a, (i+1) 2^-a) x
// [j 2^-(m-a), (j+1) 2^-(m-a)), for every a from 0 to m, holds exactly one point.
bool is_02_net(const std::vector<vec2>& pts, int m) {
  const uint32_t n = 1u << m;
  if (pts.size() != n) return false;
  for (int a = 0; a <= m; ++a) {
    std::vector<int> count(n, 0);
    for (const vec2& p : pts) {
      const uint32_t i = uint32_t(p.x * float(1u << a));
      const uint32_t j = uint32_t(p.y * float(1u << (m - a)));
      if (++count[(i << (m - a)) | j] > 1) return false;
    }
  }
  return true;
}

TEST(Sobol, FirstDimensionsAreTheSobolSequence) {
  // Dimension 1's first points as fractions of 2^32 (Joe & Kuo's direction numbers, d = 2).
  const uint32_t expected1[] = {0x00000000u, 0x80000000u, 0xc0000000u, 0x40000000u,
                                0xa0000000u, 0x20000000u, 0x60000000u, 0xe0000000u};
  for (uint32_t i = 0; i < 8; ++i) {
    EXPECT_EQ(sobol_dim1(i), expected1[i]) << i;
    EXPECT_EQ(sobol_dim0(i), reverse_bits32(i));
  }
  Pcg32 rng(3u, 4u);
  for (int t = 0; t < 10000; ++t) {
    const uint32_t i = t < 64 ? uint32_t(t) : rng.next_u32();
    ASSERT_EQ(sobol_dim1_reversed(i), reverse_bits32(sobol_dim1(i))) << i;
  }
  // The vertex's points are the scrambles written out in full (sobol.h cancels reversals):
  // sequence index 13 for the single sequence, 13 >> 1 for the paired sampler.
  for (bool pairs : {false, true}) {
    const SobolVertex v(9, 13, 2, 4, pairs);
    const uint32_t shuffled = nested_uniform_scramble(pairs ? 13 >> 1 : 13, v.scramble_seed(3, 0));
    EXPECT_EQ(v.get_2d(3).x, fraction_to_float(nested_uniform_scramble(sobol_dim0(shuffled),
                                                                       v.scramble_seed(3, 1))));
    EXPECT_EQ(v.get_2d(3).y, fraction_to_float(nested_uniform_scramble(sobol_dim1(shuffled),
                                                                       v.scramble_seed(3, 2))));
  }
  for (int t = 0; t < 1000; ++t) {
    const uint64_t x = uint64_t(rng.next_u32()) << 32 | rng.next_u32();
    ASSERT_EQ(reverse_bits64(x),
              uint64_t(reverse_bits32(uint32_t(x))) << 32 | reverse_bits32(uint32_t(x >> 32)));
  }
  EXPECT_EQ(reverse_bits32(1u), 0x80000000u);
  EXPECT_EQ(reverse_bits32(0x12345678u), 0x1e6a2c48u);
}

TEST(Sobol, NestedScrambleIsABijectionOnEveryPrefixBlock) {
  // A nested scramble maps each aligned block of 2^k values onto an aligned block of 2^k values
  // (the digits above k only depend on the digits above them), bijectively.
  for (uint32_t seed : {0u, 1u, 0xdeadbeefu}) {
    for (int k : {1, 4, 8}) {
      std::vector<int> hit(1u << k, 0);
      uint32_t block = 0;
      for (uint32_t i = 0; i < (1u << k); ++i) {
        const uint32_t y = nested_uniform_scramble(i << (32 - k), seed);
        hit[y >> (32 - k)]++;
        // Indices (low digits) shuffled: those below 2^k stay in one block of 2^k.
        const uint32_t s = nested_uniform_scramble(i, seed);
        if (i == 0) block = s >> k;
        EXPECT_EQ(s >> k, block);
      }
      for (int h : hit) EXPECT_EQ(h, 1) << "seed " << seed << " k " << k;
    }
  }
}

TEST(Sobol, EveryAlignedBlockOfTheSequenceIsA02Net) {
  // The first 2^m samples, and every later aligned block of 2^m, of the single sequence.
  for (uint32_t pixel : {0u, 7u, 123456u}) {
    for (uint32_t bounce : {0u, 3u}) {
      for (uint32_t pair : {0u, 1u, 4u}) {
        for (int m = 0; m <= 8; ++m) {
          for (uint32_t block : {0u, 1u, 5u}) {
            std::vector<vec2> pts;
            for (uint32_t k = 0; k < (1u << m); ++k)
              pts.push_back(point(pixel, (block << m) + k, bounce, pair, 5));
            EXPECT_TRUE(is_02_net(pts, m)) << "pixel " << pixel << " bounce " << bounce << " pair "
                                           << pair << " block " << block << " m " << m;
          }
        }
      }
    }
  }
}

TEST(Sobol, EachHalfOfThePairedSamplerIsA02Net) {
  for (uint32_t pixel : {0u, 7u, 123456u}) {
    for (uint32_t bounce : {0u, 3u}) {
      for (uint32_t pair : {0u, 1u, 4u}) {
        for (uint32_t half : {0u, 1u}) {
          for (int m = 0; m <= 8; ++m) {
            std::vector<vec2> pts;
            for (uint32_t k = 0; k < (1u << m); ++k)
              pts.push_back(point(pixel, 2 * k + half, bounce, pair, 5, true));
            EXPECT_TRUE(is_02_net(pts, m)) << "pixel " << pixel << " bounce " << bounce << " pair "
                                           << pair << " half " << half << " m " << m;
          }
        }
      }
    }
  }
}

TEST(Sobol, NetCheckRejectsIndependentPoints) {
  // The net test can fail: 256 independent uniform points are almost never a (0,8,2)-net.
  Pcg32 rng(1u, 2u);
  std::vector<vec2> pts;
  for (int i = 0; i < 256; ++i) pts.push_back(rng.next_2d());
  EXPECT_FALSE(is_02_net(pts, 8));
  // Nor are the first 256 samples of the paired sampler's two halves mixed (two independent
  // randomizations), nor 256 samples of the single sequence that straddle two blocks.
  pts.clear();
  for (uint32_t n = 0; n < 256; ++n) pts.push_back(point(3, n, 1, 2, 0, true));
  EXPECT_FALSE(is_02_net(pts, 8));
  pts.clear();
  for (uint32_t n = 128; n < 384; ++n) pts.push_back(point(3, n, 1, 2));
  EXPECT_FALSE(is_02_net(pts, 8));
}

TEST(Sobol, CoordinatesAreUniformOverPixels) {
  // For a fixed sample index, the randomization makes every coordinate uniform: 4096 pixels,
  // 64 bins, a chi-square test per (sample, pair, coordinate), Sidak-corrected.
  constexpr int kBins = 64, kPixels = 4096;
  const uint32_t samples[] = {0u, 1u, 2u, 77u, 1000001u};
  const uint32_t pairs[] = {0u, 1u, 2u, 3u, 4u};
  const int tests = 5 * 5 * 2 * 2;
  const double alpha = 1.0 - std::pow(1.0 - 0.01, 1.0 / tests);
  for (uint32_t bounce : {0u, 2u}) {
    for (uint32_t n : samples) {
      for (uint32_t pair : pairs) {
        for (int c = 0; c < 2; ++c) {
          std::vector<int> hist(kBins, 0);
          for (uint32_t p = 0; p < kPixels; ++p) {
            const vec2 u = point(p, n, bounce, pair);
            ASSERT_GE(u[c], 0.0f);
            ASSERT_LT(u[c], 1.0f);
            hist[int(u[c] * kBins)]++;
          }
          double chi2 = 0.0;
          const double e = double(kPixels) / kBins;
          for (int h : hist) chi2 += (h - e) * (h - e) / e;
          const double p_value = chi2::gamma_q(0.5 * (kBins - 1), 0.5 * chi2);
          EXPECT_GT(p_value, alpha) << "sample " << n << " pair " << pair << " coord " << c
                                    << " bounce " << bounce << " chi2 " << chi2;
        }
      }
    }
  }
  // The 1D draw is the first coordinate of its pair.
  for (bool pairs : {false, true}) {
    const SobolVertex v(11, 6, 2, 9, pairs);
    EXPECT_EQ(v.get_1d(3), v.get_2d(3).x);
  }
}

double correlation(const std::vector<double>& a, const std::vector<double>& b) {
  double ma = 0, mb = 0;
  for (size_t i = 0; i < a.size(); ++i) ma += a[i], mb += b[i];
  ma /= a.size();
  mb /= b.size();
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

TEST(Sobol, PixelsPairsBouncesAndPairedHalvesAreUncorrelated) {
  // Pearson correlation over 1024 pixels x 64 samples; independent streams give |r| ~ 1/256.
  constexpr uint32_t kPixels = 1024, kSamples = 64;
  const double limit = 5.0 / std::sqrt(double(kPixels * kSamples));
  struct Case {
    const char* what;
    uint32_t dpixel, dsample, bounce_b, pair_a, pair_b;
    int coord_b;
    bool pairs;  // the paired sampler, else the single sequence
  };
  // Sample 2k + 1 against sample 2k: the two half-buffer estimates, independent with the paired
  // sampler. The single sequence pairs x with x +- 1/2 there (checked below).
  const Case cases[] = {{"neighbouring pixels", 1, 0, 1, 2, 2, 0, false},
                        {"dimension pairs 2 and 3", 0, 0, 1, 2, 3, 0, false},
                        {"pair 1 x against pair 2 y", 0, 0, 1, 1, 2, 1, false},
                        // The three scrambles of a pair take seeds from one hash (rotated).
                        {"x against y of one pair", 0, 0, 1, 2, 2, 1, false},
                        {"paired: x against y of one pair", 0, 0, 1, 2, 2, 1, true},
                        {"bounces 1 and 2", 0, 0, 2, 2, 2, 0, false},
                        {"paired: neighbouring pixels", 1, 0, 1, 2, 2, 0, true},
                        {"paired: bounces 1 and 2", 0, 0, 2, 2, 2, 0, true},
                        {"paired: even and odd samples", 0, 1, 1, 2, 2, 0, true},
                        {"single against paired, same seed", 0, 0, 1, 2, 2, 0, true}};
  auto series = [&](const Case& cs, double* r) {
    std::vector<double> a, b;
    for (uint32_t p = 0; p < kPixels; ++p) {
      for (uint32_t k = 0; k < kSamples; ++k) {
        const uint32_t n = cs.dsample ? 2 * k : k;
        // The last case compares the two samplers; the others one sampler with itself.
        const bool a_pairs = cs.pairs && cs.what[0] != 's';
        a.push_back(point(p, n, 1, cs.pair_a, 0, a_pairs).x);
        b.push_back(
            point(p + cs.dpixel, n + cs.dsample, cs.bounce_b, cs.pair_b, 0, cs.pairs)[cs.coord_b]);
      }
    }
    *r = correlation(a, b);
  };
  for (const Case& cs : cases) {
    double r;
    series(cs, &r);
    EXPECT_LT(std::abs(r), limit) << cs.what << ": r = " << r;
  }
  // The single sequence's even and odd samples fill each other's gaps: strongly anti-correlated
  // (x against x +- 1/2 in the first digit: r = -3/4), which is why its half-buffer noise
  // estimates read high.
  double r;
  series({"single: even and odd samples", 0, 1, 1, 2, 2, 0, false}, &r);
  EXPECT_LT(r, -0.5);
  // The check can fail: x against itself shifted by half a period.
  std::vector<double> a, b;
  for (uint32_t k = 0; k < 256; ++k) {
    a.push_back(fraction_to_float(sobol_dim0(2 * k)));
    b.push_back(fraction_to_float(sobol_dim0(2 * k + 1)));
  }
  EXPECT_GT(std::abs(correlation(a, b)), 0.9);
}

TEST(Sobol, Deterministic) {
  for (uint32_t n = 0; n < 100; ++n) {
    const vec2 a = point(42, n, 3, 1, 7), b = point(42, n, 3, 1, 7);
    EXPECT_EQ(a, b);
  }
  // Every input changes the numbers.
  const vec2 base = point(42, 10, 3, 1, 7);
  EXPECT_NE(base, point(43, 10, 3, 1, 7));
  EXPECT_NE(base, point(42, 11, 3, 1, 7));
  EXPECT_NE(base, point(42, 10, 4, 1, 7));
  EXPECT_NE(base, point(42, 10, 3, 2, 7));
  EXPECT_NE(base, point(42, 10, 3, 1, 8));
  EXPECT_NE(base, point(42, 10, 3, 1, 7, true));
}

}  // namespace
}  // namespace tracer
