// Pixel reconstruction filters, applied by where a camera sample lands rather than by weights:
// each sample's offset from the pixel centre is drawn with density proportional to the filter
// (separable, x and y alike), so every sample has weight 1 and the film keeps its plain average.
// This is the filter-importance-sampling of pbrt-v4 (sec. 8.8) with exact sampling: the tent by
// its inverse CDF, the Gaussian and Blackman-Harris by rejection from a uniform proposal. For
// non-negative filters it is unbiased for the filtered image, and no sample is splatted into
// neighbouring pixels.
#pragma once

#include "core/hd.h"
#include "core/math.h"

namespace tracer {

enum class PixelFilter : uint32_t { kBox = 0, kTent = 1, kGaussian = 2, kBlackmanHarris = 3 };

// The radius used when the setting gives 0: box 0.5 (one pixel), tent 1 (as Tungsten's and
// pbrt-v4's triangle references), Gaussian 1.5 (pbrt-v4's default; sigma = radius / 3),
// Blackman-Harris 1 (a window two pixels wide).
TRACER_HD TRACER_INLINE float default_filter_radius(PixelFilter f) {
  switch (f) {
    case PixelFilter::kBox: return 0.5f;
    case PixelFilter::kTent: return 1.0f;
    case PixelFilter::kGaussian: return 1.5f;
    case PixelFilter::kBlackmanHarris: return 1.0f;
  }
  return 0.5f;
}

// The 1D filter profile on [-radius, radius], up to a constant (peak 1 at 0).
TRACER_HD TRACER_INLINE float filter_profile(PixelFilter f, float radius, float x) {
  const float a = glm::abs(x);
  if (a > radius) return 0.0f;
  switch (f) {
    case PixelFilter::kBox: return 1.0f;
    case PixelFilter::kTent: return 1.0f - a / radius;
    case PixelFilter::kGaussian: {
      // pbrt-v4's Gaussian: the bell minus its value at the radius, so it reaches 0 there.
      const float sigma = radius / 3.0f;
      const float g = glm::exp(-0.5f * x * x / (sigma * sigma));
      const float edge = glm::exp(-4.5f);
      return (g - edge) / (1.0f - edge);
    }
    case PixelFilter::kBlackmanHarris: {
      // The 4-term Blackman-Harris window over [-radius, radius] (Harris 1978), centred.
      const float t = 2.0f * kPi * (x / (2.0f * radius) + 0.5f);
      const float w = 0.35875f - 0.48829f * glm::cos(t) + 0.14128f * glm::cos(2.0f * t) -
                      0.01168f * glm::cos(3.0f * t);
      return w;  // 1 at the centre (0.35875 + 0.48829 + 0.14128 + 0.01168 = 1)
    }
  }
  return 1.0f;
}

// A 1D offset from the pixel centre with density proportional to the filter's profile. `u` is the
// first uniform number (from the sampler, so that box and tent keep its stratification);
// `next()` supplies more for rejection (at most 64 tries; the acceptance rate is 41% for the
// Gaussian and 36% for Blackman-Harris, so running out has probability below 1e-12).
template <class Next>
TRACER_HD inline float sample_filter_1d(PixelFilter f, float radius, float u, Next&& next) {
  switch (f) {
    case PixelFilter::kBox:
      return (2.0f * u - 1.0f) * radius;
    case PixelFilter::kTent: {
      // Inverse CDF of the tent on [-r, r], one half at a time.
      if (u < 0.5f) return radius * (glm::sqrt(2.0f * u) - 1.0f);
      return radius * (1.0f - glm::sqrt(2.0f - 2.0f * u));
    }
    default: {
      for (int i = 0; i < 64; ++i) {
        const float x = (2.0f * u - 1.0f) * radius;
        if (next() < filter_profile(f, radius, x)) return x;
        u = next();
      }
      return 0.0f;
    }
  }
}

}  // namespace tracer
