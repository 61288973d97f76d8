// SVG log-log plot: decade grid, labelled axes, one polyline with markers per series, legend.
#include "image/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace tracer {
namespace {

// Tableau 10, then the same hues dashed for series 11-20.
const char* const kColors[] = {"#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f",
                               "#edc948", "#b07aa1", "#ff9da7", "#9c755f", "#bab0ac"};

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f", v);
  return buf;
}

// "0.01", "1", "100" for decades near 1; "1e-05" style beyond.
std::string decade_label(int k) {
  char buf[32];
  if (k >= -3 && k <= 3)
    std::snprintf(buf, sizeof(buf), "%g", std::pow(10.0, k));
  else
    std::snprintf(buf, sizeof(buf), "1e%d", k);
  return buf;
}

}  // namespace

std::string loglog_svg(const PlotSpec& spec) {
  double x0 = std::numeric_limits<double>::max(), x1 = 0, y0 = x0, y1 = 0;
  for (const PlotSeries& s : spec.series) {
    for (auto [x, y] : s.points) {
      if (!(x > 0) || !(y > 0) || !std::isfinite(x) || !std::isfinite(y)) continue;
      x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
  }
  for (const auto& m : spec.y_marks) {
    if (m.first > 0) y0 = std::min(y0, m.first), y1 = std::max(y1, m.first);
  }
  if (!(x1 > 0)) x0 = 1e-3, x1 = 1;  // no data: an empty frame still opens
  if (!(y1 > 0)) y0 = 1e-4, y1 = 1;
  const int dx0 = int(std::floor(std::log10(x0))),
            dx1 = std::max(dx0 + 1, int(std::ceil(std::log10(x1))));
  const int dy0 = int(std::floor(std::log10(y0))),
            dy1 = std::max(dy0 + 1, int(std::ceil(std::log10(y1))));

  const double W = spec.width, H = spec.height;
  const double left = 80, right = W - 300, top = 50, bottom = H - 60;  // legend right of the axes
  auto px = [&](double x) { return left + (std::log10(x) - dx0) / (dx1 - dx0) * (right - left); };
  auto py = [&](double y) { return bottom - (std::log10(y) - dy0) / (dy1 - dy0) * (bottom - top); };

  std::string s;
  s += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + num(W) + "\" height=\"" + num(H) +
       "\" viewBox=\"0 0 " + num(W) + " " + num(H) +
       "\" font-family=\"sans-serif\" font-size=\"13\">\n";
  s += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  s += "<text x=\"" + num(W / 2) + "\" y=\"28\" text-anchor=\"middle\" font-size=\"16\">" +
       escape(spec.title) + "</text>\n";
  // Grid: decades solid, 2..9 faint.
  for (int k = dx0; k <= dx1; ++k) {
    for (int m = 1; m <= 9 && (m == 1 || k < dx1); ++m) {
      const double x = px(m * std::pow(10.0, k));
      s += "<line x1=\"" + num(x) + "\" y1=\"" + num(top) + "\" x2=\"" + num(x) + "\" y2=\"" +
           num(bottom) + "\" stroke=\"" + (m == 1 ? "#bbb" : "#eee") + "\"/>\n";
    }
    s += "<text x=\"" + num(px(std::pow(10.0, k))) + "\" y=\"" + num(bottom + 18) +
         "\" text-anchor=\"middle\">" + decade_label(k) + "</text>\n";
  }
  for (int k = dy0; k <= dy1; ++k) {
    for (int m = 1; m <= 9 && (m == 1 || k < dy1); ++m) {
      const double y = py(m * std::pow(10.0, k));
      s += "<line x1=\"" + num(left) + "\" y1=\"" + num(y) + "\" x2=\"" + num(right) + "\" y2=\"" +
           num(y) + "\" stroke=\"" + (m == 1 ? "#bbb" : "#eee") + "\"/>\n";
    }
    s += "<text x=\"" + num(left - 8) + "\" y=\"" + num(py(std::pow(10.0, k)) + 4) +
         "\" text-anchor=\"end\">" + decade_label(k) + "</text>\n";
  }
  s += "<rect x=\"" + num(left) + "\" y=\"" + num(top) + "\" width=\"" + num(right - left) +
       "\" height=\"" + num(bottom - top) + "\" fill=\"none\" stroke=\"#333\"/>\n";
  s += "<text x=\"" + num((left + right) / 2) + "\" y=\"" + num(H - 18) +
       "\" text-anchor=\"middle\">" + escape(spec.x_label) + "</text>\n";
  s += "<text transform=\"translate(22," + num((top + bottom) / 2) +
       ") rotate(-90)\" text-anchor=\"middle\">" + escape(spec.y_label) + "</text>\n";
  for (const auto& m : spec.y_marks) {
    if (!(m.first > 0)) continue;
    const double y = py(m.first);
    s += "<line x1=\"" + num(left) + "\" y1=\"" + num(y) + "\" x2=\"" + num(right) + "\" y2=\"" +
         num(y) + "\" stroke=\"#666\" stroke-dasharray=\"6 4\"/>\n";
    s += "<text x=\"" + num(right - 4) + "\" y=\"" + num(y - 4) +
         "\" text-anchor=\"end\" fill=\"#444\">" + escape(m.second) + "</text>\n";
  }
  if (spec.slope_guide) {
    // Slope -1 through the top-left decade corner region: one decade of y per decade of x.
    const double xa = std::pow(10.0, dx0), ya = std::pow(10.0, dy1);
    const double span = std::min(dx1 - dx0, dy1 - dy0);
    const double xb = xa * std::pow(10.0, span), yb = ya / std::pow(10.0, span);
    s += "<line x1=\"" + num(px(xa)) + "\" y1=\"" + num(py(ya)) + "\" x2=\"" + num(px(xb)) +
         "\" y2=\"" + num(py(yb)) + "\" stroke=\"#999\" stroke-dasharray=\"2 4\"/>\n";
  }
  // Series and legend.
  double ly = top + 10;
  for (size_t i = 0; i < spec.series.size(); ++i) {
    const PlotSeries& ser = spec.series[i];
    const std::string color = kColors[i % 10];
    const std::string dash = (i / 10) % 2 ? " stroke-dasharray=\"8 4\"" : "";
    std::string path;
    for (auto [x, y] : ser.points) {
      if (!(x > 0) || !(y > 0) || !std::isfinite(x) || !std::isfinite(y)) continue;
      path += (path.empty() ? "M" : " L") + num(px(x)) + "," + num(py(y));
    }
    if (!path.empty()) {
      s += "<path d=\"" + path + "\" fill=\"none\" stroke=\"" + color + "\" stroke-width=\"2\"" +
           dash + "/>\n";
      for (auto [x, y] : ser.points) {
        if (!(x > 0) || !(y > 0) || !std::isfinite(x) || !std::isfinite(y)) continue;
        s += "<circle cx=\"" + num(px(x)) + "\" cy=\"" + num(py(y)) + "\" r=\"2.5\" fill=\"" +
             color + "\"/>\n";
      }
    }
    s += "<line x1=\"" + num(right + 16) + "\" y1=\"" + num(ly) + "\" x2=\"" + num(right + 40) +
         "\" y2=\"" + num(ly) + "\" stroke=\"" + color + "\" stroke-width=\"2\"" + dash + "/>\n";
    s += "<text x=\"" + num(right + 46) + "\" y=\"" + num(ly + 4) + "\">" + escape(ser.name) +
         "</text>\n";
    ly += 20;
  }
  if (spec.slope_guide) {
    s += "<line x1=\"" + num(right + 16) + "\" y1=\"" + num(ly) + "\" x2=\"" + num(right + 40) +
         "\" y2=\"" + num(ly) + "\" stroke=\"#999\" stroke-dasharray=\"2 4\"/>\n";
    s += "<text x=\"" + num(right + 46) + "\" y=\"" + num(ly + 4) +
         "\">slope -1 (unbiased)</text>\n";
  }
  s += "</svg>\n";
  return s;
}

}  // namespace tracer
