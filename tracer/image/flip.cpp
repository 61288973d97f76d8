// LDR-FLIP (Andersson, Nilsson, Akenine-Möller, Oskarsson, Åström, Fairchild, HPG 2020) on the
// CPU: a colour pipeline (CSF filtering in YCxCz, Hunt-adjusted L*a*b*, HyAB, remap to [0, 1])
// and a feature pipeline (edges and points on the achromatic channel), combined per pixel as
// ΔE = ΔEc^(1 - ΔEf). Constants and filter construction follow the paper and NVlabs/flip's FLIP.h.
#include "image/flip.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/diagnostics.h"

namespace tracer {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The paper's constants: colour exponent q_c, remap knee p_c and its target p_t (colour
// pipeline), edge-detector peak-to-trough width w in degrees and feature exponent q_f (feature
// pipeline).
constexpr float kQc = 0.7f, kPc = 0.4f, kPt = 0.95f;
constexpr double kFeatureWidth = 0.082;
constexpr float kQf = 0.5f;

// The contrast sensitivity functions as sums of two Gaussians in the spatial domain:
// S(x) = a1 sqrt(pi / b1) exp(-pi^2 x^2 / b1) + a2 sqrt(pi / b2) exp(-pi^2 x^2 / b2), x in degrees.
// The achromatic and red-green channels use one Gaussian (a2 = 0).
struct Csf {
  double a1, b1, a2, b2;
};
constexpr Csf kCsfY{1.0, 0.0047, 0.0, 1e-5};
constexpr Csf kCsfCx{1.0, 0.0053, 0.0, 1e-5};
constexpr Csf kCsfCz{34.1, 0.04, 13.5, 0.025};
// The widest Gaussian of the three sets the radius of all three filters.
constexpr double kCsfMaxB = 0.04;

// D65 reference white in XYZ (Y = 1), and the sRGB primaries' matrices for that white.
constexpr float kWhite[3] = {0.950428545f, 1.0f, 1.088900371f};
constexpr float kRgbToXyz[3][3] = {
    {10135552.0f / 24577794.0f, 8788810.0f / 24577794.0f, 4435075.0f / 24577794.0f},
    {2613072.0f / 12288897.0f, 8788810.0f / 12288897.0f, 887015.0f / 12288897.0f},
    {1425312.0f / 73733382.0f, 8788810.0f / 73733382.0f, 70074185.0f / 73733382.0f}};
constexpr float kXyzToRgb[3][3] = {{3.241003275f, -1.537398934f, -0.498615861f},
                                   {-0.969224334f, 1.875930071f, 0.041554224f},
                                   {0.055639423f, -0.204011202f, 1.057148933f}};

struct Color {
  float v[3];
};

Color mul(const float m[3][3], Color c) {
  Color out;
  for (int i = 0; i < 3; ++i) out.v[i] = m[i][0] * c.v[0] + m[i][1] * c.v[1] + m[i][2] * c.v[2];
  return out;
}

// YCxCz (Johnson & Fairchild): CIELAB without the cube root, so that it is linear in XYZ and
// linear filtering in it is meaningful.
Color xyz_to_ycxcz(Color xyz) {
  const float x = xyz.v[0] / kWhite[0], y = xyz.v[1] / kWhite[1], z = xyz.v[2] / kWhite[2];
  return {{116.0f * y - 16.0f, 500.0f * (x - y), 200.0f * (y - z)}};
}

Color ycxcz_to_xyz(Color c) {
  const float y = (c.v[0] + 16.0f) / 116.0f;
  return {{(y + c.v[1] / 500.0f) * kWhite[0], y * kWhite[1], (y - c.v[2] / 200.0f) * kWhite[2]}};
}

// CIE 1976 L*a*b* with the linear segment below (6/29)^3.
Color xyz_to_lab(Color xyz) {
  constexpr float kDelta = 6.0f / 29.0f;
  float f[3];
  for (int i = 0; i < 3; ++i) {
    const float t = xyz.v[i] / kWhite[i];
    f[i] =
        t > kDelta * kDelta * kDelta ? std::cbrt(t) : t / (3.0f * kDelta * kDelta) + 4.0f / 29.0f;
  }
  return {{116.0f * f[1] - 16.0f, 500.0f * (f[0] - f[1]), 200.0f * (f[1] - f[2])}};
}

// Linear RGB in [0, 1] to Hunt-adjusted L*a*b*: chroma scaled by 0.01 L*, so that dark
// colours differ less in chroma, as the Hunt effect has it.
Color rgb_to_hunt_lab(Color rgb) {
  Color lab = xyz_to_lab(mul(kRgbToXyz, rgb));
  const float s = 0.01f * lab.v[0];
  lab.v[1] *= s;
  lab.v[2] *= s;
  return lab;
}

// HyAB (Abasi et al. 2020): city-block distance in L, Euclidean in (a, b).
float hyab(Color a, Color b) {
  const float da = a.v[1] - b.v[1], db = a.v[2] - b.v[2];
  return std::fabs(a.v[0] - b.v[0]) + std::sqrt(da * da + db * db);
}

// c_max: the largest colour distance, that between Hunt-adjusted green and blue, to the power q_c.
float max_color_distance() {
  const Color green = rgb_to_hunt_lab({{0.0f, 1.0f, 0.0f}});
  const Color blue = rgb_to_hunt_lab({{0.0f, 0.0f, 1.0f}});
  return std::pow(hyab(green, blue), kQc);
}

// One channel per vector, row-major.
using Plane = std::vector<float>;

// How a filter's taps sum: to 1 (blurs), or to 0 (derivatives). A zero-sum filter is applied to
// the differences from the centre pixel, which is the same in exact arithmetic but gives exactly 0
// on flat regions: otherwise float rounding in the tap sum leaves ~1e-8 there, which the square
// root of q_f = 0.5 lifts to a ~1e-4 feature difference between two flat colours.
enum class TapSum { kOne, kZero };

// out[x] = sum_k taps[k] * in[clamp(x + k - r)] along each row (a correlation, with edge pixels
// repeated, as the reference implementation pads).
void filter_rows(const Plane& in, int w, int h, const std::vector<float>& taps, TapSum sum,
                 Plane* out) {
  const int r = static_cast<int>(taps.size()) / 2;
  std::vector<float> pad(static_cast<size_t>(w) + 2 * r);
  out->assign(in.size(), 0.0f);
  for (int y = 0; y < h; ++y) {
    const float* src = in.data() + static_cast<size_t>(y) * w;
    for (int i = 0; i < w + 2 * r; ++i) pad[i] = src[std::clamp(i - r, 0, w - 1)];
    float* dst = out->data() + static_cast<size_t>(y) * w;
    for (size_t k = 0; k < taps.size(); ++k) {
      const float t = taps[k];
      const float* p = pad.data() + k;
      if (sum == TapSum::kOne) {
        for (int x = 0; x < w; ++x) dst[x] += t * p[x];
      } else {
        for (int x = 0; x < w; ++x) dst[x] += t * (p[x] - src[x]);
      }
    }
  }
}

// The same down the columns, for one output row y only.
void filter_column_row(const Plane& in, int w, int h, int y, const std::vector<float>& taps,
                       TapSum sum, float* dst) {
  const int r = static_cast<int>(taps.size()) / 2;
  const float* centre = in.data() + static_cast<size_t>(y) * w;
  std::fill(dst, dst + w, 0.0f);
  for (size_t k = 0; k < taps.size(); ++k) {
    const int yy = std::clamp(y + static_cast<int>(k) - r, 0, h - 1);
    const float t = taps[k];
    const float* src = in.data() + static_cast<size_t>(yy) * w;
    if (sum == TapSum::kOne) {
      for (int x = 0; x < w; ++x) dst[x] += t * src[x];
    } else {
      for (int x = 0; x < w; ++x) dst[x] += t * (src[x] - centre[x]);
    }
  }
}

// The 1D factors of the CSF filters. A 2D Gaussian is the product of two 1D ones; the sum of two
// (blue-yellow) is the sum of two such products, each factor sqrt(a sqrt(pi / b)) exp(-pi^2 x^2 /
// b), normalised so that the 2D filter sums to 1 (as the reference's separatedConvolutions.pdf
// does).
struct CsfTaps {
  std::vector<float> y, cx, cz1, cz2;
};

CsfTaps make_csf_taps(double ppd) {
  const int r = static_cast<int>(std::ceil(3.0 * std::sqrt(kCsfMaxB / (2.0 * kPi * kPi)) * ppd));
  CsfTaps t;
  double sum_y = 0, sum_cx = 0, sum_cz1 = 0, sum_cz2 = 0;
  std::vector<double> y, cx, cz1, cz2;
  auto gauss = [](double x2, double a, double b) {
    return a * std::sqrt(kPi / b) * std::exp(-kPi * kPi * x2 / b);
  };
  auto gauss_sqrt = [](double x2, double a, double b) {
    return std::sqrt(a * std::sqrt(kPi / b)) * std::exp(-kPi * kPi * x2 / b);
  };
  for (int i = -r; i <= r; ++i) {
    const double x = i / ppd, x2 = x * x;  // degrees
    y.push_back(gauss(x2, kCsfY.a1, kCsfY.b1));
    cx.push_back(gauss(x2, kCsfCx.a1, kCsfCx.b1));
    cz1.push_back(gauss_sqrt(x2, kCsfCz.a1, kCsfCz.b1));
    cz2.push_back(gauss_sqrt(x2, kCsfCz.a2, kCsfCz.b2));
    sum_y += y.back();
    sum_cx += cx.back();
    sum_cz1 += cz1.back();
    sum_cz2 += cz2.back();
  }
  // The 2D blue-yellow filter sums to sum_cz1^2 + sum_cz2^2; each 1D factor takes its square root.
  const double norm_cz = 1.0 / std::sqrt(sum_cz1 * sum_cz1 + sum_cz2 * sum_cz2);
  for (size_t i = 0; i < y.size(); ++i) {
    t.y.push_back(static_cast<float>(y[i] / sum_y));
    t.cx.push_back(static_cast<float>(cx[i] / sum_cx));
    t.cz1.push_back(static_cast<float>(cz1[i] * norm_cz));
    t.cz2.push_back(static_cast<float>(cz2[i] * norm_cz));
  }
  return t;
}

// The edge and point detectors: the first and second derivatives of a Gaussian
// with standard deviation w/2 degrees, applied separably with the Gaussian itself across. The
// Gaussian sums to 1; the positive and negative lobes of each derivative to +1 and -1.
struct FeatureTaps {
  std::vector<float> g, dg, ddg;
};

FeatureTaps make_feature_taps(double ppd) {
  const double sd = 0.5 * kFeatureWidth * ppd;  // pixels
  const int r = static_cast<int>(std::ceil(3.0 * sd));
  std::vector<double> g, dg, ddg;
  double g_sum = 0, dg_pos = 0, dg_neg = 0, ddg_pos = 0, ddg_neg = 0;
  for (int i = -r; i <= r; ++i) {
    const double x = i;
    const double gi = std::exp(-x * x / (2.0 * sd * sd));
    g.push_back(gi);
    dg.push_back(-x * gi);
    ddg.push_back((x * x / (sd * sd) - 1.0) * gi);
    g_sum += gi;
    (dg.back() > 0 ? dg_pos : dg_neg) += std::fabs(dg.back());
    (ddg.back() > 0 ? ddg_pos : ddg_neg) += std::fabs(ddg.back());
  }
  // Below ~2 pixels per degree the Gaussian underflows to one tap and the derivatives vanish;
  // the detectors then see nothing rather than dividing by 0.
  auto lobe = [](double v, double pos, double neg) {
    const double s = v > 0 ? pos : neg;
    return s > 0 ? static_cast<float>(v / s) : 0.0f;
  };
  FeatureTaps t;
  for (size_t i = 0; i < g.size(); ++i) {
    t.g.push_back(static_cast<float>(g[i] / g_sum));
    t.dg.push_back(lobe(dg[i], dg_pos, dg_neg));
    t.ddg.push_back(lobe(ddg[i], ddg_pos, ddg_neg));
  }
  return t;
}

// An image as shown on an LDR display (scaled, clamped to [0, 1]) in YCxCz, one plane each.
struct Opponent {
  Plane y, cx, cz;
};

Opponent to_opponent(const ImageRGB& img, float scale) {
  const size_t n = static_cast<size_t>(img.width) * img.height;
  Opponent o;
  o.y.resize(n);
  o.cx.resize(n);
  o.cz.resize(n);
  for (size_t i = 0; i < n; ++i) {
    Color rgb;
    for (int c = 0; c < 3; ++c) {
      const float v = img.pixels[3 * i + c] * scale;
      rgb.v[c] = v > 0.0f ? std::min(v, 1.0f) : 0.0f;  // NaN and negatives give 0, +Inf 1
    }
    const Color ycxcz = xyz_to_ycxcz(mul(kRgbToXyz, rgb));
    o.y[i] = ycxcz.v[0];
    o.cx[i] = ycxcz.v[1];
    o.cz[i] = ycxcz.v[2];
  }
  return o;
}

// Colour pipeline: CSF-filtered YCxCz, clamped to the RGB cube, Hunt-adjusted
// L*a*b*, HyAB^q_c remapped so that p_c c_max lands on p_t. Writes ΔEc per pixel.
void color_difference(const Opponent& a, const Opponent& b, int w, int h, const CsfTaps& taps,
                      float* out) {
  const float cmax = max_color_distance();
  const float pccmax = kPc * cmax;
  // Horizontal passes, then vertical ones a row at a time.
  Plane h_img[2][4];
  for (int i = 0; i < 2; ++i) {
    const Opponent& o = i == 0 ? a : b;
    filter_rows(o.y, w, h, taps.y, TapSum::kOne, &h_img[i][0]);
    filter_rows(o.cx, w, h, taps.cx, TapSum::kOne, &h_img[i][1]);
    filter_rows(o.cz, w, h, taps.cz1, TapSum::kOne, &h_img[i][2]);
    filter_rows(o.cz, w, h, taps.cz2, TapSum::kOne, &h_img[i][3]);
  }
  std::vector<float> rows[2][4];
  for (auto& per_image : rows)
    for (auto& row : per_image) row.resize(w);
  for (int y = 0; y < h; ++y) {
    for (int i = 0; i < 2; ++i) {
      filter_column_row(h_img[i][0], w, h, y, taps.y, TapSum::kOne, rows[i][0].data());
      filter_column_row(h_img[i][1], w, h, y, taps.cx, TapSum::kOne, rows[i][1].data());
      filter_column_row(h_img[i][2], w, h, y, taps.cz1, TapSum::kOne, rows[i][2].data());
      filter_column_row(h_img[i][3], w, h, y, taps.cz2, TapSum::kOne, rows[i][3].data());
    }
    for (int x = 0; x < w; ++x) {
      Color lab[2];
      for (int i = 0; i < 2; ++i) {
        const Color ycxcz = {{rows[i][0][x], rows[i][1][x], rows[i][2][x] + rows[i][3][x]}};
        Color rgb = mul(kXyzToRgb, ycxcz_to_xyz(ycxcz));
        for (float& c : rgb.v) c = std::clamp(c, 0.0f, 1.0f);
        lab[i] = rgb_to_hunt_lab(rgb);
      }
      const float d = std::pow(hyab(lab[0], lab[1]), kQc);
      out[static_cast<size_t>(y) * w + x] =
          d < pccmax ? d * (kPt / pccmax) : kPt + (d - pccmax) / (cmax - pccmax) * (1.0f - kPt);
    }
  }
}

// Feature pipeline and the combination: ΔEf = (max(|Δedge|, |Δpoint|) /
// sqrt 2)^q_f on the achromatic channel normalised to [0, 1]; then ΔE = ΔEc^(1 - ΔEf) in place.
void combine_with_features(const Opponent& a, const Opponent& b, int w, int h,
                           const FeatureTaps& taps, float* inout) {
  Plane h_img[2][3];  // per image: x-derivative, second x-derivative, Gaussian
  for (int i = 0; i < 2; ++i) {
    Plane grey = (i == 0 ? a : b).y;
    for (float& v : grey) v = (v + 16.0f) / 116.0f;
    filter_rows(grey, w, h, taps.dg, TapSum::kZero, &h_img[i][0]);
    filter_rows(grey, w, h, taps.ddg, TapSum::kZero, &h_img[i][1]);
    filter_rows(grey, w, h, taps.g, TapSum::kOne, &h_img[i][2]);
  }
  std::vector<float> rows[2][4];  // dx, ddx, dy, ddy
  for (auto& per_image : rows)
    for (auto& row : per_image) row.resize(w);
  const float inv_sqrt2 = static_cast<float>(1.0 / std::sqrt(2.0));
  for (int y = 0; y < h; ++y) {
    for (int i = 0; i < 2; ++i) {
      filter_column_row(h_img[i][0], w, h, y, taps.g, TapSum::kOne, rows[i][0].data());
      filter_column_row(h_img[i][1], w, h, y, taps.g, TapSum::kOne, rows[i][1].data());
      filter_column_row(h_img[i][2], w, h, y, taps.dg, TapSum::kZero, rows[i][2].data());
      filter_column_row(h_img[i][2], w, h, y, taps.ddg, TapSum::kZero, rows[i][3].data());
    }
    for (int x = 0; x < w; ++x) {
      float edge[2], point[2];
      for (int i = 0; i < 2; ++i) {
        edge[i] = std::sqrt(rows[i][0][x] * rows[i][0][x] + rows[i][2][x] * rows[i][2][x]);
        point[i] = std::sqrt(rows[i][1][x] * rows[i][1][x] + rows[i][3][x] * rows[i][3][x]);
      }
      const float diff = std::max(std::fabs(edge[0] - edge[1]), std::fabs(point[0] - point[1]));
      const float ef = std::pow(inv_sqrt2 * diff, kQf);
      float& e = inout[static_cast<size_t>(y) * w + x];
      e = std::pow(e, 1.0f - ef);
    }
  }
}

void check_same_size(const ImageRGB& test, const ImageRGB& ref) {
  auto size = [](const ImageRGB& img) {
    return std::to_string(img.width) + "x" + std::to_string(img.height);
  };
  if (test.width != ref.width || test.height != ref.height) {
    throw InputError(SourceLoc{"FLIP comparison", 0},
                     "the test image is " + size(test) + " but the reference is " + size(ref),
                     "nothing was compared");
  }
  for (const ImageRGB* img : {&test, &ref}) {
    if (img->width < 0 || img->height < 0 ||
        img->pixels.size() != 3 * static_cast<size_t>(img->width) * img->height) {
      throw std::invalid_argument("ldr_flip: pixel buffer does not match " + size(*img));
    }
  }
}

}  // namespace

FlipResult ldr_flip(const ImageRGB& test, const ImageRGB& reference, double pixels_per_degree,
                    float exposure_stops) {
  check_same_size(test, reference);
  if (!(pixels_per_degree > 0.0) || !std::isfinite(pixels_per_degree)) {
    throw std::invalid_argument("ldr_flip: pixels_per_degree must be positive and finite");
  }
  FlipResult out;
  out.width = test.width;
  out.height = test.height;
  const int w = test.width, h = test.height;
  const size_t n = static_cast<size_t>(w) * h;
  if (n == 0) {
    out.mean = std::numeric_limits<double>::quiet_NaN();
    return out;
  }
  const float scale = std::exp2(exposure_stops);
  const Opponent t = to_opponent(test, scale);
  const Opponent r = to_opponent(reference, scale);
  out.per_pixel.resize(n);
  color_difference(r, t, w, h, make_csf_taps(pixels_per_degree), out.per_pixel.data());
  combine_with_features(r, t, w, h, make_feature_taps(pixels_per_degree), out.per_pixel.data());
  double sum = 0.0;
  for (float v : out.per_pixel) sum += v;
  out.mean = sum / static_cast<double>(n);
  return out;
}

vec3 magma(float t) {
  // matplotlib's magma sampled at 9 even steps (the values R's magma(9) prints), sRGB-encoded;
  // interpolated in the encoded values, as viridis() in metrics.cpp is.
  static const unsigned kStops[] = {0x000004, 0x1D1147, 0x51127C, 0x822681, 0xB63679,
                                    0xE65164, 0xFB8861, 0xFEC287, 0xFCFDBF};
  return color_ramp(kStops, 9, t);
}

ImageRGB flip_error_map(const FlipResult& flip) {
  ImageRGB out = make_image(flip.width, flip.height);
  for (size_t i = 0; i < flip.per_pixel.size(); ++i) {
    const vec3 c = magma(flip.per_pixel[i]);
    for (int k = 0; k < 3; ++k) out.pixels[3 * i + k] = c[k];
  }
  return out;
}

}  // namespace tracer
