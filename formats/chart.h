// A PNG chart of error against time (log time axis), the way a user picks a method:
// one curve per series, labelled points, axes with units, a legend.
#pragma once

#include <string>
#include <vector>

namespace ssdo {

struct ChartPoint {
  double x = 0;       // > 0 (log axis), e.g. milliseconds per frame
  double y = 0;       // e.g. MAE
  std::string label;  // printed beside the point (empty = none)
};

// How a series' line is drawn: series of one colour (one method) differ by their line.
enum class ChartLine {
  solid,   // 3 px, filled points
  dashed,  // 3 px, 10 px on and 6 off, filled points
  thin,    // 1 px, hollow points
};

struct ChartSeries {
  std::string name;            // legend entry
  std::vector<ChartPoint> points;
  bool connect = true;         // draw a line through the points in x order
  int colour = -1;             // index into the chart's 8-colour palette; -1: the series' position
  ChartLine line = ChartLine::solid;
};

struct ChartOptions {
  std::string title;
  std::string x_label = "time per frame (ms, log scale)";
  std::string y_label = "mean absolute error";
  int width_px = 1400;   // image size, [400, 8192]
  int height_px = 900;   // [300, 8192]
  // A TrueType font (Debian's fonts-dejavu-core); without one the chart has no text.
  std::string font_path = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
};

// Renders the chart and writes it as PNG (temp file + rename). Empty string on success,
// else the error.
std::string write_chart_png(const std::string& path, const std::vector<ChartSeries>& series,
                            const ChartOptions& options = {});

}  // namespace ssdo
