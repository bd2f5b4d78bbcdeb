#include "formats/chart.h"
#include "formats/oiio/module_api.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <optional>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

namespace ssdo::oiio_module {

namespace {

// Colour-blind-safe palette (Okabe and Ito 2008), RGB in [0, 1].
constexpr float kPalette[][3] = {{0.0f, 0.45f, 0.70f}, {0.90f, 0.62f, 0.0f}, {0.0f, 0.62f, 0.45f},
                                 {0.80f, 0.40f, 0.0f},  {0.35f, 0.70f, 0.90f}, {0.80f, 0.60f, 0.70f},
                                 {0.94f, 0.89f, 0.26f}, {0.0f, 0.0f, 0.0f}};

std::string format_number(double v) {
  char buf[32];
  if (v >= 100 || v == std::floor(v)) std::snprintf(buf, sizeof buf, "%.0f", v);
  else if (v >= 1) std::snprintf(buf, sizeof buf, "%.1f", v);
  else std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

// A "nice" step (1, 2 or 5 x 10^k) giving about `ticks` intervals over `span`.
double nice_step(double span, int ticks) {
  const double raw = span / ticks;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (raw <= m * p) return m * p;
  return 10 * p;
}

// The plot area and its axes: log10 decades [lx0, lx1] on x, [0, y_top] on y.
struct PlotArea {
  double lx0 = 0, lx1 = 1, y_step = 1, y_top = 1;
  int left = 0, top = 0, pw = 0, ph = 0;  // pixels: top-left corner, width, height
  int px(double x) const { return left + int(std::lround((std::log10(x) - lx0) / (lx1 - lx0) * pw)); }
  int py(double y) const { return top + ph - int(std::lround(y / y_top * ph)); }
};

bool plottable(const ChartPoint& p) { return p.x > 0 && std::isfinite(p.x) && std::isfinite(p.y); }

// The axes' ranges from the series' points (x > 0, finite); nullopt without any.
std::optional<PlotArea> plot_area(const std::vector<ChartSeries>& series, const ChartOptions& o) {
  double x_min = std::numeric_limits<double>::infinity(), x_max = 0, y_max = 0;
  for (const ChartSeries& s : series)
    for (const ChartPoint& p : s.points) {
      if (!plottable(p)) continue;
      x_min = std::min(x_min, p.x);
      x_max = std::max(x_max, p.x);
      y_max = std::max(y_max, p.y);
    }
  if (!(x_max > 0)) return std::nullopt;
  PlotArea a;
  a.lx0 = std::floor(std::log10(x_min));
  a.lx1 = std::max(a.lx0 + 1, std::ceil(std::log10(x_max)));
  a.y_step = nice_step(std::max(y_max, 1e-6), 6);
  a.y_top = std::ceil(std::max(y_max, 1e-6) * 1.08 / a.y_step) * a.y_step;
  const int right = 360, bottom = 90;  // margins: axis labels, legend
  a.left = 110;
  a.top = 70;
  a.pw = o.width_px - a.left - right;
  a.ph = o.height_px - a.top - bottom;
  return a;
}

const float kWhite[3] = {1, 1, 1}, kGrid[3] = {0.88f, 0.88f, 0.88f}, kAxis[3] = {0.2f, 0.2f, 0.2f};

// The image and its text (none without the font).
struct Canvas {
  OIIO::ImageBuf img;
  std::string font_path;
  bool text = false;
  void label(int x, int y, const std::string& s, int size, const float* c,
             OIIO::ImageBufAlgo::TextAlignX ax = OIIO::ImageBufAlgo::TextAlignX::Left,
             OIIO::ImageBufAlgo::TextAlignY ay = OIIO::ImageBufAlgo::TextAlignY::Baseline) {
    if (text) OIIO::ImageBufAlgo::render_text(img, x, y, s, size, font_path, {c, 3}, ax, ay);
  }
};

// Grid and tick labels (decades, and 2x, 5x, on x; nice steps on y), frame and titles.
void draw_axes(Canvas& canvas, const PlotArea& a, const ChartOptions& o) {
  OIIO::ImageBuf& img = canvas.img;
  for (double d = a.lx0; d <= a.lx1 + 1e-9; d += 1) {
    for (double m : {1.0, 2.0, 5.0}) {
      const double x = m * std::pow(10.0, d);
      if (std::log10(x) > a.lx1 + 1e-9) break;
      OIIO::ImageBufAlgo::render_line(img, a.px(x), a.top, a.px(x), a.top + a.ph, {kGrid, 3});
      canvas.label(a.px(x), a.top + a.ph + 24, format_number(x), 16, kAxis,
                   OIIO::ImageBufAlgo::TextAlignX::Center);
    }
  }
  for (double y = 0; y <= a.y_top + 1e-12; y += a.y_step) {
    OIIO::ImageBufAlgo::render_line(img, a.left, a.py(y), a.left + a.pw, a.py(y), {kGrid, 3});
    canvas.label(a.left - 10, a.py(y), format_number(y), 16, kAxis,
                 OIIO::ImageBufAlgo::TextAlignX::Right, OIIO::ImageBufAlgo::TextAlignY::Center);
  }
  OIIO::ImageBufAlgo::render_box(img, a.left, a.top, a.left + a.pw, a.top + a.ph, {kAxis, 3});
  canvas.label(a.left + a.pw / 2, o.height_px - 30, o.x_label, 20, kAxis,
               OIIO::ImageBufAlgo::TextAlignX::Center);
  canvas.label(20, a.top - 20, o.y_label, 20, kAxis);
  canvas.label(a.left + a.pw / 2, 35, o.title, 24, kAxis, OIIO::ImageBufAlgo::TextAlignX::Center);
}

const float* series_colour(const ChartSeries& s, size_t i) {
  constexpr size_t n = sizeof kPalette / sizeof kPalette[0];
  return kPalette[(s.colour >= 0 ? size_t(s.colour) : i) % n];
}

// A segment in the series' line style: 3 px wide across its main direction (solid,
// dashed: 10 px on, 6 off) or 1 px (thin).
void draw_segment(OIIO::ImageBuf& img, int x0, int y0, int x1, int y1, ChartLine line, const float* c) {
  const bool steep = std::abs(y1 - y0) > std::abs(x1 - x0);
  const int half_width = line == ChartLine::thin ? 0 : 1;
  const double length = std::hypot(double(x1 - x0), double(y1 - y0));
  const double on = line == ChartLine::dashed ? 10 : length, period = line == ChartLine::dashed ? 16 : length + 1;
  for (double s0 = 0; s0 < length; s0 += period) {
    const double s1 = std::min(length, s0 + on);
    const auto at = [&](double s, int a, int b) { return int(std::lround(a + (b - a) * s / length)); };
    const int ax = at(s0, x0, x1), ay = at(s0, y0, y1), bx = at(s1, x0, x1), by = at(s1, y0, y1);
    for (int t = -half_width; t <= half_width; ++t)
      OIIO::ImageBufAlgo::render_line(img, ax + (steep ? t : 0), ay + (steep ? 0 : t), bx + (steep ? t : 0),
                                      by + (steep ? 0 : t), {c, 3});
  }
}

// A point's marker: a 10 px square, hollow for thin lines.
void draw_marker(OIIO::ImageBuf& img, int x, int y, ChartLine line, const float* c) {
  OIIO::ImageBufAlgo::render_box(img, x - 5, y - 5, x + 5, y + 5, {c, 3}, line != ChartLine::thin);
}

// Series `i`: a line in x order, labelled points, a legend entry (a sample of its line).
void draw_series(Canvas& canvas, const PlotArea& a, const ChartSeries& s, size_t i) {
  OIIO::ImageBuf& img = canvas.img;
  const float* c = series_colour(s, i);
  std::vector<ChartPoint> pts;
  for (const ChartPoint& p : s.points)
    if (plottable(p)) pts.push_back(p);
  std::sort(pts.begin(), pts.end(), [](const ChartPoint& p, const ChartPoint& q) { return p.x < q.x; });
  for (size_t k = 0; s.connect && k + 1 < pts.size(); ++k)
    draw_segment(img, a.px(pts[k].x), a.py(pts[k].y), a.px(pts[k + 1].x), a.py(pts[k + 1].y), s.line, c);
  for (const ChartPoint& p : pts) {
    draw_marker(img, a.px(p.x), a.py(p.y), s.line, c);
    // Above the point; below for dashed lines, variants that often lie on their solid series.
    const int label_dy = s.line == ChartLine::dashed ? 20 : -8;
    if (!p.label.empty()) canvas.label(a.px(p.x) + 8, a.py(p.y) + label_dy, p.label, 14, kAxis);
  }
  const int ly = a.top + 20 + int(i) * 30, lx = a.left + a.pw + 20;
  draw_segment(img, lx, ly - 4, lx + 36, ly - 4, s.line, c);
  draw_marker(img, lx + 18, ly - 4, s.line, c);
  canvas.label(lx + 46, ly + 2, s.name, 16, kAxis);
}

// Writes the image as PNG through a temp file renamed into place.
std::string write_png_file(const std::string& path, OIIO::ImageBuf& img) {
  const std::filesystem::path final_path(path);
  std::string tmp_name = final_path.filename().string();
  tmp_name.insert(0, 1, '.');
  tmp_name += ".tmp.png";
  const std::string tmp = (final_path.parent_path() / tmp_name).string();
  if (!img.write(tmp)) {
    std::filesystem::remove(tmp);
    return path + ": cannot write the chart: " + img.geterror();
  }
  std::error_code ec;
  std::filesystem::rename(tmp, final_path, ec);
  if (ec) {
    std::filesystem::remove(tmp);
    return path + ": cannot write the chart: " + ec.message();
  }
  return {};
}

}  // namespace

std::string render_chart_png(const std::string& path, const std::vector<ChartSeries>& series,
                             const ChartOptions& o) {
  if (o.width_px < 400 || o.width_px > 8192 || o.height_px < 300 || o.height_px > 8192)
    return path + ": chart size out of range";
  const std::optional<PlotArea> area = plot_area(series, o);
  if (!area) return path + ": no point to plot (times must be > 0)";
  Canvas canvas{OIIO::ImageBuf(OIIO::ImageSpec(o.width_px, o.height_px, 3, OIIO::TypeDesc::UINT8)),
                o.font_path, std::filesystem::exists(o.font_path)};
  OIIO::ImageBufAlgo::fill(canvas.img, kWhite);
  draw_axes(canvas, *area, o);
  for (size_t i = 0; i < series.size(); ++i) draw_series(canvas, *area, series[i], i);
  return write_png_file(path, canvas.img);
}

}  // namespace ssdo::oiio_module
