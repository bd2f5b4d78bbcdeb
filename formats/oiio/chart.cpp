#include "formats/chart.h"
#include "formats/oiio/module_api.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

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

}  // namespace

std::string render_chart_png(const std::string& path, const std::vector<ChartSeries>& series,
                             const ChartOptions& o) {
  if (o.width_px < 400 || o.width_px > 8192 || o.height_px < 300 || o.height_px > 8192)
    return path + ": chart size out of range";
  double x_min = std::numeric_limits<double>::infinity(), x_max = 0, y_max = 0;
  for (const ChartSeries& s : series)
    for (const ChartPoint& p : s.points) {
      if (!(p.x > 0) || !std::isfinite(p.x) || !std::isfinite(p.y)) continue;
      x_min = std::min(x_min, p.x);
      x_max = std::max(x_max, p.x);
      y_max = std::max(y_max, p.y);
    }
  if (!(x_max > 0)) return path + ": no point to plot (times must be > 0)";
  const double lx0 = std::floor(std::log10(x_min)), lx1 = std::max(lx0 + 1, std::ceil(std::log10(x_max)));
  const double y_step = nice_step(std::max(y_max, 1e-6), 6);
  const double y_top = std::ceil(std::max(y_max, 1e-6) * 1.08 / y_step) * y_step;

  const int w = o.width_px, h = o.height_px;
  const int left = 110, right = 300, top = 70, bottom = 90;  // margins: axis labels, legend
  const int pw = w - left - right, ph = h - top - bottom;
  auto px = [&](double x) { return left + int(std::lround((std::log10(x) - lx0) / (lx1 - lx0) * pw)); };
  auto py = [&](double y) { return top + ph - int(std::lround(y / y_top * ph)); };

  OIIO::ImageBuf img(OIIO::ImageSpec(w, h, 3, OIIO::TypeDesc::UINT8));
  const float white[3] = {1, 1, 1}, grid[3] = {0.88f, 0.88f, 0.88f}, axis[3] = {0.2f, 0.2f, 0.2f};
  OIIO::ImageBufAlgo::fill(img, white);
  const bool text = std::filesystem::exists(o.font_path);
  auto label = [&](int x, int y, const std::string& s, int size, const float* c,
                   OIIO::ImageBufAlgo::TextAlignX ax = OIIO::ImageBufAlgo::TextAlignX::Left,
                   OIIO::ImageBufAlgo::TextAlignY ay = OIIO::ImageBufAlgo::TextAlignY::Baseline) {
    if (text) OIIO::ImageBufAlgo::render_text(img, x, y, s, size, o.font_path, {c, 3}, ax, ay);
  };

  // Grid and tick labels: decades (and 2x, 5x) on x, nice steps on y.
  for (double d = lx0; d <= lx1 + 1e-9; d += 1) {
    for (double m : {1.0, 2.0, 5.0}) {
      const double x = m * std::pow(10.0, d);
      if (std::log10(x) > lx1 + 1e-9) break;
      OIIO::ImageBufAlgo::render_line(img, px(x), top, px(x), top + ph, {grid, 3});
      label(px(x), top + ph + 24, format_number(x), 16, axis, OIIO::ImageBufAlgo::TextAlignX::Center);
    }
  }
  for (double y = 0; y <= y_top + 1e-12; y += y_step) {
    OIIO::ImageBufAlgo::render_line(img, left, py(y), left + pw, py(y), {grid, 3});
    label(left - 10, py(y), format_number(y), 16, axis, OIIO::ImageBufAlgo::TextAlignX::Right,
          OIIO::ImageBufAlgo::TextAlignY::Center);
  }
  OIIO::ImageBufAlgo::render_box(img, left, top, left + pw, top + ph, {axis, 3});
  label(left + pw / 2, h - 30, o.x_label, 20, axis, OIIO::ImageBufAlgo::TextAlignX::Center);
  label(20, top - 20, o.y_label, 20, axis);
  label(left + pw / 2, 35, o.title, 24, axis, OIIO::ImageBufAlgo::TextAlignX::Center);

  // Series: lines in x order, points as small squares with labels, a legend on the right.
  for (size_t i = 0; i < series.size(); ++i) {
    const float* c = kPalette[i % (sizeof kPalette / sizeof kPalette[0])];
    std::vector<ChartPoint> pts;
    for (const ChartPoint& p : series[i].points)
      if (p.x > 0 && std::isfinite(p.x) && std::isfinite(p.y)) pts.push_back(p);
    std::sort(pts.begin(), pts.end(), [](const ChartPoint& a, const ChartPoint& b) { return a.x < b.x; });
    for (size_t k = 0; series[i].connect && k + 1 < pts.size(); ++k)
      for (int t = -1; t <= 1; ++t)  // 3 px wide
        OIIO::ImageBufAlgo::render_line(img, px(pts[k].x), py(pts[k].y) + t, px(pts[k + 1].x),
                                        py(pts[k + 1].y) + t, {c, 3});
    for (const ChartPoint& p : pts) {
      OIIO::ImageBufAlgo::render_box(img, px(p.x) - 5, py(p.y) - 5, px(p.x) + 5, py(p.y) + 5, {c, 3}, true);
      if (!p.label.empty()) label(px(p.x) + 8, py(p.y) - 8, p.label, 14, axis);
    }
    const int ly = top + 20 + int(i) * 30;
    OIIO::ImageBufAlgo::render_box(img, left + pw + 25, ly - 12, left + pw + 45, ly + 4, {c, 3}, true);
    label(left + pw + 55, ly + 2, series[i].name, 18, axis);
  }

  const std::filesystem::path final_path(path);
  const std::string tmp = (final_path.parent_path() / ("." + final_path.filename().string() + ".tmp.png")).string();
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

}  // namespace ssdo::oiio_module
