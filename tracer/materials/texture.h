// Image textures in device-readable form: every texture's RGBA8 texels live in one flat array,
// described by a TextureDesc each. Lookups map the uv through the texture's affine transform
// (glTF KHR_texture_transform), filter bilinearly and apply the glTF wrap modes; colour textures
// are stored sRGB-encoded and decoded per texel before filtering, as GPU sRGB formats do
// (filtering encoded values would darken edges).
#pragma once

#include "core/hd.h"

namespace tracer {

// glTF sampler wrap modes (KHR spec sec. 5.26), in the order TextureDesc stores them.
enum class TextureWrap : uint32_t { kRepeat = 0, kClampToEdge = 1, kMirroredRepeat = 2 };

enum TextureDescFlags : uint32_t {
  kTextureSrgb = 1u << 4,  // bits 0-1: wrap s, bits 2-3: wrap t
};

struct TextureDesc {
  uint32_t offset;  // first texel in the flat array
  uint32_t width, height;
  uint32_t flags;  // wrap_s | wrap_t << 2 | kTextureSrgb
  // The lookup reads the texture at uv_transform * (uv, 1): a texture use's
  // KHR_texture_transform (one desc per image and transform), the identity otherwise.
  glm::mat3x2 uv_transform = glm::mat3x2(1.0f);
};

// RGBA8 storage (4 bytes a texel, a quarter of linear floats): big textures matter more than the
// cost of decoding sRGB at lookup. 8 bits are what the source PNG/JPEG files hold anyway.
TRACER_HD TRACER_INLINE float srgb_to_linear(float c) {
  // IEC 61966-2-1.
  return c <= 0.04045f ? c * (1.0f / 12.92f) : powf((c + 0.055f) * (1.0f / 1.055f), 2.4f);
}

// Texel index for integer coordinate i (any integer) under a wrap mode.
TRACER_HD TRACER_INLINE int wrap_texel(int i, int n, uint32_t mode) {
  switch (mode) {
    case uint32_t(TextureWrap::kClampToEdge):
      return i < 0 ? 0 : (i >= n ? n - 1 : i);
    case uint32_t(TextureWrap::kMirroredRepeat): {
      int m = i % (2 * n);
      if (m < 0) m += 2 * n;
      return m < n ? m : 2 * n - 1 - m;
    }
    default: {
      int m = i % n;
      return m < 0 ? m + n : m;
    }
  }
}

TRACER_HD TRACER_INLINE vec4 fetch_texel(const uint32_t* texels, const TextureDesc& d, int x,
                                         int y) {
  const uint32_t t = texels[d.offset + uint32_t(y) * d.width + uint32_t(x)];
  vec4 c(float(t & 0xffu), float((t >> 8) & 0xffu), float((t >> 16) & 0xffu), float(t >> 24));
  c *= 1.0f / 255.0f;
  if (d.flags & kTextureSrgb) {
    c.x = srgb_to_linear(c.x);
    c.y = srgb_to_linear(c.y);
    c.z = srgb_to_linear(c.z);
  }
  return c;
}

// Bilinear lookup at the surface's uv, after the texture's uv_transform (glTF convention: (0, 0)
// is the first texel of the first row, the image's top-left corner); texel centres lie at
// (i + 0.5) / width. Returns linear RGBA.
TRACER_HD inline vec4 sample_texture(const TextureDesc* descs, const uint32_t* texels, uint32_t tex,
                                     vec2 uv) {
  const TextureDesc d = descs[tex];
  uv = d.uv_transform * vec3(uv, 1.0f);
  const int w = int(d.width), h = int(d.height);
  // Keep the coordinates in int range; far-away uvs lose precision anyway.
  const float fx = glm::clamp(uv.x, -1e6f, 1e6f) * float(w) - 0.5f;
  const float fy = glm::clamp(uv.y, -1e6f, 1e6f) * float(h) - 0.5f;
  const float x0f = floorf(fx), y0f = floorf(fy);
  const float tx = fx - x0f, ty = fy - y0f;
  const int x0 = int(x0f), y0 = int(y0f);
  const uint32_t ws = d.flags & 3u, wt = (d.flags >> 2) & 3u;
  const int xa = wrap_texel(x0, w, ws), xb = wrap_texel(x0 + 1, w, ws);
  const int ya = wrap_texel(y0, h, wt), yb = wrap_texel(y0 + 1, h, wt);
  const vec4 c00 = fetch_texel(texels, d, xa, ya), c10 = fetch_texel(texels, d, xb, ya);
  const vec4 c01 = fetch_texel(texels, d, xa, yb), c11 = fetch_texel(texels, d, xb, yb);
  return (1.0f - ty) * ((1.0f - tx) * c00 + tx * c10) + ty * ((1.0f - tx) * c01 + tx * c11);
}

}  // namespace tracer
