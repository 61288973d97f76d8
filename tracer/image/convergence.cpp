// Error terms against a reference with its variance, and the convergence summary of a sweep.
#include "image/convergence.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/diagnostics.h"

namespace tracer {
namespace {

constexpr double kRelEpsilon = 0.01;  // as in metrics.cpp (pbrt-v4's MRSE)

void require_size(const ImageRGB& img, const ImageRGB& ref, const char* what) {
  if (img.width != ref.width || img.height != ref.height ||
      img.pixels.size() != ref.pixels.size()) {
    throw InputError(SourceLoc{"image comparison", 0},
                     std::string("the ") + what + " is " + std::to_string(img.width) + "x" +
                         std::to_string(img.height) + " but the reference is " +
                         std::to_string(ref.width) + "x" + std::to_string(ref.height),
                     "nothing was compared");
  }
}

std::string fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), f, a, b, c);
  return buf;
}

}  // namespace

std::string variance_path_for(const std::string& reference_path) {
  const std::filesystem::path p(reference_path);
  return (p.parent_path() / (p.stem().string() + ".variance.exr")).string();
}

ImageRGB variance_from_halves(const ImageRGB& even, const ImageRGB& odd) {
  require_size(odd, even, "odd half");
  ImageRGB out = make_image(even.width, even.height);
  for (size_t i = 0; i < even.pixels.size(); ++i) {
    const double d = double(even.pixels[i]) - double(odd.pixels[i]);
    out.pixels[i] = static_cast<float>(0.25 * d * d);
  }
  return out;
}

namespace {

// The block bias test of error_terms (see convergence.h) at one block size: per block and
// channel, the squared mean relative error minus the expected noise of that mean. Returns the
// mean over blocks and its standard error; false without a block.
bool block_bias(const ImageRGB& test, const ReferenceImage& ref, const ImageRGB& even,
                const ImageRGB& odd, int kBlock, double* bias2, double* stderr_out) {
  const bool ref_var = !ref.variance.pixels.empty();
  double sum = 0, sum2 = 0;
  long blocks = 0;
  for (int by = 0; by < test.height; by += kBlock) {
    for (int bx = 0; bx < test.width; bx += kBlock) {
      double block_s = 0;  // the block's three channels together
      bool any = false;
      for (int c = 0; c < 3; ++c) {
        double d_sum = 0, noise = 0;
        long m = 0;
        for (int y = by; y < std::min(by + kBlock, test.height); ++y) {
          for (int x = bx; x < std::min(bx + kBlock, test.width); ++x) {
            const size_t i = 3 * (size_t(y) * test.width + x) + c;
            const double t = test.pixels[i], r = ref.mean.pixels[i];
            if (!std::isfinite(t) || !std::isfinite(r)) continue;
            const double inv = 1.0 / (r + kRelEpsilon);
            if (!std::isfinite(inv)) continue;
            const double dh = double(even.pixels[i]) - double(odd.pixels[i]);
            d_sum += (t - r) * inv;
            const double ref_noise = ref_var ? double(ref.variance.pixels[i]) : 0.0;
            noise += (0.25 * dh * dh + ref_noise) * inv * inv;
            ++m;
          }
        }
        if (m == 0) continue;
        const double mean = d_sum / m;
        block_s += mean * mean - noise / (double(m) * m);
        any = true;
      }
      if (!any) continue;
      block_s /= 3.0;
      sum += block_s;
      sum2 += block_s * block_s;
      ++blocks;
    }
  }
  if (blocks == 0) return false;
  *bias2 = sum / blocks;
  const double var_s = std::max(0.0, sum2 / blocks - *bias2 * *bias2);
  *stderr_out = std::sqrt(var_s / blocks);
  return true;
}

// Two block sizes, both lower bounds of the squared bias (Jensen: a block's squared mean bias is
// at most the mean of its pixels' squared biases): 2x2 blocks keep a bias confined to a few
// pixels (a clamped caustic) but average the noise only 4-fold; 8x8 blocks average it 64-fold
// for a bias spread over a region. The larger (in standard errors) is reported.
void block_bias(const ImageRGB& test, const ReferenceImage& ref, const ImageRGB& even,
                const ImageRGB& odd, ErrorTerms& e) {
  bool any = false;
  double best_z = -1e300;
  for (int size : {2, 8}) {
    double b2, se;
    if (!block_bias(test, ref, even, odd, size, &b2, &se)) continue;
    const double z = se > 0 ? b2 / se : (b2 > 0 ? 1e300 : -1e300);
    if (!any || z > best_z) {
      e.bias2 = b2;
      e.bias2_stderr = se;
      best_z = z;
    }
    any = true;
  }
  if (!any) return;
  e.block_test = true;
  e.variance = std::max(0.0, e.relmse - std::max(0.0, e.bias2));
}

}  // namespace

ErrorTerms error_terms(const ImageRGB& test, const ReferenceImage& ref, const ImageRGB* even,
                       const ImageRGB* odd, bool independent_halves) {
  require_size(test, ref.mean, "test image");
  const bool ref_var = !ref.variance.pixels.empty();
  if (ref_var) require_size(ref.variance, ref.mean, "reference's variance image");
  const bool halves = even && odd;
  if (halves) {
    require_size(*even, ref.mean, "even half");
    require_size(*odd, ref.mean, "odd half");
  }
  // Doubles throughout: a 1080p image has 6.2 M values.
  double sum_rel = 0, sum_sq = 0, sum_floor = 0, sum_var = 0, sum_d = 0, sum_d2 = 0;
  long n = 0;
  for (size_t i = 0; i < test.pixels.size(); ++i) {
    const double t = test.pixels[i], r = ref.mean.pixels[i];
    if (!std::isfinite(t) || !std::isfinite(r)) continue;  // counted by the renderer and loader
    const double w = 1.0 / ((r + kRelEpsilon) * (r + kRelEpsilon));
    if (!std::isfinite(w)) continue;
    const double sq = (t - r) * (t - r);
    const double floor = ref_var ? double(ref.variance.pixels[i]) * w : 0.0;
    double var = 0.0;
    if (halves) {
      const double d = double((*even).pixels[i]) - double((*odd).pixels[i]);
      var = 0.25 * d * d * w;
    }
    ++n;
    sum_sq += sq;
    sum_rel += sq * w;
    sum_floor += floor;
    sum_var += var;
    // Per value: error - its expected noise = an unbiased estimate of the squared bias.
    const double bias_i = sq * w - floor - var;
    sum_d += bias_i;
    sum_d2 += bias_i * bias_i;
  }
  ErrorTerms e;
  if (n == 0) return e;
  e.relmse_raw = sum_rel / n;
  e.reference_floor = sum_floor / n;
  e.relmse = e.relmse_raw - e.reference_floor;
  e.rmse = std::sqrt(sum_sq / n);
  if (halves && !independent_halves) {
    block_bias(test, ref, *even, *odd, e);
  } else if (halves) {
    e.variance = sum_var / n;
    e.bias2 = sum_d / n;
    const double mean = sum_d / n;
    const double var_d = std::max(0.0, sum_d2 / n - mean * mean);
    // Three channels of one pixel share the path: count pixels, not values, as independent.
    e.bias2_stderr = std::sqrt(var_d / std::max(1.0, n / 3.0));
  }
  return e;
}

std::string reference_independence_warning(const std::string& reference_path, uint32_t seed,
                                           const std::string& sampler) {
  std::ifstream f(reference_path + ".json");
  if (!f) return "";
  const nlohmann::json j = nlohmann::json::parse(f, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return "";
  auto field = [&](const char* key) -> const nlohmann::json* {
    if (j.contains(key)) return &j[key];
    // The sidecar's "render" section (settings table), or "settings" in older sidecars.
    if (j.contains("render") && j["render"].is_object() && j["render"].contains(key))
      return &j["render"][key];
    if (j.contains("settings") && j["settings"].is_object() && j["settings"].contains(key))
      return &j["settings"][key];
    return nullptr;
  };
  const nlohmann::json* s = field("seed");
  if (!s || !s->is_number_unsigned() || s->get<uint64_t>() != seed) return "";
  const nlohmann::json* smp = field("sampler");
  const std::string ref_sampler = smp && smp->is_string() ? smp->get<std::string>() : "random";
  if (ref_sampler != sampler) return "";
  return reference_path + ": the reference was rendered with the same seed (" +
         std::to_string(seed) + ") and sampler (" + sampler +
         ") as this render, so it contains this render's first samples and the error reads too "
         "low; render the reference with another --seed";
}

TimeToError time_to_error(const std::vector<Checkpoint>& sweep, double target) {
  TimeToError out;
  if (sweep.empty() || !(target > 0)) return out;
  auto err = [](const Checkpoint& c) { return std::max(c.error.relmse, 1e-30); };
  for (size_t i = 0; i < sweep.size(); ++i) {
    if (err(sweep[i]) > target) continue;
    if (i == 0) {  // already below at the first checkpoint: scale back along error ~ 1/time
      out.seconds = sweep[0].seconds * err(sweep[0]) / target;
      out.extrapolated = true;
      return out;
    }
    const Checkpoint &a = sweep[i - 1], &b = sweep[i];
    const double la = std::log(err(a)), lb = std::log(err(b)), lt = std::log(target);
    const double ta = std::log(std::max(a.seconds, 1e-12)),
                 tb = std::log(std::max(b.seconds, 1e-12));
    const double f = la == lb ? 1.0 : (la - lt) / (la - lb);
    out.seconds = std::exp(ta + f * (tb - ta));
    return out;
  }
  const Checkpoint& last = sweep.back();
  if (last.error.significant_bias()) {
    // Only the noise falls with time: variance * t_last / t + bias2 = target.
    if (last.error.bias2 >= target) return out;  // never
    out.seconds = last.seconds * last.error.variance / (target - last.error.bias2);
  } else {
    out.seconds = last.seconds * err(last) / target;
  }
  out.extrapolated = true;
  return out;
}

ConvergenceSummary summarize(const std::vector<Checkpoint>& sweep) {
  ConvergenceSummary s;
  if (sweep.empty()) {
    s.verdict = "no checkpoints";
    return s;
  }
  // Least squares of log relMSE on log spp over the checkpoints with two samples or more (the
  // first sample has no half-buffer variance and sits furthest from the asymptote).
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  std::vector<std::pair<double, double>> pts;
  for (const Checkpoint& c : sweep) {
    if (c.spp < 2 || !(c.error.relmse > 0)) continue;
    pts.push_back({std::log(double(c.spp)), std::log(c.error.relmse)});
  }
  s.slope_points = int(pts.size());
  if (pts.size() >= 2) {
    for (auto [x, y] : pts) {
      sx += x;
      sy += y;
      sxx += x * x;
      sxy += x * y;
    }
    const double m = double(pts.size());
    const double den = m * sxx - sx * sx;
    s.slope = den > 0 ? (m * sxy - sx * sy) / den : 0.0;
    const double icpt = (sy - s.slope * sx) / m;
    if (pts.size() >= 3 && den > 0) {
      double rss = 0;
      for (auto [x, y] : pts) rss += (y - icpt - s.slope * x) * (y - icpt - s.slope * x);
      s.slope_stderr = std::sqrt(rss / (m - 2) * m / den);
    }
  }
  s.to_1e2 = time_to_error(sweep, 1e-2);
  s.to_1e3 = time_to_error(sweep, 1e-3);
  const Checkpoint& last = sweep.back();
  if (last.error.relmse > 0 && last.seconds > 0)
    s.efficiency = 1.0 / (last.error.relmse * last.seconds);

  const bool flat = s.slope_points >= 4 && s.slope > -0.8;
  if (last.error.significant_bias()) {
    s.biased = true;
    s.verdict =
        fmt("biased: the error plateaus near relMSE %.2g (bias is %.0f%% of the error at "
            "the last point)",
            last.error.bias2, 100.0 * last.error.bias2 / last.error.relmse);
    if (s.slope_points >= 2) s.verdict += fmt("; slope %.2f", s.slope);
  } else if (flat && !last.error.has_variance()) {
    // No half buffers to test the bias directly (e.g. the workbench): the slope is the evidence.
    s.biased = true;
    s.verdict =
        fmt("slope %.2f +- %.2f is flatter than -1: bias, or a reference that is not "
            "converged",
            s.slope, s.slope_stderr);
  } else if (flat) {
    // The half-buffer test found no bias: randomised QMC can converge slower than 1/N for a while
    // after a fast start, and heavy-tailed noise flattens a short sweep.
    s.verdict =
        std::string(last.error.block_test ? "no significant bias (block test); "
                                          : "no significant bias (half-buffer test); ") +
        fmt("slope %.2f +- %.2f is flatter than "
            "-1: pre-asymptotic or heavy-tailed noise",
            s.slope, s.slope_stderr);
  } else if (s.slope_points >= 2) {
    const double tolerance = std::max(0.1, 2.0 * s.slope_stderr);
    const bool near = std::abs(s.slope + 1.0) <= tolerance;
    // Stratified (quasi-Monte Carlo) samples converge faster than 1/N wherever the integrand is
    // smooth enough in their first dimensions: a steeper slope is their signature, not a fault.
    if (near)
      s.verdict = fmt("unbiased (slope %.2f +- %.2f)", s.slope, s.slope_stderr);
    else if (s.slope < -1.0)
      s.verdict = fmt("unbiased (slope %.2f +- %.2f, steeper than -1: stratified samples)", s.slope,
                      s.slope_stderr);
    else
      s.verdict =
          fmt("no significant bias; slope %.2f +- %.2f is off -1 (outliers or "
              "too few samples)",
              s.slope, s.slope_stderr);
  } else {
    s.verdict = "too few checkpoints for a slope";
  }
  return s;
}

}  // namespace tracer
