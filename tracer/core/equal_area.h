// The equal-area octahedral map between the unit square and the unit sphere (Clarberg 2008, "Fast
// Equal-Area Mapping of the (Hemi)Sphere using SIMD"; the layout pbrt-v4 stores environment maps
// in): the square's centre is +z, its corners -z, and every region of the square covers a solid
// angle of 4 pi times its area, so a uniform point of the square is a uniform direction.
#pragma once

#include "core/math.h"

namespace tracer {

// |a| with the sign of b (b = -0 counts as negative, as the map's folds need).
TRACER_HD TRACER_INLINE float copy_sign(float a, float b) {
  return int_as_float((float_as_int(a) & 0x7fffffff) | (float_as_int(b) & int32_t(0x80000000)));
}

// p in [0, 1]^2 to a unit direction. The square, moved to [-1, 1]^2, is folded into its first
// quadrant; there r = 1 - |1 - |u| - |v|| is the distance from the fold's diagonal (the square's
// centre at r = 0 for the upper hemisphere, the corners at r = 0 for the lower), z = +-(1 - r^2)
// keeps area (dz = 2 r dr), and phi runs linearly along the diamond of radius r.
TRACER_HD inline vec3 equal_area_square_to_sphere(vec2 p) {
  const float u = 2.0f * p.x - 1.0f, v = 2.0f * p.y - 1.0f;
  const float au = glm::abs(u), av = glm::abs(v);
  const float signed_distance = 1.0f - (au + av);
  const float r = 1.0f - glm::abs(signed_distance);
  const float phi = (r == 0.0f ? 1.0f : (av - au) / r + 1.0f) * (0.25f * kPi);  // [0, pi/2]
  const float z = copy_sign(1.0f - r * r, signed_distance);
  const float sin_theta = r * safe_sqrt(2.0f - r * r);
  return vec3(copy_sign(glm::cos(phi) * sin_theta, u), copy_sign(glm::sin(phi) * sin_theta, v), z);
}

// The inverse: a unit direction to [0, 1]^2 (exact atan where Clarberg uses a polynomial).
TRACER_HD inline vec2 equal_area_sphere_to_square(vec3 d) {
  const float x = glm::abs(d.x), y = glm::abs(d.y), z = glm::abs(d.z);
  const float r = safe_sqrt(1.0f - z);
  const float a = glm::max(x, y), b = glm::min(x, y);
  // phi / (pi/2) in the first octant, measured from the larger of x and y.
  float phi = a == 0.0f ? 0.0f : glm::atan(b / a) * (2.0f / kPi);
  if (x < y) phi = 1.0f - phi;
  float v = phi * r, u = r - v;
  if (d.z < 0.0f) {  // the lower hemisphere: unfold across the diagonal
    const float t = u;
    u = 1.0f - v;
    v = 1.0f - t;
  }
  u = copy_sign(u, d.x);
  v = copy_sign(v, d.y);
  return vec2(0.5f * (u + 1.0f), 0.5f * (v + 1.0f));
}

// Texel (x, y) of a square map of n x n texels, moved back inside when a bilinear footprint
// steps over an edge: across an edge the map continues mirrored (pbrt-v4's OctahedralSphere
// wrap), since the sphere's neighbours of an edge texel lie on the same edge's other half.
TRACER_HD TRACER_INLINE void equal_area_wrap(int& x, int& y, int n) {
  if (x < 0) {
    x = -x - 1;
    y = n - 1 - y;
  } else if (x >= n) {
    x = 2 * n - 1 - x;
    y = n - 1 - y;
  }
  if (y < 0) {
    x = n - 1 - x;
    y = -y - 1;
  } else if (y >= n) {
    x = n - 1 - x;
    y = 2 * n - 1 - y;
  }
}

}  // namespace tracer
