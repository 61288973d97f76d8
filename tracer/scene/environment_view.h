// The lights at infinity as both backends read them: the environment (an image in one of two
// mappings, or a constant colour) with its piecewise-constant sampling distribution, and the
// distant lights (suns). Directions here are world directions, unit length, pointing away from
// the scene (where the light comes from). Built by build_infinite_lights (scene/environment.h).
#pragma once

#include "core/equal_area.h"
#include "core/sampling.h"

namespace tracer {

// InfiniteLights::env.
enum EnvKind : uint32_t { kEnvNone = 0, kEnvConstant = 1, kEnvEquirect = 2, kEnvOctahedral = 3 };

struct DistantLight {
  vec3 dir;             // unit, from the scene towards the light
  float one_minus_cos;  // 1 - cos of the cone's half-angle; 0: a delta light (a direction)
  vec3 radiance;        // inside the cone; a delta light: its irradiance
  uint32_t light;       // its index in SceneView::lights
};

struct InfiniteLights {
  uint32_t env = kEnvNone;
  uint32_t env_light = kInvalid;  // the environment's index in SceneView::lights
  uint32_t width = 0, height = 0;
  // RGBA (A unused) per texel, rows top to bottom, already clamped to >= 0; not scaled.
  const float* texels = nullptr;
  // The sampling distribution over the texel cells (x right, y down): each cell's importance
  // (its mean luminance times its solid angle), the conditional CDF of each row (width + 1
  // entries), the marginal CDF of the rows (height + 1) and the importance's sum. A cell is
  // chosen in proportion to its importance and sampled uniformly in solid angle inside, so the
  // pdf is piecewise constant on the sphere: the cell's mean luminance over the map's integral.
  const float* func = nullptr;
  const float* cond_cdf = nullptr;
  const float* marg_cdf = nullptr;
  float func_sum = 0.0f;
  float strength = 1.0f;       // multiplies the map
  vec3 constant = vec3(0.0f);  // kEnvConstant: the radiance (strength included)
  // The map's frame (y up) to world directions and back: the rotation about +y times the scene's
  // placement of the map (EnvironmentDesc::frame), and its transpose.
  mat3 to_world = mat3(1.0f), to_map = mat3(1.0f);
  uint32_t visible = 1;  // camera rays see the environment (else `background`)
  vec3 background = vec3(0.0f);
  const DistantLight* distant = nullptr;
  uint32_t distant_count = 0;
};

// World direction -> the map's frame (y up), and back.
TRACER_HD TRACER_INLINE vec3 env_world_to_map(const InfiniteLights& e, vec3 w) {
  return e.to_map * w;
}
TRACER_HD TRACER_INLINE vec3 env_map_to_world(const InfiniteLights& e, vec3 m) {
  return e.to_world * m;
}

// The image position [0, 1]^2 (x right, y down) of a direction in the map's frame.
// Equirectangular: longitude u = 1/2 + atan2(z, x) / 2pi (the image's centre column looks along
// +x, a quarter to the right along +z: Blender's layout with its z up turned into our y up),
// latitude v = acos(y) / pi (the top row is straight up). Octahedral (pbrt-v4): the square's
// centre is up (+y), the map's own z axis; its x is our x and its y our -z, as in pbrt-v4 scenes
// whose light transform takes the map's z to their y.
TRACER_HD inline vec2 env_map_uv(uint32_t kind, vec3 m) {
  if (kind == kEnvOctahedral) return equal_area_sphere_to_square(vec3(m.x, -m.z, m.y));
  const float u = 0.5f + glm::atan(m.z, m.x) * (0.5f * kInvPi);
  const float v = glm::acos(glm::clamp(m.y, -1.0f, 1.0f)) * kInvPi;
  return vec2(u, v);
}
TRACER_HD inline vec3 env_map_dir(uint32_t kind, vec2 uv) {
  if (kind == kEnvOctahedral) {
    const vec3 o = equal_area_square_to_sphere(uv);
    return vec3(o.x, o.z, -o.y);
  }
  const float phi = 2.0f * kPi * (uv.x - 0.5f), theta = kPi * uv.y;
  const float s = glm::sin(theta);
  return vec3(s * glm::cos(phi), glm::cos(theta), s * glm::sin(phi));
}
// The solid angle of a texel cell in row `row`: the equal-area map's are all 4 pi / (w h); the
// equirectangular map's are 2 pi / w times the difference of cos(theta) across the row.
TRACER_HD TRACER_INLINE float env_cell_solid_angle(uint32_t kind, uint32_t row, uint32_t w,
                                                   uint32_t h) {
  if (kind == kEnvOctahedral) return 4.0f * kPi / (float(w) * float(h));
  // cos a - cos b = 2 sin((a + b) / 2) sin((b - a) / 2): no cancellation in the polar rows.
  const float mid = kPi * (float(row) + 0.5f) / float(h), half = 0.5f * kPi / float(h);
  return 4.0f * kPi / float(w) * glm::sin(mid) * glm::sin(half);
}

// Texel (x, y), wrapped as the mapping continues across the image's edges: the equirectangular
// map around in x and clamped in y, the octahedral one mirrored (equal_area_wrap).
TRACER_HD TRACER_INLINE vec3 env_texel(const InfiniteLights& e, int x, int y) {
  const int w = int(e.width), h = int(e.height);
  if (e.env == kEnvOctahedral) {
    equal_area_wrap(x, y, w);
  } else {
    x = x % w;
    if (x < 0) x += w;
    y = glm::clamp(y, 0, h - 1);
  }
  const float* t = e.texels + 4 * (size_t(y) * size_t(w) + size_t(x));
  return vec3(t[0], t[1], t[2]);
}

// Bilinear lookup at image position uv (texel centres at half-integers), unscaled.
TRACER_HD inline vec3 env_lookup(const InfiniteLights& e, vec2 uv) {
  const float x = uv.x * float(e.width) - 0.5f, y = uv.y * float(e.height) - 0.5f;
  const float fx = glm::floor(x), fy = glm::floor(y);
  const int x0 = int(fx), y0 = int(fy);
  const float tx = x - fx, ty = y - fy;
  return (1.0f - ty) * ((1.0f - tx) * env_texel(e, x0, y0) + tx * env_texel(e, x0 + 1, y0)) +
         ty * ((1.0f - tx) * env_texel(e, x0, y0 + 1) + tx * env_texel(e, x0 + 1, y0 + 1));
}

// The environment's radiance arriving from world direction d (0 without an environment).
TRACER_HD inline vec3 env_radiance(const InfiniteLights& e, vec3 d) {
  if (e.env == kEnvConstant) return e.constant;
  if (e.env == kEnvNone) return vec3(0.0f);
  const vec3 m = env_world_to_map(e, d);
  return e.strength * env_lookup(e, env_map_uv(e.env, m));
}

// The cell of [0, n) that x in [0, 1] falls into.
TRACER_HD TRACER_INLINE uint32_t env_cell(float x, uint32_t n) {
  return uint32_t(glm::clamp(int(x * float(n)), 0, int(n) - 1));
}

// The solid-angle density with which env_sample picks world direction d.
TRACER_HD inline float env_pdf(const InfiniteLights& e, vec3 d) {
  if (e.env == kEnvConstant) return uniform_sphere_pdf();
  if (e.env == kEnvNone) return 0.0f;
  const vec2 uv = env_map_uv(e.env, env_world_to_map(e, d));
  const uint32_t row = env_cell(uv.y, e.height);
  const float f = e.func[row * e.width + env_cell(uv.x, e.width)];
  const float omega = env_cell_solid_angle(e.env, row, e.width, e.height);
  return f > 0.0f ? f / (e.func_sum * omega) : 0.0f;
}

// The index i in [0, n) with cdf[i] <= u < cdf[i + 1] (cdf has n + 1 entries from 0 to 1; a
// zero-width interval is never returned for u < 1), and u's place inside it in [0, 1).
TRACER_HD inline uint32_t env_find_cdf(const float* cdf, uint32_t n, float u, float* frac) {
  uint32_t lo = 0, hi = n;  // invariant: cdf[lo] <= u < cdf[hi]
  while (hi - lo > 1) {
    const uint32_t mid = (lo + hi) / 2;
    if (cdf[mid] <= u)
      lo = mid;
    else
      hi = mid;
  }
  const float width = cdf[lo + 1] - cdf[lo];
  *frac = width > 0.0f ? glm::clamp((u - cdf[lo]) / width, 0.0f, 0x1.fffffep-1f) : 0.5f;
  return lo;
}

// A world direction from the environment's distribution (pbrt-v4 sec. A.5.6's piecewise-constant
// 2D distribution: a row by the marginal CDF, then a column by that row's conditional CDF), the
// point uniform in solid angle inside the cell (uniform in cos(theta) across an equirectangular
// row, uniform in the square for the equal-area map), its solid-angle pdf in *pdf (0: none).
TRACER_HD inline vec3 env_sample(const InfiniteLights& e, vec2 u, float* pdf) {
  if (e.env == kEnvConstant) {
    *pdf = uniform_sphere_pdf();
    return sample_uniform_sphere(u);
  }
  float fy, fx;
  const uint32_t row = env_find_cdf(e.marg_cdf, e.height, u.y, &fy);
  const uint32_t col = env_find_cdf(e.cond_cdf + size_t(row) * (e.width + 1), e.width, u.x, &fx);
  const float f = e.func[row * e.width + col];
  const float omega = env_cell_solid_angle(e.env, row, e.width, e.height);
  *pdf = f > 0.0f ? f / (e.func_sum * omega) : 0.0f;
  vec3 m;
  if (e.env == kEnvOctahedral) {
    m = env_map_dir(e.env,
                    vec2((float(col) + fx) / float(e.width), (float(row) + fy) / float(e.height)));
  } else {
    const float c0 = glm::cos(kPi * float(row) / float(e.height));
    const float c1 = glm::cos(kPi * float(row + 1) / float(e.height));
    const float cos_t = glm::clamp(c0 + fy * (c1 - c0), -1.0f, 1.0f);
    const float sin_t = safe_sqrt(1.0f - cos_t * cos_t);
    const float phi = 2.0f * kPi * ((float(col) + fx) / float(e.width) - 0.5f);
    m = vec3(sin_t * glm::cos(phi), cos_t, sin_t * glm::sin(phi));
  }
  return env_map_to_world(e, m);
}

// Whether direction d lies in distant light dl's cone: |d - dir|^2 = 2 (1 - cos) compares the
// cosines without the rounding of a dot product near 1 (the sun's cone is 1e-5 wide in cos).
TRACER_HD TRACER_INLINE bool distant_hit(const DistantLight& dl, vec3 d) {
  const vec3 diff = d - dl.dir;
  return glm::dot(diff, diff) <= 2.0f * dl.one_minus_cos;
}
TRACER_HD TRACER_INLINE float distant_cone_pdf(const DistantLight& dl) {
  return 1.0f / (2.0f * kPi * dl.one_minus_cos);
}
// A direction uniform in the light's cone (its pdf distant_cone_pdf), with 1 - cos kept in the
// small numbers instead of cos near 1 (the cone sampling of pbrt-v4 sec. A.5.4, rearranged).
TRACER_HD inline vec3 distant_sample(const DistantLight& dl, vec2 u) {
  const float one_minus_cos_t = u.x * dl.one_minus_cos;
  const float cos_t = 1.0f - one_minus_cos_t;
  const float sin_t = safe_sqrt(one_minus_cos_t * (2.0f - one_minus_cos_t));
  const float phi = 2.0f * kPi * u.y;
  const Frame f = Frame::from_normal(dl.dir);
  return glm::normalize(f.to_world(vec3(sin_t * glm::cos(phi), sin_t * glm::sin(phi), cos_t)));
}

}  // namespace tracer
