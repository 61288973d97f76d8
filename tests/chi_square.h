// Chi-square goodness-of-fit tests for samplers, shared by the sampling, BSDF and RNG tests.
// Follows Mitsuba 3's `ChiSquareTest` and pbrt-v4's `chi2` tests: histogram the samples, integrate
// the claimed pdf over every cell, pool cells expecting fewer than 5 samples, and reject when the
// p-value is below a significance level Sidak-corrected for the number of tests in the executable.
// Set TRACER_CHI2_VERBOSE=1 to print every statistic.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <glm/glm.hpp>

#include "core/hd.h"
#include <numeric>
#include <string>
#include <vector>

namespace chi2 {

constexpr double kPi = 3.14159265358979323846;

// Regularised upper incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a), by the series for
// P(a, x) when x < a + 1 and Lentz's continued fraction for Q otherwise (Numerical Recipes, 3rd
// ed., sec. 6.2, gser/gcf). The iteration limits are large because the chi-square tests here have
// thousands of degrees of freedom, and both expansions need O(sqrt(a)) terms near x = a.
inline double gamma_q(double a, double x) {
  if (!(a > 0.0) || !(x >= 0.0)) return std::nan("");
  if (x == 0.0) return 1.0;
  const double log_prefactor = -x + a * std::log(x) - std::lgamma(a);
  constexpr double kEps = 1e-15;
  constexpr int kMaxIter = 1000000;
  if (x < a + 1.0) {
    double ap = a, del = 1.0 / a, sum = del;
    for (int n = 0; n < kMaxIter; ++n) {
      ap += 1.0;
      del *= x / ap;
      sum += del;
      if (std::fabs(del) < std::fabs(sum) * kEps) break;
    }
    return std::max(0.0, 1.0 - sum * std::exp(log_prefactor));
  }
  constexpr double kTiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / kTiny, d = 1.0 / b, h = d;
  for (int i = 1; i < kMaxIter; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::fabs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::fabs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::fabs(del - 1.0) < kEps) break;
  }
  return std::exp(log_prefactor) * h;
}

// P(X >= statistic) for X ~ chi-square with `dof` degrees of freedom.
inline double chi_square_p_value(double statistic, int dof) {
  return gamma_q(0.5 * dof, 0.5 * statistic);
}

// Per-test significance so that `test_count` independent tests together reject a correct sampler
// with probability `significance` (Sidak correction, as Mitsuba does).
inline double sidak_alpha(double significance, int test_count) {
  return 1.0 - std::pow(1.0 - significance, 1.0 / std::max(test_count, 1));
}

struct Result {
  bool passed = false;
  double statistic = 0.0;
  int dof = 0;
  double p_value = 0.0;
  double alpha = 0.0;
  int pooled_cells = 0;
  double pdf_integral = 0.0;  // integral of the pdf over the whole domain (filled by the samplers)
  std::string message;        // why it failed, or a one-line summary
};

// Pearson's chi-square test of observed against expected counts. Cells expecting fewer than
// `min_expected` samples are pooled into one cell (smallest first, as Mitsuba does), and the pool
// keeps absorbing cells until it expects at least `min_expected`. A sample in a cell whose
// expected count is zero fails at once: the sampler produced a direction its pdf says is
// impossible.
inline Result chi_square_test(const std::vector<double>& observed,
                              const std::vector<double>& expected, double significance,
                              int test_count, double min_expected = 5.0) {
  Result r;
  r.alpha = sidak_alpha(significance, test_count);
  std::vector<size_t> order(expected.size());
  std::iota(order.begin(), order.end(), size_t(0));
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return expected[a] < expected[b]; });
  double pooled_obs = 0.0, pooled_exp = 0.0, stat = 0.0;
  int cells = 0;
  for (size_t i : order) {
    const double o = observed[i], e = expected[i];
    if (e <= 0.0) {
      if (o > 0.0) {
        char buf[160];
        std::snprintf(buf, sizeof(buf), "%.0f samples in cell %zu whose expected count is zero", o,
                      i);
        r.message = buf;
        return r;
      }
      continue;
    }
    if (e < min_expected || (pooled_exp > 0.0 && pooled_exp < min_expected)) {
      pooled_obs += o;
      pooled_exp += e;
      ++r.pooled_cells;
    } else {
      stat += (o - e) * (o - e) / e;
      ++cells;
    }
  }
  if (pooled_exp > 0.0) {
    stat += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
    ++cells;
  }
  r.statistic = stat;
  r.dof = cells - 1;
  if (r.dof < 1) {
    r.message = "fewer than two usable cells";
    return r;
  }
  r.p_value = chi_square_p_value(stat, r.dof);
  r.passed = r.p_value >= r.alpha;
  char buf[200];
  std::snprintf(buf, sizeof(buf), "chi2 = %.1f, dof = %d, p = %.3g, alpha = %.3g, pooled %d cells",
                stat, r.dof, r.p_value, r.alpha, r.pooled_cells);
  r.message = buf;
  if (std::getenv("TRACER_CHI2_VERBOSE")) std::printf("  %s\n", buf);  // to see the margins
  return r;
}

// A right-handed orthonormal basis around a unit axis, in double (independent of the tracer's
// Frame so that the harness does not test the code with itself).
struct Basis {
  glm::dvec3 t, b, n;
  explicit Basis(glm::dvec3 axis = glm::dvec3(0, 0, 1)) {
    n = glm::normalize(axis);
    const glm::dvec3 helper = std::fabs(n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    t = glm::normalize(glm::cross(helper, n));
    b = glm::cross(n, t);
  }
  glm::dvec3 to_local(glm::dvec3 v) const {
    return glm::dvec3(glm::dot(v, t), glm::dot(v, b), glm::dot(v, n));
  }
  glm::dvec3 to_world(glm::dvec3 v) const { return v.x * t + v.y * b + v.z * n; }
};

// Cells of equal solid angle: `z_res` rows uniform in the local cos(theta) over [z_lo, 1] times
// `phi_res` columns in phi, about `basis.n`. Directions below z_lo go to one extra cell whose
// expected count is integrated like the others. Setting z_lo to the edge of a narrow support (a
// cone) keeps the resolution where the samples are.
struct SphereBins {
  int z_res = 32;
  int phi_res = 64;
  double z_lo = -1.0;
  Basis basis;
  int integration_res = 8;  // k x k midpoint samples per cell, 8k x 8k where the pdf has an edge
};

namespace detail {
// Integral of f over [x0,x1] x [y0,y1] by the midpoint rule on a k x k grid. A cell where f is
// zero at some points and not at others, among the midpoints and the (k+1) x (k+1) grid corners,
// holds an edge of the support (a straight edge crossing a cell always separates its corners) and
// is redone 8 times finer, so that boundary cells are not biased.
template <class F>
double integrate_cell(const F& f, double x0, double x1, double y0, double y1, int k) {
  bool any_zero = false, any_nonzero = false;
  auto note = [&](double v) { (v > 0.0 ? any_nonzero : any_zero) = true; };
  auto midpoint = [&](int res) {
    double sum = 0.0;
    for (int j = 0; j < res; ++j)
      for (int i = 0; i < res; ++i) {
        const double v = f(x0 + (x1 - x0) * (i + 0.5) / res, y0 + (y1 - y0) * (j + 0.5) / res);
        note(v);
        sum += v;
      }
    return sum * (x1 - x0) * (y1 - y0) / (double(res) * res);
  };
  const double coarse = midpoint(k);
  for (int j = 0; j <= k && !(any_zero && any_nonzero); ++j)
    for (int i = 0; i <= k; ++i) note(f(x0 + (x1 - x0) * i / k, y0 + (y1 - y0) * j / k));
  if (!(any_zero && any_nonzero)) return coarse;
  const double fine = midpoint(8 * k);
  // The support only grazes the cell (a sliver thinner than the fine grid): not provably empty,
  // so it goes to the pooled cell rather than failing a sample found there.
  return fine > 0.0 ? fine : 1e-300;
}
}  // namespace detail

// Draws `n` directions from `sample` (bool(glm::dvec3& w), false for an invalid sample, which is
// dropped as Mitsuba does) and tests them against `pdf` (double(glm::dvec3 w), solid-angle
// density in the same space as the samples).
template <class Sampler, class Pdf>
Result sphere_chi_square(Sampler&& sample, Pdf&& pdf, size_t n, const SphereBins& bins,
                         double significance, int test_count) {
  const int cells = bins.z_res * bins.phi_res;
  std::vector<double> observed(cells + 1, 0.0), expected(cells + 1, 0.0);
  const double dz = (1.0 - bins.z_lo) / bins.z_res, dphi = 2.0 * kPi / bins.phi_res;
  const double z_tol = std::max(1e-6, 1e-4 * dz);  // float rounding at a support edge
  for (size_t s = 0; s < n; ++s) {
    glm::dvec3 w;
    if (!sample(w)) continue;
    const glm::dvec3 l = bins.basis.to_local(glm::normalize(w));
    if (l.z < bins.z_lo - z_tol) {
      observed[cells] += 1.0;
      continue;
    }
    const int zi = std::clamp(int((l.z - bins.z_lo) / dz), 0, bins.z_res - 1);
    double phi = std::atan2(l.y, l.x);
    if (phi < 0.0) phi += 2.0 * kPi;
    const int pi = std::clamp(int(phi / dphi), 0, bins.phi_res - 1);
    observed[zi * bins.phi_res + pi] += 1.0;
  }
  // d(omega) = d(cos theta) d(phi), so the integrand in (z, phi) is the pdf itself.
  auto integrand = [&](double z, double phi) {
    const double st = std::sqrt(std::max(0.0, 1.0 - z * z));
    return pdf(bins.basis.to_world(glm::dvec3(st * std::cos(phi), st * std::sin(phi), z)));
  };
  double total = 0.0;
  for (int zi = 0; zi < bins.z_res; ++zi)
    for (int pi = 0; pi < bins.phi_res; ++pi) {
      const double v =
          detail::integrate_cell(integrand, bins.z_lo + zi * dz, bins.z_lo + (zi + 1) * dz,
                                 pi * dphi, (pi + 1) * dphi, bins.integration_res);
      total += v;
      expected[zi * bins.phi_res + pi] = v * double(n);
    }
  if (bins.z_lo > -1.0) {
    // The region below z_lo, as a 64 x 128 grid of cells.
    double outside = 0.0;
    const double odz = (bins.z_lo + 1.0) / 64, odphi = 2.0 * kPi / 128;
    for (int zi = 0; zi < 64; ++zi)
      for (int pi = 0; pi < 128; ++pi)
        outside += detail::integrate_cell(integrand, -1.0 + zi * odz, -1.0 + (zi + 1) * odz,
                                          pi * odphi, (pi + 1) * odphi, bins.integration_res);
    total += outside;
    expected[cells] = outside * double(n);
  }
  Result r = chi_square_test(observed, expected, significance, test_count);
  r.pdf_integral = total;
  return r;
}

// Cells of a rectangle [x0,x1] x [y0,y1] in a planar domain; a sample outside it is a failure
// (the pdf must vanish outside the rectangle).
struct PlaneBins {
  double x0 = 0.0, x1 = 1.0, y0 = 0.0, y1 = 1.0;
  int nx = 32, ny = 32;
  int integration_res = 8;
};

// Planar version: `sample` is bool(glm::dvec2&), `pdf` is double(glm::dvec2), a density per unit
// area of the plane.
template <class Sampler, class Pdf>
Result plane_chi_square(Sampler&& sample, Pdf&& pdf, size_t n, const PlaneBins& bins,
                        double significance, int test_count) {
  const int cells = bins.nx * bins.ny;
  std::vector<double> observed(cells + 1, 0.0), expected(cells + 1, 0.0);
  const double dx = (bins.x1 - bins.x0) / bins.nx, dy = (bins.y1 - bins.y0) / bins.ny;
  for (size_t s = 0; s < n; ++s) {
    glm::dvec2 p;
    if (!sample(p)) continue;
    if (!(p.x >= bins.x0 && p.x <= bins.x1 && p.y >= bins.y0 && p.y <= bins.y1)) {
      observed[cells] += 1.0;  // expected[cells] stays 0: an immediate failure
      continue;
    }
    const int xi = std::clamp(int((p.x - bins.x0) / dx), 0, bins.nx - 1);
    const int yi = std::clamp(int((p.y - bins.y0) / dy), 0, bins.ny - 1);
    observed[yi * bins.nx + xi] += 1.0;
  }
  auto integrand = [&](double x, double y) { return pdf(glm::dvec2(x, y)); };
  double total = 0.0;
  for (int yi = 0; yi < bins.ny; ++yi)
    for (int xi = 0; xi < bins.nx; ++xi) {
      const double v =
          detail::integrate_cell(integrand, bins.x0 + xi * dx, bins.x0 + (xi + 1) * dx,
                                 bins.y0 + yi * dy, bins.y0 + (yi + 1) * dy, bins.integration_res);
      total += v;
      expected[yi * bins.nx + xi] = v * double(n);
    }
  Result r = chi_square_test(observed, expected, significance, test_count);
  r.pdf_integral = total;
  return r;
}

// Uniform floats in [0, 1) from a 32-bit engine, independent of the tracer's own Pcg32 (and of
// std::generate_canonical<float>, which can round up to 1).
template <class Engine>
float uniform_float(Engine& e) {
  return float(uint32_t(e()) >> 8) * 0x1p-24f;
}

// Uniform numbers in [0, 1) for the tests' samplers, from a seeded std::mt19937.
struct Uniform {
  std::mt19937 engine;
  explicit Uniform(uint32_t seed) : engine(seed) {}
  float f() { return uniform_float(engine); }
  tracer::vec2 f2() {
    const float a = f();
    return tracer::vec2(a, f());
  }
};

// A unit direction in the local frame from its polar angle (degrees) and azimuth (radians).
inline tracer::vec3 direction(float theta_deg, float phi = 0.7f) {
  const double t = theta_deg * 3.14159265358979323846 / 180.0;
  return tracer::vec3(float(std::sin(t) * std::cos(phi)), float(std::sin(t) * std::sin(phi)),
                      float(std::cos(t)));
}

}  // namespace chi2
