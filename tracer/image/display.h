// The display transform shared by the PNG writer and the GPU's display kernel: exposure, a tone
// map, the sRGB OETF (IEC 61966-2-1) and 8-bit quantisation. NaN, infinities and negative values
// display as black, so that bad samples show as dark specks instead of being hidden.
#pragma once

#include "core/math.h"

namespace tracer {

enum class ToneMap { kNone, kReinhard, kAces };  // kNone = clamp to [0, 1]

TRACER_HD TRACER_INLINE float display_clamp01(float v) {
  if (!(v > 0.0f) || !is_finite(v)) return 0.0f;
  return v < 1.0f ? v : 1.0f;
}

// Narkowicz, "ACES Filmic Tone Mapping Curve" (2016): a rational fit to the ACES RRT+ODT.
TRACER_HD TRACER_INLINE float aces_narkowicz(float x) {
  constexpr float kA = 2.51f, kB = 0.03f, kC = 2.43f, kD = 0.59f, kE = 0.14f;
  return (x * (kA * x + kB)) / (x * (kC * x + kD) + kE);
}

TRACER_HD TRACER_INLINE float tone_map_channel(float v, ToneMap op) {
  if (!(v > 0.0f) || !is_finite(v)) return 0.0f;
  switch (op) {
    case ToneMap::kNone: break;
    case ToneMap::kReinhard: v = v / (1.0f + v); break;
    case ToneMap::kAces: v = aces_narkowicz(v); break;
  }
  return display_clamp01(v);
}

TRACER_HD TRACER_INLINE float srgb_encode(float linear01) {
  const float v = display_clamp01(linear01);
  if (v <= 0.0031308f) return 12.92f * v;
  return 1.055f * glm::pow(v, 1.0f / 2.4f) - 0.055f;
}

TRACER_HD TRACER_INLINE uint8_t srgb8(float linear01) {
  return uint8_t(srgb_encode(linear01) * 255.0f + 0.5f);
}

// RGBA8 (alpha 255) packed little-endian as R | G << 8 | B << 16 | A << 24.
TRACER_HD TRACER_INLINE uint32_t display_rgba8(vec3 linear, float exposure_scale, ToneMap op) {
  const uint32_t r = srgb8(tone_map_channel(linear.x * exposure_scale, op));
  const uint32_t g = srgb8(tone_map_channel(linear.y * exposure_scale, op));
  const uint32_t b = srgb8(tone_map_channel(linear.z * exposure_scale, op));
  return r | (g << 8) | (b << 16) | (0xffu << 24);
}

}  // namespace tracer
