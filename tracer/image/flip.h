// LDR-FLIP, the perceptual image difference of Andersson et al., "FLIP: A Difference Evaluator
// for Alternating Images" (HPG 2020): a per-pixel error in [0, 1] for what a viewer flipping
// between two images would notice, and its mean. Also the magma error map the FLIP tool shows.
#pragma once

#include <vector>

#include "image/image.h"

namespace tracer {

// Pixels per degree of visual angle for a 0.7 m wide, 3840-pixel monitor seen from 0.7 m: the
// FLIP paper's default observer, 0.7 * (3840 / 0.7) * pi / 180.
constexpr double kFlipDefaultPpd = 67.02064327658226;

struct FlipResult {
  int width = 0, height = 0;
  double mean = 0.0;             // mean of per_pixel; NaN for an empty image
  std::vector<float> per_pixel;  // width * height values in [0, 1], row-major, top row first
};

// LDR-FLIP between two linear images. Each is first mapped to what an LDR display shows, as
// LDR-FLIP expects sRGB input in [0, 1]: multiplied by 2^exposure_stops and clamped to [0, 1]
// (NaN and negative values give 0, +Inf gives 1), with no tone map. The result is symmetric in
// its two arguments. Throws InputError if the sizes differ. Single-threaded.
FlipResult ldr_flip(const ImageRGB& test, const ImageRGB& reference,
                    double pixels_per_degree = kFlipDefaultPpd, float exposure_stops = 0.0f);

// Magma (van der Walt & Smith 2015) at t in [0, 1], clamped, as linear RGB.
vec3 magma(float t);
// The per-pixel FLIP values through magma, stored linear so that a PNG of the result shows the
// map's sRGB values (black is no error, pale yellow is FLIP 1).
ImageRGB flip_error_map(const FlipResult& flip);

}  // namespace tracer
