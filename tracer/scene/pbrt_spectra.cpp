// Spectral data of pbrt-v4 scenes reduced to RGB for an RGB renderer.
#include "scene/pbrt_spectra.h"

#include <cmath>

#include "core/math.h"

namespace tracer {

namespace {

struct NamedMetal {
  const char* name;
  vec3 eta, k;
};

// RGB fits of the measured spectra (Tungsten's ComplexIorData, the data pbrt's named spectra
// come from, integrated over the sRGB primaries); CuZn (brass) from Mitsuba's table.
const NamedMetal kMetals[] = {
    {"Ag", vec3(0.155265f, 0.116723f, 0.138381f), vec3(4.828343f, 3.122246f, 2.146950f)},
    {"Al", vec3(1.657460f, 0.880369f, 0.521229f), vec3(9.223869f, 6.269523f, 4.837001f)},
    {"Au", vec3(0.143119f, 0.374957f, 1.442479f), vec3(3.983160f, 2.385721f, 1.603215f)},
    {"Cu", vec3(0.200438f, 0.924033f, 1.102212f), vec3(3.912949f, 2.452848f, 2.142188f)},
    {"CuZn", vec3(0.444f, 0.527f, 1.094f), vec3(3.695f, 2.765f, 1.829f)},
    {"MgO", vec3(2.089589f, 1.650722f, 1.594876f), vec3(0.0f)},
    {"TiO2", vec3(3.456620f, 2.801708f, 2.905149f), vec3(0.000103f, 0.0f, 0.000636f)},
};

struct NamedGlass {
  const char* name;
  float eta;  // n_d (587.6 nm), Schott catalogue
};

const NamedGlass kGlasses[] = {
    {"glass-BK7", 1.5168f},   {"glass-BAF10", 1.6700f}, {"glass-FK51A", 1.4866f},
    {"glass-LASF9", 1.8503f}, {"glass-F5", 1.6727f},    {"glass-F10", 1.7283f},
    {"glass-F11", 1.7847f},
};

// The CIE 1931 colour matching functions as Wyman, Sloan & Shirley's multi-lobe piecewise
// Gaussian fit ("Simple Analytic Approximations to the CIE XYZ Color Matching Functions",
// JCGT 2(2), 2013, eq. 2).
float lobe(float l, float mu, float s1, float s2) {
  const float t = (l - mu) / (l < mu ? s1 : s2);
  return std::exp(-0.5f * t * t);
}

vec3 cie_xyz(float l) {
  const float x = 1.056f * lobe(l, 599.8f, 37.9f, 31.0f) + 0.362f * lobe(l, 442.0f, 16.0f, 26.7f) -
                  0.065f * lobe(l, 501.1f, 20.4f, 26.2f);
  const float y = 0.821f * lobe(l, 568.8f, 46.9f, 40.5f) + 0.286f * lobe(l, 530.9f, 16.3f, 31.1f);
  const float z = 1.217f * lobe(l, 437.0f, 11.8f, 36.0f) + 0.681f * lobe(l, 459.0f, 26.0f, 13.8f);
  return vec3(x, y, z);
}

// CIE XYZ to linear sRGB (D65), IEC 61966-2-1.
vec3 xyz_to_srgb(vec3 c) {
  return vec3(3.2404542f * c.x - 1.5371385f * c.y - 0.4985314f * c.z,
              -0.9692660f * c.x + 1.8760108f * c.y + 0.0415560f * c.z,
              0.0556434f * c.x - 0.2040259f * c.y + 1.0572252f * c.z);
}

// XYZ of a spectrum given as a function of wavelength, 360..830 nm in 1 nm steps.
template <typename Fn>
vec3 integrate_xyz(Fn value) {
  glm::dvec3 sum(0.0);
  for (int l = 360; l <= 830; ++l) sum += glm::dvec3(cie_xyz(float(l))) * double(value(float(l)));
  return vec3(sum);
}

vec3 luminance_one(vec3 xyz) {
  if (!(xyz.y > 0.0f)) return vec3(0.0f);
  return glm::max(xyz_to_srgb(xyz / xyz.y), vec3(0.0f));
}

}  // namespace

bool pbrt_named_metal(const std::string& name, vec3* rgb) {
  for (const NamedMetal& m : kMetals) {
    const std::string base = std::string("metal-") + m.name;
    if (name == base + "-eta") {
      *rgb = m.eta;
      return true;
    }
    if (name == base + "-k") {
      *rgb = m.k;
      return true;
    }
  }
  return false;
}

bool pbrt_named_glass(const std::string& name, float* eta) {
  for (const NamedGlass& g : kGlasses) {
    if (name == g.name) {
      *eta = g.eta;
      return true;
    }
  }
  return false;
}

std::vector<std::string> pbrt_spectrum_names() {
  std::vector<std::string> names;
  for (const NamedMetal& m : kMetals) {
    names.push_back(std::string("metal-") + m.name + "-eta");
    names.push_back(std::string("metal-") + m.name + "-k");
  }
  for (const NamedGlass& g : kGlasses) names.push_back(g.name);
  return names;
}

vec3 conductor_f0(vec3 eta, vec3 k) {
  const vec3 num = (eta - 1.0f) * (eta - 1.0f) + k * k;
  const vec3 den = (eta + 1.0f) * (eta + 1.0f) + k * k;
  return glm::clamp(num / glm::max(den, vec3(1e-6f)), vec3(0.0f), vec3(1.0f));
}

vec3 blackbody_rgb(float kelvin) {
  // Planck's law; the constant factors cancel in the normalisation to luminance 1.
  const double c2 = 1.4387768775e7;  // h c / k_B in nm K
  const double t = std::max(double(kelvin), 1.0);
  return luminance_one(integrate_xyz([&](float l) {
    const double lm = double(l);
    return float(1.0 / (lm * lm * lm * lm * lm * (std::exp(c2 / (lm * t)) - 1.0)) * 1e15);
  }));
}

float spectrum_at(const std::vector<double>& pairs, float lambda) {
  const size_t n = pairs.size() / 2;
  if (n == 0) return 0.0f;
  if (lambda <= pairs[0]) return float(pairs[1]);
  for (size_t i = 1; i < n; ++i) {
    const double l0 = pairs[2 * i - 2], l1 = pairs[2 * i];
    if (lambda <= l1) {
      const double t = l1 > l0 ? (double(lambda) - l0) / (l1 - l0) : 1.0;
      return float(pairs[2 * i - 1] + t * (pairs[2 * i + 1] - pairs[2 * i - 1]));
    }
  }
  return float(pairs[2 * n - 1]);
}

vec3 emission_spectrum_rgb(const std::vector<double>& pairs) {
  return luminance_one(integrate_xyz([&](float l) { return spectrum_at(pairs, l); }));
}

vec3 reflectance_spectrum_rgb(const std::vector<double>& pairs) {
  // Under an equal-energy illuminant, then a von Kries scaling of X and Z to D65's white point
  // (0.9505, 1, 1.0890), so that a constant reflectance of 1 maps to sRGB white.
  const vec3 white = integrate_xyz([](float) { return 1.0f; });
  vec3 xyz = integrate_xyz([&](float l) { return spectrum_at(pairs, l); }) / white.y;
  xyz.x *= 0.9505f * white.y / white.x;
  xyz.z *= 1.0890f * white.y / white.z;
  return glm::max(xyz_to_srgb(xyz), vec3(0.0f));
}

}  // namespace tracer
