// Error of a progressive render against a reference, split into its noise and its bias, and the
// convergence figures derived from a sweep: log-log slope, time to an error, efficiency.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "image/image.h"

namespace tracer {

// A reference image and the variance of its mean per pixel and channel (empty when unknown).
struct ReferenceImage {
  ImageRGB mean;
  ImageRGB variance;
};

// Where the variance image of a reference lives: "dir/NAME.exr" -> "dir/NAME.variance.exr".
std::string variance_path_for(const std::string& reference_path);

// Per-pixel variance of the mean of two equal-sized half estimates (even and odd samples):
// E[(a - b)^2] = 4 Var((a + b) / 2), so the estimate is (a - b)^2 / 4. Unbiased, but it rests on
// one pair per pixel, so it is noisy per pixel and only its averages are meaningful.
ImageRGB variance_from_halves(const ImageRGB& even, const ImageRGB& odd);

// All terms except rmse are means over pixels and channels of squared errors divided by
// (r + 0.01)^2, the pbrt-v4 relMSE regulariser used everywhere in the project.
struct ErrorTerms {
  double relmse_raw = 0;       // (t - r)^2 against the reference as stored
  double reference_floor = 0;  // the reference's own share, Var(r); 0 without a variance image
  double relmse = 0;           // relmse_raw - reference_floor: the test image's own error
  double rmse = 0;             // sqrt(mean (t - r)^2), absolute, raw
  double variance = -1;        // the test's noise from its half buffers; < 0 when unknown
  double bias2 = 0;            // relmse - variance: the squared bias in relMSE units
  double bias2_stderr = 0;     // its standard error over pixels (taken as independent)
  bool block_test = false;     // bias2 from 2x2/8x8-pixel block means (halves not independent)
  bool has_variance() const { return variance >= 0; }
  // Bias that is both statistically clear (4 standard errors) and a visible share (10%) of the
  // error: the error will plateau instead of falling as 1/samples.
  bool significant_bias() const {
    return has_variance() && bias2 > 4.0 * bias2_stderr && bias2 > 0.1 * relmse;
  }
};

// `even` and `odd` (the test's half buffers) may be null, e.g. at one sample per pixel: the
// variance and the bias then stay unknown. Throws InputError when the sizes differ.
//
// `independent_halves` false (the single Sobol sequence, whose halves are anti-correlated and
// overstate the noise 2-3x): the bias is estimated from the means of the relative error over
// 2x2- and 8x8-pixel blocks instead, where the noise averages down 4- and 64-fold and a bias of
// one sign does not. Each block estimate subtracts the halves' (overstated) noise and the
// reference's, divided by the block's pixel count, so it is a lower bound of the squared bias
// (exact for a bias that is constant over each block); the one further from zero in standard
// errors is reported, and `variance` is then the rest of the error, relmse - bias2.
ErrorTerms error_terms(const ImageRGB& test, const ReferenceImage& ref,
                       const ImageRGB* even = nullptr, const ImageRGB* odd = nullptr,
                       bool independent_halves = true);

// A reference rendered with the same seed and sampler as the image compared with it shares that
// image's first samples: the error then reads too low (E[(t - r)^2] = Var t - Var r). Reads the
// reference's JSON sidecar (`<path>.json`, from `pathtracer render` or `bench --error`) and
// returns a warning naming the file when seed and sampler match, else "" (also without one).
std::string reference_independence_warning(const std::string& reference_path, uint32_t seed,
                                           const std::string& sampler);

// One point of a sweep: the image after `spp` samples, `seconds` of rendering in total.
struct Checkpoint {
  uint32_t spp = 0;
  double seconds = 0;
  ErrorTerms error;
  double flip = -1;  // mean LDR-FLIP against the reference; < 0 when not computed
};

// When a sweep first reaches relMSE `target`: log-log interpolation between the two checkpoints
// around it. Not reached: extrapolated from the last checkpoint (`extrapolated` set) as error ~
// 1/time, or, when the last checkpoint has a significant bias, with only its noise part falling
// as 1/time; "never" (< 0) when the bias alone exceeds the target.
struct TimeToError {
  double seconds = -1;
  bool extrapolated = false;
};
TimeToError time_to_error(const std::vector<Checkpoint>& sweep, double target);

struct ConvergenceSummary {
  double slope = 0;         // least squares of log relMSE against log spp
  double slope_stderr = 0;  // from the fit's residuals
  int slope_points = 0;     // checkpoints used (spp >= 2 with a positive relMSE)
  TimeToError to_1e2, to_1e3;
  double efficiency = 0;  // 1 / (relMSE * seconds) at the last checkpoint
  bool biased = false;    // significant bias at the last checkpoint, or a flat slope
  std::string verdict;    // one line for people, e.g. "unbiased (slope -1.01 +- 0.02)"
};
ConvergenceSummary summarize(const std::vector<Checkpoint>& sweep);

}  // namespace tracer
