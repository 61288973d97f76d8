// The image buffer and the display transform: tone mapping operators and the sRGB transfer
// functions used by PNG export and by decoding 8-bit textures.
#include "image/image.h"

#include <cassert>
#include <cctype>
#include <cmath>

namespace tracer {

vec3 ImageRGB::at(int x, int y) const {
  assert(x >= 0 && x < width && y >= 0 && y < height);
  const size_t i = 3 * (static_cast<size_t>(y) * width + x);
  return vec3(pixels[i], pixels[i + 1], pixels[i + 2]);
}

void ImageRGB::set(int x, int y, vec3 c) {
  assert(x >= 0 && x < width && y >= 0 && y < height);
  const size_t i = 3 * (static_cast<size_t>(y) * width + x);
  pixels[i] = c.x;
  pixels[i + 1] = c.y;
  pixels[i + 2] = c.z;
}

ImageRGB make_image(int width, int height, vec3 fill) {
  ImageRGB img;
  img.width = width;
  img.height = height;
  const size_t n = static_cast<size_t>(width) * height;
  img.pixels.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    img.pixels[3 * i] = fill.x;
    img.pixels[3 * i + 1] = fill.y;
    img.pixels[3 * i + 2] = fill.z;
  }
  return img;
}

const char* tone_map_name(ToneMap op) {
  switch (op) {
    case ToneMap::kNone:
      return "none";
    case ToneMap::kReinhard:
      return "reinhard";
    case ToneMap::kAces:
      return "aces";
  }
  return "none";
}

bool parse_tone_map(const std::string& name, ToneMap* op) {
  std::string lower;
  for (char c : name) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (ToneMap candidate : {ToneMap::kNone, ToneMap::kReinhard, ToneMap::kAces}) {
    if (lower == tone_map_name(candidate)) {
      *op = candidate;
      return true;
    }
  }
  return false;
}

namespace {

// Written so that NaN fails every comparison and lands on 0, as does -Inf; +Inf is treated as a
// bad sample too (0) rather than as white, so that it is visible as a dark speck, not hidden.
float clamp01(float v) {
  if (!(v > 0.0f) || !std::isfinite(v)) return 0.0f;
  return v < 1.0f ? v : 1.0f;
}

float reinhard(float c) {
  return c / (1.0f + c);
}

// Narkowicz, "ACES Filmic Tone Mapping Curve" (2016): a rational fit to the ACES RRT+ODT.
float aces_narkowicz(float x) {
  constexpr float kA = 2.51f, kB = 0.03f, kC = 2.43f, kD = 0.59f, kE = 0.14f;
  return (x * (kA * x + kB)) / (x * (kC * x + kD) + kE);
}

}  // namespace

vec3 tone_map(vec3 linear, ToneMap op) {
  vec3 out;
  for (int c = 0; c < 3; ++c) {
    float v = linear[c];
    // Bad and negative values go to 0 before the operator, so neither curve sees them.
    if (!(v > 0.0f) || !std::isfinite(v)) {
      out[c] = 0.0f;
      continue;
    }
    switch (op) {
      case ToneMap::kNone:
        break;
      case ToneMap::kReinhard:
        v = reinhard(v);
        break;
      case ToneMap::kAces:
        v = aces_narkowicz(v);
        break;
    }
    out[c] = clamp01(v);
  }
  return out;
}

// IEC 61966-2-1 sRGB OETF: linear segment below 0.0031308, then a 1/2.4 power with offset.
float linear_to_srgb(float linear01) {
  const float v = clamp01(linear01);
  if (v <= 0.0031308f) return 12.92f * v;
  return 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

// The inverse (EOTF); the 0.04045 threshold is 12.92 * 0.0031308.
float srgb_to_linear(float encoded01) {
  const float v = clamp01(encoded01);
  if (v <= 0.04045f) return v / 12.92f;
  return std::pow((v + 0.055f) / 1.055f, 2.4f);
}

uint8_t to_srgb8(float linear01) {
  return static_cast<uint8_t>(linear_to_srgb(linear01) * 255.0f + 0.5f);
}

}  // namespace tracer
