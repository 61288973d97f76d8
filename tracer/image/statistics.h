// The few distribution functions the image comparisons need: Student's t tail probability (from
// the regularised incomplete beta function) and the Sidak correction for many simultaneous tests.
#pragma once

namespace tracer {

// Regularised incomplete beta function I_x(a, b) for a, b > 0 and x in [0, 1].
double incomplete_beta(double a, double b, double x);

// Two-sided tail probability P(|T| >= |t|) of Student's t with `dof` degrees of freedom (any
// real dof > 0; +infinity gives the normal distribution). NaN t gives NaN; infinite t gives 0.
double student_t_two_sided_p(double t, double dof);

// The per-test significance that keeps the probability of at least one false alarm among
// `tests` independent tests at `family` (Sidak 1967): 1 - (1 - family)^(1 / tests).
double sidak_per_test(double family, int tests);

// Welch-Satterthwaite degrees of freedom of a sum of independent variance estimates v_i, each
// with dof_i degrees of freedom: (sum v_i)^2 / sum (v_i^2 / dof_i). Terms with v_i = 0 drop out;
// all zero gives +infinity.
double satterthwaite_dof(const double* variances, const double* dofs, int count);

}  // namespace tracer
