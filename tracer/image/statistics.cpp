// Student's t tail from the incomplete beta function (Numerical Recipes 3rd ed., section 6.4,
// continued fraction by the modified Lentz method), the Sidak correction, Welch-Satterthwaite.
#include "image/statistics.h"

#include <cmath>
#include <limits>

namespace tracer {
namespace {

// The continued fraction of I_x(a, b) (NR eq. 6.4.5), converging fast for x < (a + 1) / (a + b +
// 2).
double beta_continued_fraction(double a, double b, double x) {
  constexpr double kTiny = 1e-300, kEps = 1e-15;
  const double qab = a + b, qap = a + 1.0, qam = a - 1.0;
  double c = 1.0, d = 1.0 - qab * x / qap;
  if (std::fabs(d) < kTiny) d = kTiny;
  d = 1.0 / d;
  double h = d;
  for (int m = 1; m <= 10000; ++m) {
    const int m2 = 2 * m;
    double aa = m * (b - m) * x / ((qam + m2) * (a + m2));
    d = 1.0 + aa * d;
    if (std::fabs(d) < kTiny) d = kTiny;
    c = 1.0 + aa / c;
    if (std::fabs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    h *= d * c;
    aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
    d = 1.0 + aa * d;
    if (std::fabs(d) < kTiny) d = kTiny;
    c = 1.0 + aa / c;
    if (std::fabs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::fabs(del - 1.0) < kEps) break;
  }
  return h;
}

}  // namespace

double incomplete_beta(double a, double b, double x) {
  if (!(x > 0.0)) return 0.0;
  if (!(x < 1.0)) return 1.0;
  const double log_front =
      std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) + a * std::log(x) + b * std::log1p(-x);
  const double front = std::exp(log_front);
  // Symmetry I_x(a, b) = 1 - I_{1-x}(b, a) keeps the fraction in its fast-converging range.
  if (x < (a + 1.0) / (a + b + 2.0)) return front * beta_continued_fraction(a, b, x) / a;
  return 1.0 - front * beta_continued_fraction(b, a, 1.0 - x) / b;
}

double student_t_two_sided_p(double t, double dof) {
  if (std::isnan(t) || !(dof > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  if (std::isinf(t)) return 0.0;
  if (std::isinf(dof)) return std::erfc(std::fabs(t) / std::sqrt(2.0));
  // P(|T| >= t) = I_{dof / (dof + t^2)}(dof / 2, 1 / 2) (Abramowitz & Stegun 26.7.1).
  return incomplete_beta(0.5 * dof, 0.5, dof / (dof + t * t));
}

double sidak_per_test(double family, int tests) {
  if (tests <= 1) return family;
  // -expm1(log1p(-a) / k) is 1 - (1 - a)^(1/k) without cancellation for small a.
  return -std::expm1(std::log1p(-family) / tests);
}

double satterthwaite_dof(const double* variances, const double* dofs, int count) {
  double sum = 0.0, denom = 0.0;
  for (int i = 0; i < count; ++i) {
    if (!(variances[i] > 0.0)) continue;
    sum += variances[i];
    if (std::isfinite(dofs[i])) denom += variances[i] * variances[i] / dofs[i];
  }
  if (denom == 0.0) return std::numeric_limits<double>::infinity();
  return sum * sum / denom;
}

}  // namespace tracer
