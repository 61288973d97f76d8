// Named metals: complex indices of refraction eta + i k per RGB channel, reduced from measured
// spectral data, for the conductor's exact Fresnel equations (bsdf.h, kMaterialConductorIor).
#pragma once

#include <string>
#include <vector>

#include "core/hd.h"

namespace tracer {

struct NamedMetal {
  const char* name;
  vec3 eta, k;
};

// Sources: Ag, Al, Au, Cu from pbrt-v4's named spectra "metal-X-eta" / "metal-X-k"
// (src/pbrt/util/spectrum.cpp; Palik, Handbook of Optical Constants of Solids, 1985); Cr, Ni, Ti
// from Johnson & Christy, Phys. Rev. B 9, 5056 (1974), as tabulated by refractiveindex.info (CC0).
// Reduction to RGB (scripts/metal_rgb.py, which prints this table): per channel, the (eta, k)
// whose exact Fresnel reflectance best fits, over 32 angles weighted by the projected solid angle,
// that channel of the linear-sRGB colour of the spectral reflectance (CIE 1931 observer, equal-
// energy white); where that colour is out of gamut (gold's red) it is capped at the spectrum's own
// maximum. Every channel fits its target curve to 0.0005 rms, so F0 here is the spectrum's
// colour at normal incidence (gold: 0.972, 0.789, 0.342).
inline const std::vector<NamedMetal>& named_metals() {
  static const std::vector<NamedMetal> kMetals = {
      {"Ag", vec3(0.1346f, 0.1252f, 0.1519f), vec3(4.4298f, 3.3584f, 2.3938f)},
      {"Al", vec3(1.4812f, 0.9401f, 0.5823f), vec3(7.8517f, 6.6325f, 5.3238f)},
      {"Au", vec3(0.1757f, 0.3985f, 1.5856f), vec3(4.8935f, 2.3672f, 1.7183f)},
      {"Cr", vec3(3.2995f, 3.1177f, 2.2738f), vec3(3.2902f, 3.3343f, 3.1090f)},
      {"Cu", vec3(0.2362f, 0.9496f, 1.2167f), vec3(4.7042f, 2.6290f, 2.3561f)},
      {"Ni", vec3(2.0654f, 1.9061f, 1.7266f), vec3(4.2955f, 3.5827f, 2.8830f)},
      {"Ti", vec3(2.7835f, 2.5130f, 2.2339f), vec3(3.8899f, 3.4074f, 3.0101f)},
  };
  return kMetals;
}

// The metal of that name (case-sensitive, as chemical symbols are), or null.
inline const NamedMetal* find_metal(const std::string& name) {
  for (const NamedMetal& m : named_metals())
    if (name == m.name) return &m;
  return nullptr;
}

inline std::vector<std::string> metal_names() {
  std::vector<std::string> names;
  for (const NamedMetal& m : named_metals()) names.push_back(m.name);
  return names;
}

}  // namespace tracer
