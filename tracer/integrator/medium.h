// Homogeneous participating media for subsurface scattering: the random walk of Cycles and Arnold
// inside closed meshes. Free-flight distances are sampled per colour channel with one-sample MIS
// over the channels (the spectral MIS of Wilkie et al. 2014, as in pbrt-v4's volumetric path
// tracer), so chromatic media stay unbiased; directions follow the Henyey-Greenstein phase function.
#pragma once

#include "core/sampling.h"
#include "materials/fresnel.h"
#include "materials/material.h"
#include "materials/subsurface.h"

namespace tracer {

// Walks longer than this stop and are counted (a path that never finds its way out, for example
// in a medium of albedo 1, must not loop forever).
constexpr uint32_t kMaxWalkSteps = 1u << 16;

// Henyey-Greenstein phase function, cos_theta between the incoming propagation direction and the
// outgoing one (g > 0 scatters forward). pbrt-v4 eq. 11.12.
TRACER_HD TRACER_INLINE float hg_phase(float cos_theta, float g) {
  const float denom = 1.0f + g * g - 2.0f * g * cos_theta;
  return (1.0f / (4.0f * kPi)) * (1.0f - g * g) / (denom * safe_sqrt(denom));
}

// A direction about the propagation direction d distributed as hg_phase (inverse CDF; for |g|
// near 0 the isotropic case). The sampling weight phase/pdf is exactly 1.
TRACER_HD TRACER_INLINE vec3 sample_hg(vec3 d, float g, vec2 u) {
  float cos_t;
  if (glm::abs(g) < 1e-3f) {
    cos_t = 1.0f - 2.0f * u.x;
  } else {
    const float s = (1.0f - g * g) / (1.0f - g + 2.0f * g * u.x);
    cos_t = (1.0f + g * g - s * s) / (2.0f * g);
  }
  cos_t = glm::clamp(cos_t, -1.0f, 1.0f);
  const float sin_t = safe_sqrt(1.0f - cos_t * cos_t);
  const float phi = 2.0f * kPi * u.y;
  return Frame::from_normal(d).to_world(
      vec3(sin_t * glm::cos(phi), sin_t * glm::sin(phi), cos_t));
}

// The diffuse exit of a subsurface random walk (the default; kMaterialSmoothExit keeps the smooth
// dielectric boundary): where a walk meets the boundary from inside, the boundary scatters as a
// thin Lambertian sheet (MaterialType::kDiffuseTransmission) that reflects back into the medium
// with albedo F_in, the hemispherical average of the Fresnel reflectance seen from inside
// (fresnel_average_inside), and transmits out with 1 - F_out = ior^2 (1 - F_in) times the
// material's tint, cosine-distributed. These are the smooth boundary's energy fractions for
// diffuse light inside, radiance scaling by ior^2 across the interface included, so a lossless
// medium in a white furnace stays at 1 and an index-matched boundary (ior 1) becomes a plain
// Lambertian exit of weight 1. What changes is the angular distribution of the light that leaves
// (diffuse instead of refracted) and where it leaves from: light sampling now works at the exit
// point, which the smooth boundary's delta lobe never allowed. Entry stays the smooth refraction
// (its specular reflection is the material's gloss). This is the exit model of Cycles' and
// Arnold's random-walk subsurface, whose exits are shaded as a diffuse surface.
TRACER_HD TRACER_INLINE Material subsurface_exit_material(const Material& m) {
  const float f_in = fresnel_average_inside(m.ior, (m.flags & kMaterialSchlickFresnel) != 0);
  Material e;
  e.type = MaterialType::kDiffuseTransmission;
  e.albedo = vec3(f_in);
  e.transmittance = m.albedo * (m.ior * m.ior * (1.0f - f_in));
  e.ior = m.ior;
  e.flags = 0;
  return e;
}

struct MediumEvent {
  bool scattered;  // true: a scattering event at distance t before the boundary
  float t;
  vec3 weight;     // multiplies the path throughput
};

// The probabilities of driving the free-flight distance by each channel: the path throughput.
TRACER_HD TRACER_INLINE vec3 channel_probabilities(vec3 throughput) {
  const float sum = throughput.x + throughput.y + throughput.z;
  return sum > 0.0f ? throughput / sum : vec3(1.0f / 3.0f);
}

// The event "flew past the boundary at t_boundary": transmittance over its probability.
TRACER_HD TRACER_INLINE MediumEvent medium_boundary_event(const Material& m, vec3 throughput,
                                                          float t_boundary) {
  const vec3 tr = glm::exp(-(m.scattering + m.absorption) * t_boundary);
  const float prob = glm::dot(channel_probabilities(throughput), tr);
  MediumEvent ev;
  ev.scattered = false;
  ev.t = t_boundary;
  ev.weight = prob > 0.0f ? tr / prob : vec3(0.0f);
  return ev;
}

// Samples the next event along a segment of length t_boundary inside medium m. The channel that
// drives the distance is chosen in proportion to the path throughput.
TRACER_HD inline MediumEvent sample_medium(const Material& m, vec3 throughput, float t_boundary,
                                           float u_channel, float u_distance) {
  const vec3 sigma_t = m.scattering + m.absorption;
  const vec3 p = channel_probabilities(throughput);
  const int c = u_channel < p.x ? 0 : (u_channel < p.x + p.y ? 1 : 2);
  const float st = sigma_t[c];
  const float t = st > 0.0f ? -glm::log(1.0f - u_distance) / st : kInfinity;
  if (!(t < t_boundary)) return medium_boundary_event(m, throughput, t_boundary);
  const vec3 tr = glm::exp(-sigma_t * t);
  const float pdf = glm::dot(p, sigma_t * tr);  // mixture of the per-channel exponentials
  MediumEvent ev;
  ev.scattered = true;
  ev.t = t;
  ev.weight = pdf > 0.0f ? m.scattering * tr / pdf : vec3(0.0f);
  return ev;
}

}  // namespace tracer
