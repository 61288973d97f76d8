// Per-region means, relMSE and the noise test of compare_regions.
#include "image/region_stats.h"

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "image/convergence.h"
#include "image/statistics.h"

namespace tracer {
namespace {

constexpr double kRelEpsilon = 0.01;  // as in metrics.cpp (pbrt-v4's MRSE)
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool finite3(const float* p) {
  return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
}

// Per region and channel: the sums the statistics are made of.
struct Sums {
  long pixels = 0, nonfinite = 0;
  double t[3] = {0, 0, 0}, r[3] = {0, 0, 0};
  double vt[3] = {0, 0, 0}, vt2[3] = {0, 0, 0};  // test variances and their squares
  double vr[3] = {0, 0, 0}, vr2[3] = {0, 0, 0};  // reference variances and their squares
  double rel = 0;
};

// Variance of a region mean from n per-pixel variances: sum v / n^2, with the degrees of freedom
// of a sum of one-pair estimates (see compare_regions in the header).
void mean_variance(double sum_v, double sum_v2, long n, double* var, double* dof) {
  *var = sum_v / (double(n) * double(n));
  *dof = sum_v2 > 0.0 ? std::min(double(n), 3.0 * sum_v * sum_v / sum_v2)
                      : std::numeric_limits<double>::infinity();
}

nlohmann::json num(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json();
}

}  // namespace

NoisyImage noisy_from_pair(const ImageRGB& a, const ImageRGB& b, const std::string& name_a,
                           const std::string& name_b) {
  require_same_size(b, name_b, a.width, a.height, name_a);
  NoisyImage out;
  out.mean = make_image(a.width, a.height);
  for (size_t i = 0; i < a.pixels.size(); ++i)
    out.mean.pixels[i] = 0.5f * (a.pixels[i] + b.pixels[i]);
  out.variance = variance_from_halves(a, b);
  out.noise = "two renders (" + name_a + ", " + name_b + ")";
  return out;
}

NoisyImage noisy_with_variance(const ImageRGB& mean, const ImageRGB& variance,
                               const std::string& name_mean, const std::string& name_variance) {
  require_same_size(variance, name_variance, mean.width, mean.height, name_mean);
  NoisyImage out;
  out.mean = mean;
  out.variance = variance;
  out.noise = "variance image " + name_variance;
  return out;
}

NoisyImage noisy_without_variance(const ImageRGB& mean) {
  NoisyImage out;
  out.mean = mean;
  return out;
}

RegionComparison compare_regions(const NoisyImage& test, const NoisyImage& ref,
                                 const RegionMap& regions, const PixelMask* mask,
                                 double significance) {
  const int w = test.mean.width, h = test.mean.height;
  require_same_size(ref.mean, "the reference", w, h, "the test image");
  require_same_size(ImageRGB{regions.width, regions.height, {}}, "the region map", w, h,
                    "the test image");
  if (mask)
    require_same_size(ImageRGB{mask->width, mask->height, {}}, "the mask", w, h, "the test image");

  std::vector<Sums> sums(regions.regions.size());
  const size_t n_pixels = size_t(w) * h;
  for (size_t i = 0; i < n_pixels; ++i) {
    const int32_t id = regions.label[i];
    if (id == RegionMap::kNoRegion || (mask && !mask->keep[i])) continue;
    Sums& s = sums[size_t(id)];
    const float* t = &test.mean.pixels[3 * i];
    const float* r = &ref.mean.pixels[3 * i];
    const float* vt = test.has_variance() ? &test.variance.pixels[3 * i] : nullptr;
    const float* vr = ref.has_variance() ? &ref.variance.pixels[3 * i] : nullptr;
    if (!finite3(t) || !finite3(r) || (vt && !finite3(vt)) || (vr && !finite3(vr))) {
      ++s.nonfinite;
      continue;
    }
    ++s.pixels;
    for (int c = 0; c < 3; ++c) {
      s.t[c] += t[c];
      s.r[c] += r[c];
      // A variance image's tiny negatives (lossy EXR compression) count as 0.
      const double vtc = vt ? std::max(0.0f, vt[c]) : 0.0, vrc = vr ? std::max(0.0f, vr[c]) : 0.0;
      s.vt[c] += vtc;
      s.vt2[c] += vtc * vtc;
      s.vr[c] += vrc;
      s.vr2[c] += vrc * vrc;
      const double d = double(t[c]) - r[c], denom = (r[c] + kRelEpsilon) * (r[c] + kRelEpsilon);
      if (denom > 0.0) s.rel += d * d / denom;
    }
  }

  RegionComparison out;
  out.significance = significance;
  out.test_noise = test.has_variance();
  out.ref_noise = ref.has_variance();
  out.test_noise_source = test.noise;
  out.ref_noise_source = ref.noise;
  out.regions.resize(sums.size());
  for (size_t k = 0; k < sums.size(); ++k) {
    const Sums& s = sums[k];
    RegionStats& rs = out.regions[k];
    rs.pixels = s.pixels;
    rs.nonfinite = s.nonfinite;
    out.pixels += s.pixels;
    out.nonfinite += s.nonfinite;
    if (out.test_noise && s.pixels > 0) out.tests += 3;
  }
  out.per_test = sidak_per_test(significance, out.tests);

  for (size_t k = 0; k < sums.size(); ++k) {
    const Sums& s = sums[k];
    RegionStats& rs = out.regions[k];
    const long n = s.pixels;
    rs.relmse = n > 0 ? s.rel / (3.0 * n) : kNaN;
    for (int c = 0; c < 3; ++c) {
      ChannelStats& cs = rs.channel[c];
      if (n == 0) {
        cs = ChannelStats{kNaN, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN, kNaN, false};
        continue;
      }
      cs.mean_test = s.t[c] / n;
      cs.mean_ref = s.r[c] / n;
      cs.ratio = cs.mean_ref != 0.0 ? cs.mean_test / cs.mean_ref : kNaN;
      double var_t = kNaN, dof_t = kNaN, var_r = 0.0;
      double dof_r = std::numeric_limits<double>::infinity();
      if (out.test_noise) mean_variance(s.vt[c], s.vt2[c], n, &var_t, &dof_t);
      if (out.ref_noise) mean_variance(s.vr[c], s.vr2[c], n, &var_r, &dof_r);
      cs.sigma_test = std::sqrt(var_t);
      cs.sigma_ref = std::sqrt(var_r);
      cs.sigma = std::sqrt(var_t + var_r);
      if (!out.test_noise) {
        cs.dof = cs.z = cs.p = kNaN;
        continue;
      }
      const double vars[2] = {var_t, var_r}, dofs[2] = {dof_t, dof_r};
      cs.dof = satterthwaite_dof(vars, dofs, 2);
      const double diff = cs.mean_test - cs.mean_ref;
      // No noise at all (e.g. black in both renders): any difference is beyond it.
      cs.z = cs.sigma > 0.0 ? diff / cs.sigma : (diff == 0.0 ? 0.0 : std::copysign(INFINITY, diff));
      cs.p = cs.sigma > 0.0 ? student_t_two_sided_p(cs.z, cs.dof) : (diff == 0.0 ? 1.0 : 0.0);
      cs.differs = cs.p < out.per_test;
      rs.differs = rs.differs || cs.differs;
    }
    if (rs.differs) ++out.differing;
  }
  return out;
}

std::string region_comparison_to_json(const RegionMap& regions, const RegionComparison& c) {
  using nlohmann::json;
  json list = json::array();
  for (size_t k = 0; k < c.regions.size(); ++k) {
    const RegionMap::Region& reg = regions.regions[k];
    const RegionStats& rs = c.regions[k];
    auto per_channel = [&](double ChannelStats::*field) {
      json a = json::array();
      for (const ChannelStats& cs : rs.channel) a.push_back(num(cs.*field));
      return a;
    };
    json rel = json::array(), differs = json::array();
    for (const ChannelStats& cs : rs.channel) {
      rel.push_back(num(cs.ratio - 1.0));
      differs.push_back(cs.differs);
    }
    json r = {{"name", reg.name},
              {"box", {reg.box.x0, reg.box.y0, reg.box.x1, reg.box.y1}},
              {"pixels", rs.pixels},
              {"nonfinite_pixels", rs.nonfinite},
              {"mean_test", per_channel(&ChannelStats::mean_test)},
              {"mean_ref", per_channel(&ChannelStats::mean_ref)},
              {"ratio", per_channel(&ChannelStats::ratio)},
              {"rel_diff", rel},
              {"relmse", num(rs.relmse)},
              {"sigma_test", per_channel(&ChannelStats::sigma_test)},
              {"sigma_ref", per_channel(&ChannelStats::sigma_ref)},
              {"sigma", per_channel(&ChannelStats::sigma)},
              {"dof", per_channel(&ChannelStats::dof)},
              {"z", per_channel(&ChannelStats::z)},
              {"p", per_channel(&ChannelStats::p)},
              {"differs_channel", differs},
              {"differs", rs.differs}};
    if (reg.column >= 0) {
      r["column"] = reg.column;
      r["row"] = reg.row;
    }
    list.push_back(r);
  }
  json out = {{"source", regions.source},
              {"significance", num(c.significance)},
              {"tests", c.tests},
              {"per_test_significance", c.tests > 0 ? num(c.per_test) : json()},
              {"test_noise", c.test_noise ? json(c.test_noise_source) : json()},
              {"reference_noise", c.ref_noise ? json(c.ref_noise_source) : json("exact")},
              {"pixels", c.pixels},
              {"nonfinite_pixels", c.nonfinite},
              {"differing", c.differing},
              {"regions", list}};
  return out.dump();
}

}  // namespace tracer
