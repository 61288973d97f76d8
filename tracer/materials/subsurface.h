// Subsurface material parameters: the medium's coefficients from the colour an artist picks.
// Loaders fill Material with them; the random walk itself is integrator/medium.h.
#pragma once

#include "core/math.h"

namespace tracer {

// Single-scattering albedo from the multiple-scattering albedo A an artist picks as the surface
// colour: Kulla & Conty, "Revisiting Physically Based Shading at Imageworks" (SIGGRAPH 2017
// course), the fit for a semi-infinite isotropic medium.
TRACER_HD TRACER_INLINE float albedo_from_surface_colour(float A) {
  A = glm::clamp(A, 0.0f, 0.999999f);
  const float s = 4.09712f + 4.20863f * A - safe_sqrt(9.59217f + 41.6808f * A + 17.7126f * A * A);
  return glm::clamp(1.0f - s * s, 0.0f, 1.0f);
}

}  // namespace tracer
