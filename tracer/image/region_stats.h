// Per-region comparison of a render against a reference: the means per channel, their relative
// difference and relMSE, and whether a region differs by more than the images' own noise (a
// Student's t test per region and channel, Sidak-corrected over all of them).
#pragma once

#include <string>
#include <vector>

#include "image/image.h"
#include "image/regions.h"

namespace tracer {

// An image with what is known of its noise: the variance of `mean` per pixel and channel.
// Without a variance a test image's noise is unknown and a reference is treated as exact.
struct NoisyImage {
  ImageRGB mean;
  ImageRGB variance;  // empty when unknown
  std::string noise;  // how the variance was found, for reports; "" without one
  bool has_variance() const { return !variance.pixels.empty(); }
};

// Two independent renders of one scene (different seeds): the mean (a + b) / 2 and its variance
// ((a - b) / 2)^2 per pixel, unbiased since E[(a - b)^2] = 2 Var(a) = 4 Var((a + b) / 2).
// Throws InputError naming both sizes when they differ.
NoisyImage noisy_from_pair(const ImageRGB& a, const ImageRGB& b, const std::string& name_a,
                           const std::string& name_b);
// An image and a variance image of its mean (e.g. bench --error's NAME.variance.exr).
NoisyImage noisy_with_variance(const ImageRGB& mean, const ImageRGB& variance,
                               const std::string& name_mean, const std::string& name_variance);
NoisyImage noisy_without_variance(const ImageRGB& mean);

struct ChannelStats {
  double mean_test = 0, mean_ref = 0;    // NaN for an empty region
  double ratio = 0;                      // mean_test / mean_ref; NaN when mean_ref is 0
  double sigma_test = 0, sigma_ref = 0;  // standard errors of the means (NaN: unknown, 0: exact)
  double sigma = 0;      // of mean_test - mean_ref: sqrt(sigma_test^2 + sigma_ref^2)
  double dof = 0;        // Welch-Satterthwaite degrees of freedom of sigma^2
  double z = 0;          // (mean_test - mean_ref) / sigma; NaN when the test's noise is unknown
  double p = 0;          // two-sided, Student's t with `dof`; NaN when untested
  bool differs = false;  // p below the Sidak-corrected per-test significance
};

struct RegionStats {
  long pixels = 0;     // compared: kept by the mask and finite in every input
  long nonfinite = 0;  // kept by the mask but NaN/Inf in some input, left out
  ChannelStats channel[3];
  double relmse = 0;  // mean over pixels and channels of (t - r)^2 / (r + 0.01)^2 (pbrt's MRSE)
  bool differs = false;
};

struct RegionComparison {
  std::vector<RegionStats> regions;  // parallel to RegionMap::regions
  double significance = 0;           // family-wise: P(any region flagged | no real difference)
  int tests = 0;        // region channels tested (3 per non-empty region; 0 without noise)
  double per_test = 0;  // Sidak: 1 - (1 - significance)^(1 / tests)
  bool test_noise = false, ref_noise = false;
  std::string test_noise_source, ref_noise_source;
  int differing = 0;   // regions flagged
  long pixels = 0;     // compared in all regions
  long nonfinite = 0;  // left out as NaN/Inf
};

// Sums each region's kept pixels (those of `mask`, or all when null; pixels NaN/Inf in any input
// are left out and counted). sigma_test^2 = sum of the per-pixel variances / n^2 (pixels are
// independent estimates); its degrees of freedom are min(n, 3 (sum v)^2 / sum v^2), the
// Satterthwaite value for variances from one pair per pixel (E[d^4] = 3 Var^2 for a normal d):
// n for even noise, fewer where a few fireflies carry the sum, so the test stays honest on small
// regions and spiky noise. Throws InputError naming both sizes when any sizes differ.
RegionComparison compare_regions(const NoisyImage& test, const NoisyImage& ref,
                                 const RegionMap& regions, const PixelMask* mask,
                                 double significance);

// {"source", "significance", "tests", "per_test_significance", "test_noise", "reference_noise",
//  "pixels", "nonfinite_pixels", "differing", "regions": [{"name", "column", "row", "box",
//  "pixels", "nonfinite_pixels", "mean_test", "mean_ref", "ratio", "rel_diff", "sigma_test",
//  "sigma_ref", "sigma", "dof", "z", "p", "differs_channel", "relmse", "differs"}]}: per-channel
// values as [r, g, b]; undefined numbers (empty region, unknown noise) as null.
std::string region_comparison_to_json(const RegionMap& regions, const RegionComparison& c);

}  // namespace tracer
