// Error metrics between a render and a reference (RMSE, relMSE, means), a false-colour error
// image for looking at where they differ, and the JSON form the CLI writes next to a comparison.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/diagnostics.h"
#include "image/image.h"

namespace tracer {
namespace {

// The +0.01 keeps the relative error finite where the reference is black; the same regulariser as
// pbrt-v4's Image::MRSE (src/pbrt/util/image.cpp): (t - r)^2 / (r + 0.01)^2.
constexpr double kRelEpsilon = 0.01;
// The false-colour scale: relative squared errors from 1e-4 (invisible) to 1 (100% error).
constexpr double kLogErrorMin = -4.0, kLogErrorMax = 0.0;

void check_same_size(const ImageRGB& test, const ImageRGB& ref) {
  auto size = [](const ImageRGB& img) {
    return std::to_string(img.width) + "x" + std::to_string(img.height);
  };
  if (test.width != ref.width || test.height != ref.height) {
    throw InputError(SourceLoc{"image comparison", 0},
                     "the test image is " + size(test) + " but the reference is " + size(ref),
                     "nothing was compared");
  }
  for (const ImageRGB* img : {&test, &ref}) {
    if (img->width < 0 || img->height < 0 ||
        img->pixels.size() != 3 * static_cast<size_t>(img->width) * img->height) {
      // A programming error, not bad input: the buffer does not match its own size fields.
      throw std::invalid_argument("compare_images: pixel buffer does not match " + size(*img));
    }
  }
}

double rel_sq_error(double t, double r) {
  const double d = t - r;
  return d * d / ((r + kRelEpsilon) * (r + kRelEpsilon));
}

// Shortest decimal that reads back as the same double; JSON has no NaN/Inf, so those are null.
std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  for (int precision = 15; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

// The same for a float, so that a float mean prints as 0.1 rather than 0.10000000149011612.
std::string json_float(float v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  for (int precision = 6; precision <= 9; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, static_cast<double>(v));
    if (std::strtof(buf, nullptr) == v) break;
  }
  return buf;
}

std::string json_vec3(vec3 v) {
  return "[" + json_float(v.x) + "," + json_float(v.y) + "," + json_float(v.z) + "]";
}

}  // namespace

CompareResult compare_images(const ImageRGB& test, const ImageRGB& ref,
                             const std::vector<uint8_t>* keep) {
  check_same_size(test, ref);
  if (keep && keep->size() != test.pixels.size() / 3) {
    throw std::invalid_argument("compare_images: the pixel mask does not match the image size");
  }
  CompareResult out;
  out.width = test.width;
  out.height = test.height;

  // Doubles: a 4k image has 2.5e7 values, well past float's 2^24 exact-integer range.
  double sum_sq = 0.0, sum_rel = 0.0;
  long pairs = 0;
  double sum_test[3] = {0, 0, 0}, sum_ref[3] = {0, 0, 0};
  long count_test[3] = {0, 0, 0}, count_ref[3] = {0, 0, 0};
  for (size_t i = 0; i < test.pixels.size(); ++i) {
    if (keep && !(*keep)[i / 3]) continue;
    const int c = static_cast<int>(i % 3);
    const double t = test.pixels[i], r = ref.pixels[i];
    const bool t_ok = std::isfinite(t), r_ok = std::isfinite(r);
    if (t_ok) {
      sum_test[c] += t;
      ++count_test[c];
    } else {
      ++out.nonfinite_test;
    }
    if (r_ok) {
      sum_ref[c] += r;
      ++count_ref[c];
    } else {
      ++out.nonfinite_ref;
    }
    if (!t_ok || !r_ok) continue;
    ++pairs;
    sum_sq += (t - r) * (t - r);
    // Only r == -0.01 makes this non-finite; pbrt skips such terms and so do we.
    const double rel = rel_sq_error(t, r);
    if (std::isfinite(rel)) sum_rel += rel;
  }

  const double nan = std::numeric_limits<double>::quiet_NaN();
  out.rmse = pairs > 0 ? std::sqrt(sum_sq / pairs) : nan;
  out.relmse = pairs > 0 ? sum_rel / pairs : nan;
  for (int c = 0; c < 3; ++c) {
    out.mean_test[c] = static_cast<float>(count_test[c] > 0 ? sum_test[c] / count_test[c] : nan);
    out.mean_ref[c] = static_cast<float>(count_ref[c] > 0 ? sum_ref[c] / count_ref[c] : nan);
  }
  return out;
}

vec3 color_ramp(const unsigned* stops, int count, float t) {
  const int segments = count - 1;
  if (!(t > 0.0f)) t = 0.0f;  // also catches NaN
  if (t > 1.0f) t = 1.0f;
  const float s = t * segments;
  const int i = s >= segments ? segments - 1 : static_cast<int>(s);
  const float f = s - static_cast<float>(i);
  vec3 out;
  for (int c = 0; c < 3; ++c) {
    const int shift = 16 - 8 * c;
    const float a = static_cast<float>((stops[i] >> shift) & 0xff) / 255.0f;
    const float b = static_cast<float>((stops[i + 1] >> shift) & 0xff) / 255.0f;
    out[c] = srgb_to_linear(a + (b - a) * f);
  }
  return out;
}

vec3 viridis(float t) {
  // matplotlib's viridis sampled at 9 even steps (the values R's viridis(9) prints), sRGB-encoded.
  // Interpolating the encoded values keeps the steps perceptually even, as the map was designed.
  static const unsigned kStops[] = {0x440154, 0x472D7B, 0x3B528B, 0x2C728E, 0x21908C,
                                    0x27AD81, 0x5DC863, 0xAADC32, 0xFDE725};
  return color_ramp(kStops, 9, t);
}

ImageRGB false_color_difference(const ImageRGB& test, const ImageRGB& ref) {
  check_same_size(test, ref);
  ImageRGB out = make_image(test.width, test.height);
  const vec3 kMagenta(1.0f, 0.0f, 1.0f);
  for (int y = 0; y < test.height; ++y) {
    for (int x = 0; x < test.width; ++x) {
      const vec3 t = test.at(x, y), r = ref.at(x, y);
      double err = 0.0;
      for (int c = 0; c < 3; ++c) err += rel_sq_error(t[c], r[c]);
      err /= 3.0;
      if (!std::isfinite(err)) {  // NaN/Inf in either image (or r == -0.01)
        out.set(x, y, kMagenta);
        continue;
      }
      const double log_err = err > 0.0 ? std::log10(err) : kLogErrorMin;
      const double u = (log_err - kLogErrorMin) / (kLogErrorMax - kLogErrorMin);
      out.set(x, y, viridis(static_cast<float>(u)));
    }
  }
  return out;
}

std::string compare_to_json(const CompareResult& r) {
  return "{\"width\":" + std::to_string(r.width) + ",\"height\":" + std::to_string(r.height) +
         ",\"rmse\":" + json_number(r.rmse) + ",\"relmse\":" + json_number(r.relmse) +
         ",\"mean_test\":" + json_vec3(r.mean_test) + ",\"mean_ref\":" + json_vec3(r.mean_ref) +
         ",\"nonfinite_test\":" + std::to_string(r.nonfinite_test) +
         ",\"nonfinite_ref\":" + std::to_string(r.nonfinite_ref) + "}";
}

}  // namespace tracer
