// Spectra of pbrt-v4 scenes as RGB: the named metals' complex indices of refraction, the named
// glasses' indices, blackbody emitters and sampled (wavelength, value) spectra.
#pragma once

#include <string>
#include <vector>

#include "core/hd.h"

namespace tracer {

// eta and k of pbrt's named metal spectra ("metal-Ag-eta" / "metal-Ag-k": Ag, Al, Au, Cu, CuZn,
// MgO, TiO2) as linear sRGB; false for another name.
bool pbrt_named_metal(const std::string& name, vec3* rgb);
// Index of refraction at 587.6 nm (the d line) of pbrt's named glasses ("glass-BK7", ...).
bool pbrt_named_glass(const std::string& name, float* eta);
// Every name the two functions above know, for did-you-mean.
std::vector<std::string> pbrt_spectrum_names();

// Normal-incidence Fresnel reflectance of a conductor, per channel:
// ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2).
vec3 conductor_f0(vec3 eta, vec3 k);

// The linear sRGB colour of a blackbody at `kelvin`, scaled to luminance 1 (pbrt-v4 normalises
// emission spectra to one nit before its "scale").
vec3 blackbody_rgb(float kelvin);
// An emission spectrum of (wavelength nm, value) pairs as linear sRGB of luminance 1.
vec3 emission_spectrum_rgb(const std::vector<double>& pairs);
// A reflectance spectrum as linear sRGB (under an equal-energy illuminant adapted to D65, so a
// constant spectrum of 1 is white).
vec3 reflectance_spectrum_rgb(const std::vector<double>& pairs);
// A sampled spectrum's value at `lambda` (linear between the samples, constant beyond them).
float spectrum_at(const std::vector<double>& pairs, float lambda);

}  // namespace tracer
