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

vec3 tone_map(vec3 linear, ToneMap op) {
  return vec3(tone_map_channel(linear.x, op), tone_map_channel(linear.y, op),
              tone_map_channel(linear.z, op));
}

float linear_to_srgb(float linear01) { return srgb_encode(linear01); }

// The inverse (EOTF); the 0.04045 threshold is 12.92 * 0.0031308.
float srgb_to_linear(float encoded01) {
  const float v = display_clamp01(encoded01);
  if (v <= 0.04045f) return v / 12.92f;
  return std::pow((v + 0.055f) / 1.055f, 2.4f);
}

uint8_t to_srgb8(float linear01) { return srgb8(linear01); }

}  // namespace tracer
