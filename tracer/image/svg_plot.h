// A log-log line plot written as SVG (any browser opens it; text stays sharp): the bench's
// error-against-time picture.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace tracer {

struct PlotSeries {
  std::string name;
  std::vector<std::pair<double, double>> points;  // (x, y); non-positive values are skipped
};

struct PlotSpec {
  std::string title, x_label, y_label;
  std::vector<PlotSeries> series;
  std::vector<std::pair<double, std::string>> y_marks;  // labelled horizontal lines
  bool slope_guide = true;                              // a dotted line of slope -1 for comparison
  int width = 960, height = 600;
};

// The axes span whole decades around the data; the legend lists the series in order.
std::string loglog_svg(const PlotSpec& spec);

}  // namespace tracer
