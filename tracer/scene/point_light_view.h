// Point and spot lights as both backends read them (SceneView::point_lights): delta lights at a
// position, sampled by next-event estimation only (no ray can hit a point). Built from the
// scene's PointLightDesc by make_point_light (scene/point_lights.h).
#pragma once

#include "core/sampling.h"

namespace tracer {

struct PointLight {
  vec3 position;
  // Spot lights: the cosines where the falloff starts (full intensity inside) and where it ends
  // (nothing outside), pbrt-v4's cosFalloffStart and cosFalloffEnd; a point light: -2 and -2.
  float cos_falloff_start;
  vec3 intensity;  // W/sr (radiant intensity) along the axis, linear RGB
  float cos_falloff_end;
  vec3 axis;       // spot lights: unit, the direction the cone points; a point light: unused
  uint32_t light;  // its index in SceneView::lights
};

// pbrt-v4's SmoothStep: 0 at or below a, 1 at or above b, 3t^2 - 2t^3 between.
TRACER_HD TRACER_INLINE float smooth_step(float x, float a, float b) {
  if (a == b) return x < a ? 0.0f : 1.0f;
  const float t = glm::clamp((x - a) / (b - a), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

// The intensity pl sends in unit direction w (away from the light): a point light's in every
// direction, a spot light's scaled by the smooth step between the falloff's cosines
// (pbrt-v4 sec. 12.1.1, SpotLight::I).
TRACER_HD TRACER_INLINE vec3 point_light_intensity(const PointLight& pl, vec3 w) {
  if (pl.cos_falloff_end < -1.0f) return pl.intensity;
  return pl.intensity * smooth_step(glm::dot(w, pl.axis), pl.cos_falloff_end, pl.cos_falloff_start);
}

}  // namespace tracer
