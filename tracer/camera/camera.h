// A thin-lens perspective camera (pbrt-v4 sec. 5.2.3): vertical field of view, lens radius and
// focus distance; a lens radius of 0 is a pinhole. Pixel positions are jittered per sample.
#pragma once

#include "core/features.h"
#include "core/ray.h"
#include "core/sampling.h"

namespace tracer {

struct Camera {
  vec3 position = vec3(0.0f);
  float lens_radius = 0.0f;
  vec3 right = vec3(1, 0, 0);
  float focus_distance = 1.0f;
  vec3 up = vec3(0, 1, 0);
  float tan_half_fov = 0.36f;
  vec3 forward = vec3(0, 0, -1);
  float aspect = 1.0f;
  uint32_t width = 1, height = 1;

  TRACER_HD bool has_depth_of_field() const { return lens_radius > 0.0f; }

  // Ray through film position (x + jitter.x, y + jitter.y), y down, with a lens sample.
  template <uint32_t F = kAllFeatures>
  TRACER_HD Ray generate_ray(uint32_t x, uint32_t y, vec2 jitter, vec2 u_lens) const {
    const float sx =
        (fast_div(2.0f * (float(x) + jitter.x), float(width)) - 1.0f) * tan_half_fov * aspect;
    const float sy = (1.0f - fast_div(2.0f * (float(y) + jitter.y), float(height))) * tan_half_fov;
    vec3 d = sx * right + sy * up + forward;  // points at the plane one unit ahead
    Ray r;
    r.o = position;
    r.tmax = kInfinity;
    r.pad = 0.0f;
    if ((F & kFeatureDepthOfField) && lens_radius > 0.0f) {
      const vec2 l = lens_radius * sample_uniform_disk_concentric(u_lens);
      const vec3 focus = position + focus_distance * d;  // on the plane of focus
      r.o = position + l.x * right + l.y * up;
      d = focus - r.o;
    }
    r.d = fast_normalize(d);
    return r;
  }
};

// Builds the camera basis from look-at parameters: right = forward x up, so +x of the world
// appears on the left when looking down +z with +y up (as in the Cornell box data).
inline Camera make_camera(vec3 position, vec3 look_at, vec3 up, float vfov_deg, float lens_radius,
                          float focus_distance, uint32_t width, uint32_t height) {
  Camera c;
  c.position = position;
  c.forward = glm::normalize(look_at - position);
  c.right = glm::normalize(glm::cross(c.forward, up));
  c.up = glm::cross(c.right, c.forward);
  c.tan_half_fov = glm::tan(0.5f * glm::radians(vfov_deg));
  c.lens_radius = lens_radius;
  c.focus_distance = focus_distance > 0.0f ? focus_distance : glm::length(look_at - position);
  c.width = width;
  c.height = height;
  c.aspect = float(width) / float(height);
  return c;
}

}  // namespace tracer
