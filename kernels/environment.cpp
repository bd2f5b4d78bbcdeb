#include "kernels/environment.h"

#include "kernels/environment_irradiance.h"

#include "core/parallel.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace ssdo {

namespace {

// Rows of the grid the analytic kinds are tabulated on for their SH projection: the
// midpoint rule on 256 rows integrates the piecewise-linear sky to ~1e-5.
constexpr int kAnalyticGridHeightPx = 256;
// Rows of the source the cone filter averages: 64 rows = 2.8 deg per texel, fine against
// cones of ~10-30 deg, and keeps the one-off filtering cost small.
constexpr int kFilterSourceHeightPx = 64;

// Solid angle of a pixel of row j in an equirect of size W x H (exact: the band between
// two elevations has area 2 pi (sin theta_top - sin theta_bottom)).
double equirect_pixel_solid_angle(int j, cv::Size size) {
  const double theta_top = std::numbers::pi * (0.5 - double(j) / size.height);
  const double theta_bottom = std::numbers::pi * (0.5 - double(j + 1) / size.height);
  return (2.0 * std::numbers::pi / size.width) * (std::sin(theta_top) - std::sin(theta_bottom));
}

// Bilinear lookup of an equirect image at continuous pixel coordinates p_px (pixel centres
// at + 0.5), wrapping in azimuth and clamping in elevation.
glm::vec3 bilinear_at(const cv::Mat& image, const glm::vec2& p_px) {
  const cv::Size size = image.size();
  const glm::vec2 p = p_px - glm::vec2(0.5f);
  const float x0f = std::floor(p.x), y0f = std::floor(p.y);
  const float fx = p.x - x0f, fy = p.y - y0f;
  const int x0 = int(x0f), y0 = int(y0f);
  // A unit direction gives p.x in [-0.5, W - 0.5], so x0 and x0 + 1 are at most one period
  // out: one add or subtract wraps them (the remainder, two integer divisions, only for
  // anything else).
  auto wrap_x = [&](int x) {
    if (x >= -size.width && x < 2 * size.width) return x < 0 ? x + size.width : x >= size.width ? x - size.width : x;
    return ((x % size.width) + size.width) % size.width;
  };
  auto clamp_y = [&](int y) { return std::clamp(y, 0, size.height - 1); };
  const int xa = wrap_x(x0), xb = wrap_x(x0 + 1), ya = clamp_y(y0), yb = clamp_y(y0 + 1);
  const cv::Vec3f* ra = image.ptr<cv::Vec3f>(ya);
  const cv::Vec3f* rb = image.ptr<cv::Vec3f>(yb);
  const cv::Vec3f v = (ra[xa] * (1.0f - fx) + ra[xb] * fx) * (1.0f - fy) +
                      (rb[xa] * (1.0f - fx) + rb[xb] * fx) * fy;
  return {v[0], v[1], v[2]};
}

glm::vec3 bilinear_equirect(const cv::Mat& image, const glm::vec3& d_env) {
  return bilinear_at(image, Environment::equirect_from_direction(d_env, image.size()));
}

// atan2(y, x) within 4e-6 rad (measured over 10^7 random points): the arctangent of the
// smaller over the larger magnitude by an odd polynomial (the Cg reference atan2's
// coefficients), then reflected into the quadrant. 0 at the origin.
inline float fast_atan2(float y, float x) {
  const float ax = std::abs(x), ay = std::abs(y);
  const float hi = std::max(ax, ay), lo = std::min(ax, ay);
  const float t = hi > 0.0f ? lo / hi : 0.0f;
  const float t2 = t * t;
  const float* c = Environment::kAtanPolynomial;
  float poly = c[0];
  for (int i = 1; i < 6; ++i) poly = poly * t2 + c[i];
  float a = poly * t;
  a = ay > ax ? float(0.5 * std::numbers::pi) - a : a;
  a = x < 0.0f ? std::numbers::pi_v<float> - a : a;
  return y < 0.0f ? -a : a;
}

// equirect_from_direction with fast_atan2 for both angles (theta = atan2(z, |(x, y)|)):
// off by < 1e-4 of a texel of the filtered map, whose values vary over the filter cone
// (many texels), where asin and atan2 from the library took most of a lookup.
glm::vec2 equirect_from_direction_fast(const glm::vec3& d, cv::Size size) {
  const float theta = fast_atan2(d.z, std::sqrt(d.x * d.x + d.y * d.y));
  const float phi = fast_atan2(-d.x, d.y);
  constexpr float pi = std::numbers::pi_v<float>;
  return {0.5f * float(size.width) * (1.0f - phi / pi), float(size.height) * (0.5f - theta / pi)};
}

}  // namespace

float filter_cone_half_angle_for_samples(int samples) {
  // Cone solid angle 2 pi (1 - cos a) = 2 pi / N  ->  cos a = 1 - 1 / N.
  if (samples < 1) return 90.0f;
  return float(std::acos(std::clamp(1.0 - 1.0 / samples, 0.0, 1.0)) * 180.0 / std::numbers::pi);
}

std::string validate(const EnvironmentSettings& s) {
  if (!(s.filter_cone_half_angle_deg >= 0.0f && s.filter_cone_half_angle_deg <= 90.0f))
    return "filter_cone_half_angle_deg = " + std::to_string(s.filter_cone_half_angle_deg) +
           " is out of range [0, 90]";
  if (s.filtered_height_px < 8 || s.filtered_height_px > 512)
    return "filtered_height_px = " + std::to_string(s.filtered_height_px) + " is out of range [8, 512]";
  return {};
}

Environment::Environment() { build(); }

Environment::Environment(EnvironmentKind kind, const EnvironmentSettings& s) : kind_(kind), settings_(s) {
  CV_Assert(validate(s).empty());
}

Environment Environment::constant(const glm::vec3& radiance_rgb, const EnvironmentSettings& s) {
  Environment e(EnvironmentKind::constant, s);
  e.constant_ = radiance_rgb;
  e.build();
  return e;
}

glm::vec3 Environment::mean_radiance() const {
  // integral of L Y_00 over the sphere = L_00, Y_00 = 1 / (2 sqrt(pi)) and 4 pi Y_00^2 = 1:
  // the mean 1 / (4 pi) integral of L = Y_00 L_00.
  return kind_ == EnvironmentKind::constant ? constant_ : sh_[0] * float(0.28209479177387814);
}

Environment Environment::sky(const SkyGradient& sky, const EnvironmentSettings& s) {
  Environment e(EnvironmentKind::sky, s);
  CV_Assert(sky.up_begin < sky.up_end);
  e.sky_ = sky;
  e.build();
  return e;
}

Environment Environment::equirect(const cv::Mat& radiance_rgb, const EnvironmentSettings& s) {
  Environment e(EnvironmentKind::equirect, s);
  CV_Assert(radiance_rgb.type() == CV_32FC3 && radiance_rgb.rows >= 1 && radiance_rgb.cols >= 1);
  e.image_ = radiance_rgb;
  e.build();
  return e;
}

glm::vec3 Environment::env_from_world(const glm::vec3& d) const {
  if (settings_.up == UpAxis::z) return d;
  return {d.x, -d.z, d.y};
}

glm::mat3 Environment::env_from_world_matrix() const {
  if (settings_.up == UpAxis::z) return glm::mat3(1.0f);
  // Columns are the images of the world axes: x -> x, y -> +z, z -> -y.
  return glm::mat3(glm::vec3(1, 0, 0), glm::vec3(0, 0, 1), glm::vec3(0, -1, 0));
}

glm::vec3 Environment::direction_from_equirect(glm::vec2 pixel, cv::Size size) {
  const double theta = std::numbers::pi * (0.5 - double(pixel.y) / size.height);
  const double phi = std::numbers::pi * (1.0 - 2.0 * double(pixel.x) / size.width);
  const double c = std::cos(theta);
  return glm::vec3(float(-c * std::sin(phi)), float(c * std::cos(phi)), float(std::sin(theta)));
}

glm::vec2 Environment::equirect_from_direction(const glm::vec3& d, cv::Size size) {
  // Inverse of direction_from_equirect: theta = asin(z), phi = atan2(-x, y).
  const float theta = std::asin(std::clamp(d.z, -1.0f, 1.0f));
  const float phi = std::atan2(-d.x, d.y);
  constexpr float pi = std::numbers::pi_v<float>;
  return {0.5f * float(size.width) * (1.0f - phi / pi), float(size.height) * (0.5f - theta / pi)};
}

std::array<float, 9> Environment::sh_basis(const glm::vec3& d) {
  // Real SH, Ramamoorthi and Hanrahan 2001, eq. 3 (constants are the normalisations).
  const float x = d.x, y = d.y, z = d.z;
  return {0.282095f,
          0.488603f * y, 0.488603f * z, 0.488603f * x,
          1.092548f * x * y, 1.092548f * y * z, 0.315392f * (3.0f * z * z - 1.0f),
          1.092548f * x * z, 0.546274f * (x * x - y * y)};
}

glm::vec3 Environment::radiance_env(const glm::vec3& d) const {
  switch (kind_) {
    case EnvironmentKind::constant: return constant_;
    case EnvironmentKind::sky: {
      const float t = std::clamp((d.z - sky_.up_begin) / (sky_.up_end - sky_.up_begin), 0.0f, 1.0f);
      return (1.0f - t) * sky_.bottom + t * sky_.top;
    }
    case EnvironmentKind::equirect: return bilinear_equirect(image_, d);
  }
  return constant_;
}

glm::vec3 Environment::radiance_filtered_env(const glm::vec3& d) const {
  if (kind_ == EnvironmentKind::constant) return constant_;
  return bilinear_at(filtered_, equirect_from_direction_fast(d, filtered_.size()));
}

glm::vec3 Environment::irradiance_over_pi_env(const glm::vec3& n) const {
  if (kind_ == EnvironmentKind::constant) return constant_irradiance_over_pi_;
  return bilinear_at(irradiance_, equirect_from_direction_fast(n, irradiance_.size()));
}

glm::vec3 Environment::sh_irradiance_over_pi(const glm::vec3& n) const {
  // E(n) / pi = sum_lm (A_l / pi) L_lm Y_lm(n), A_l / pi = 1, 2/3, 1/4 (R&H 2001, eq. 8).
  const std::array<float, 9> y = sh_basis(n);
  constexpr float kBand[9] = {1.0f, 2.0f / 3.0f, 2.0f / 3.0f, 2.0f / 3.0f,
                              0.25f, 0.25f, 0.25f, 0.25f, 0.25f};
  glm::vec3 e(0.0f);
  for (int k = 0; k < 9; ++k) e += (kBand[k] * y[k]) * sh_[k];
  return e;
}

namespace {

// The analytic sky on an equirect grid of kAnalyticGridHeightPx rows, at texel centres.
// The sky depends on the up-component only, sin(theta), the same at every texel centre of
// a row: one evaluation per row.
cv::Mat tabulated_sky(const Environment& e) {
  const cv::Size size(2 * kAnalyticGridHeightPx, kAnalyticGridHeightPx);
  cv::Mat grid(size, CV_32FC3);
  for (int j = 0; j < size.height; ++j) {
    const glm::vec3 l = e.radiance_env(Environment::direction_from_equirect({0.5f, j + 0.5f}, size));
    grid.row(j).setTo(cv::Scalar(l.x, l.y, l.z));
  }
  return grid;
}

// Moments of z = sin(elevation) over a row's band [z_bottom, z_top] (dw = dz dphi): of 1, z,
// z^2, sqrt(1 - z^2) and z sqrt(1 - z^2).
struct RowMoments {
  double m0, mz, mzz, mc, mzc;
};

std::vector<RowMoments> row_moments(cv::Size size) {
  auto z_antiderivatives = [](double z, double out[5]) {
    const double c2 = std::max(0.0, 1.0 - z * z), c = std::sqrt(c2);
    out[0] = z;                              // 1
    out[1] = 0.5 * z * z;                    // z
    out[2] = z * z * z / 3.0;                // z^2
    out[3] = 0.5 * (z * c + std::asin(std::clamp(z, -1.0, 1.0)));  // sqrt(1 - z^2)
    out[4] = -c2 * c / 3.0;                  // z sqrt(1 - z^2)
  };
  std::vector<RowMoments> rows(size_t(size.height));
  for (int j = 0; j < size.height; ++j) {
    double top[5], bottom[5];
    z_antiderivatives(std::sin(std::numbers::pi * (0.5 - double(j) / size.height)), top);
    z_antiderivatives(std::sin(std::numbers::pi * (0.5 - double(j + 1) / size.height)), bottom);
    rows[j] = {top[0] - bottom[0], top[1] - bottom[1], top[2] - bottom[2], top[3] - bottom[3],
               top[4] - bottom[4]};
  }
  return rows;
}

// Moments of the azimuth over a column's [phi(i + 1), phi(i)]: of 1, sin, cos, sin cos and
// cos 2 phi.
struct ColumnMoments {
  double p0, ps, pc, psc, pcos2;
};

std::vector<ColumnMoments> column_moments(cv::Size size) {
  std::vector<ColumnMoments> cols(size_t(size.width));
  for (int i = 0; i < size.width; ++i) {
    const double hi = std::numbers::pi * (1.0 - 2.0 * double(i) / size.width);
    const double lo = std::numbers::pi * (1.0 - 2.0 * double(i + 1) / size.width);
    cols[i] = {hi - lo,
               -(std::cos(hi) - std::cos(lo)),                                  // sin
               std::sin(hi) - std::sin(lo),                                     // cos
               0.5 * (std::sin(hi) * std::sin(hi) - std::sin(lo) * std::sin(lo)),  // sin cos
               0.5 * (std::sin(2.0 * hi) - std::sin(2.0 * lo))};                // cos 2phi
  }
  return cols;
}

// SH projection: L_lm = sum over pixels of L_pixel x (integral of Y_lm over the pixel).
// The integrals are exact (each Y_lm is a polynomial in z = sin(elevation), sqrt(1 - z^2)
// and sin/cos of the azimuth, integrated in closed form over the pixel's band and
// column), so a piecewise-constant image is projected without quadrature error: a
// constant image gives L_00 to float precision and every other coefficient 0.
std::array<glm::vec3, 9> sh_projection(const cv::Mat& grid) {
  const cv::Size size = grid.size();
  const std::vector<RowMoments> rows = row_moments(size);
  const std::vector<ColumnMoments> cols = column_moments(size);
  // d = (-c sin(phi), c cos(phi), z), c = sqrt(1 - z^2); basis constants as sh_basis().
  std::array<double, 27> acc{};
  for (int j = 0; j < size.height; ++j) {
    const RowMoments& m = rows[j];
    const cv::Vec3f* row = grid.ptr<cv::Vec3f>(j);
    for (int i = 0; i < size.width; ++i) {
      const ColumnMoments& p = cols[i];
      const double y[9] = {
          0.28209479177387814 * m.m0 * p.p0,
          0.4886025119029199 * m.mc * p.pc,                   // y
          0.4886025119029199 * m.mz * p.p0,                   // z
          -0.4886025119029199 * m.mc * p.ps,                  // x
          -1.0925484305920792 * (m.m0 - m.mzz) * p.psc,        // x y
          1.0925484305920792 * m.mzc * p.pc,                  // y z
          0.31539156525252005 * (3.0 * m.mzz - m.m0) * p.p0,  // 3 z^2 - 1
          -1.0925484305920792 * m.mzc * p.ps,                 // x z
          -0.5462742152960396 * (m.m0 - m.mzz) * p.pcos2,     // x^2 - y^2 = -c^2 cos 2phi
      };
      for (int k = 0; k < 9; ++k)
        for (int c = 0; c < 3; ++c) acc[3 * k + c] += double(row[i][c]) * y[k];
    }
  }
  std::array<glm::vec3, 9> sh;
  for (int k = 0; k < 9; ++k) sh[k] = glm::vec3(float(acc[3 * k]), float(acc[3 * k + 1]), float(acc[3 * k + 2]));
  return sh;
}

// The cone filter's source: the grid box-averaged (solid-angle weighted) down to at most
// kFilterSourceHeightPx rows.
cv::Mat filter_source(const cv::Mat& grid) {
  if (grid.rows <= kFilterSourceHeightPx) return grid;
  const cv::Size ssize(2 * kFilterSourceHeightPx, kFilterSourceHeightPx);
  std::vector<double> sum(size_t(ssize.area()) * 3, 0.0), weight(size_t(ssize.area()), 0.0);
  // Target column of each grid column: non-decreasing, so a row is a sequence of runs of
  // columns that fall in the same target texel, each summed in column order.
  std::vector<int> target_column(size_t(grid.cols) + 1);
  for (int i = 0; i < grid.cols; ++i) target_column[i] = int(int64_t(i) * ssize.width / grid.cols);
  target_column[grid.cols] = ssize.width;  // sentinel: ends the last run
  for (int j = 0; j < grid.rows; ++j) {
    const double d_omega = equirect_pixel_solid_angle(j, grid.size());
    const int tj = int(int64_t(j) * ssize.height / grid.rows);
    const cv::Vec3f* row = grid.ptr<cv::Vec3f>(j);
    for (int i = 0; i < grid.cols;) {
      const int ti = target_column[i];
      const size_t t = size_t(tj) * ssize.width + ti;
      double r = sum[3 * t], g = sum[3 * t + 1], b = sum[3 * t + 2], w = weight[t];
      for (; target_column[i] == ti; ++i) {
        r += row[i][0] * d_omega, g += row[i][1] * d_omega, b += row[i][2] * d_omega;
        w += d_omega;
      }
      sum[3 * t] = r, sum[3 * t + 1] = g, sum[3 * t + 2] = b, weight[t] = w;
    }
  }
  cv::Mat source(ssize, CV_32FC3);
  for (int tj = 0; tj < ssize.height; ++tj)
    for (int ti = 0; ti < ssize.width; ++ti) {
      const size_t t = size_t(tj) * ssize.width + ti;
      cv::Vec3f& v = source.at<cv::Vec3f>(tj, ti);
      if (weight[t] > 0.0) {
        for (int c = 0; c < 3; ++c) v[c] = float(sum[3 * t + c] / weight[t]);
      } else {  // a source narrower than the target leaves gaps: sample at the centre
        const glm::vec3 d = Environment::direction_from_equirect({ti + 0.5f, tj + 0.5f}, ssize);
        const glm::vec3 l = bilinear_equirect(grid, d);
        v = cv::Vec3f(l.x, l.y, l.z);
      }
    }
  return source;
}

// The columns of source row `row` that can hold a texel centre inside the cone around a
// target texel (see row_intervals).
struct RowInterval {
  int row;              // source row j
  bool whole_row;       // the interval covers every column
  double half_columns;  // else: columns within this distance of the target's column
};

// The cone filter of a source onto a target lat-long: each target texel is the
// solid-angle weighted mean of the source texels whose centre lies within the cone around
// the target's centre direction.
struct ConeFilter {
  const cv::Mat& source;
  cv::Size ssize, tsize;
  double cone;      // half-angle, radians
  float cos_cone;
  double row_step;  // a source row's elevation span, radians
  std::vector<glm::vec3> source_dir;       // centre direction of every source texel
  std::vector<double> row_solid_angle;     // solid angle of a texel of each source row

  ConeFilter(const cv::Mat& source, const EnvironmentSettings& s)
      : source(source), ssize(source.size()), tsize(2 * s.filtered_height_px, s.filtered_height_px),
        cone(s.filter_cone_half_angle_deg * std::numbers::pi / 180.0), cos_cone(float(std::cos(cone))),
        row_step(std::numbers::pi / ssize.height), source_dir(size_t(ssize.area())),
        row_solid_angle(size_t(ssize.height)) {
    for (int j = 0; j < ssize.height; ++j) {
      row_solid_angle[j] = equirect_pixel_solid_angle(j, ssize);
      for (int i = 0; i < ssize.width; ++i)
        source_dir[size_t(j) * ssize.width + i] = Environment::direction_from_equirect({i + 0.5f, j + 0.5f}, ssize);
    }
  }
};

// Which source columns of each row can hold a texel centre inside the cone around a target
// texel of row tj. For unit directions at elevations theta_s, theta_t and azimuth
// difference dphi,
//   s . c = cos(theta_s) cos(theta_t) cos(dphi) + sin(theta_s) sin(theta_t),
// so s . c >= cos_cone  <=>  cos(dphi) >= K = (cos_cone - sin sin) / (cos cos): the texels
// of a row inside the cone are the columns within acos(K) of the target's azimuth, one
// interval (wrapping around column 0). The interval is widened to be sure it holds every
// texel the float test in cone_average accepts: K is lowered by kDotError / (cos cos),
// kDotError bounding the float dot's error against the exact one (float directions and
// three products and two sums of magnitude <= 1: < 1e-6), and kMarginColumns columns are
// added on each side. Inside the interval the float test decides, so the accepted texels,
// and the order in which they are summed (increasing column), are those of testing every
// column of the row.
void row_intervals(const ConeFilter& f, int tj, std::vector<RowInterval>& out) {
  constexpr double kDotError = 1e-5;
  constexpr double kMarginColumns = 2.0;
  out.clear();
  const double theta_t = std::numbers::pi * (0.5 - (tj + 0.5) / f.tsize.height);
  for (int j = 0; j < f.ssize.height; ++j) {
    // Rows whose elevation differs by more than the cone (plus half a row) cannot hold
    // a texel centre inside it.
    const double theta_s = std::numbers::pi * (0.5 - (j + 0.5) / f.ssize.height);
    if (std::abs(theta_s - theta_t) > f.cone + 0.5 * f.row_step) continue;
    const double cos_cos = std::cos(theta_s) * std::cos(theta_t);
    const double sin_sin = std::sin(theta_s) * std::sin(theta_t);
    const double k_low = cos_cos > 0.0 ? (double(f.cos_cone) - kDotError - sin_sin) / cos_cos : -2.0;
    if (k_low > 1.0) continue;  // no texel of the row reaches the cone
    const double half_columns =
        k_low <= -1.0 ? double(f.ssize.width)
                      : std::acos(k_low) * f.ssize.width / (2.0 * std::numbers::pi) + kMarginColumns;
    out.push_back({j, 2.0 * half_columns + 1.0 >= double(f.ssize.width), half_columns});
  }
}

// Target texel (ti, tj): the mean over the source texels of `intervals` inside the cone,
// in increasing row and column order.
cv::Vec3f cone_average(const ConeFilter& f, const std::vector<RowInterval>& intervals, int ti, int tj) {
  const int width = f.ssize.width;
  const glm::vec3 c = Environment::direction_from_equirect({ti + 0.5f, tj + 0.5f}, f.tsize);
  // The target's azimuth as a continuous source column (the centre of column i is at
  // i + 0.5 in the layout's pixel coordinates).
  const double column_t = (ti + 0.5) * width / f.tsize.width - 0.5;
  double sum[3] = {0.0, 0.0, 0.0}, weight = 0.0;
  for (const RowInterval& interval : intervals) {
    const int j = interval.row;
    const cv::Vec3f* row = f.source.ptr<cv::Vec3f>(j);
    const glm::vec3* dirs = &f.source_dir[size_t(j) * width];
    const double d_omega = f.row_solid_angle[j];
    auto add_columns = [&](int begin, int end) {
      for (int i = begin; i < end; ++i) {
        if (glm::dot(dirs[i], c) < f.cos_cone) continue;
        for (int k = 0; k < 3; ++k) sum[k] += row[i][k] * d_omega;
        weight += d_omega;
      }
    };
    if (interval.whole_row) {
      add_columns(0, width);
      continue;
    }
    // [first, last] spans fewer than width columns, so at most one end wraps and the
    // two pieces of a wrapped interval do not overlap; the piece from column 0 comes
    // first to keep the columns in increasing order.
    const int first = int(std::ceil(column_t - interval.half_columns));
    const int last = int(std::floor(column_t + interval.half_columns));
    if (first < 0) {
      add_columns(0, last + 1);
      add_columns(first + width, width);
    } else if (last >= width) {
      add_columns(0, last - width + 1);
      add_columns(first, width);
    } else {
      add_columns(first, last + 1);
    }
  }
  if (weight > 0.0) return cv::Vec3f(float(sum[0] / weight), float(sum[1] / weight), float(sum[2] / weight));
  // Cone narrower than a source texel: the point value.
  const glm::vec3 l = bilinear_equirect(f.source, c);
  return cv::Vec3f(l.x, l.y, l.z);
}

cv::Mat cone_filtered(const cv::Mat& source, const EnvironmentSettings& s) {
  const ConeFilter f(source, s);
  cv::Mat filtered(f.tsize, CV_32FC3);
  // Target rows are independent: on OpenCV's pool (as sized by the caller; the same values
  // for any thread count).
  parallel_rows(cv::Range(0, f.tsize.height), 0, [&](const cv::Range& target_rows) {
    std::vector<RowInterval> intervals;
    intervals.reserve(size_t(f.ssize.height));
    for (int tj = target_rows.start; tj < target_rows.end; ++tj) {
      row_intervals(f, tj, intervals);
      cv::Vec3f* out = filtered.ptr<cv::Vec3f>(tj);
      for (int ti = 0; ti < f.tsize.width; ++ti) out[ti] = cone_average(f, intervals, ti, tj);
    }
  }, 1);
  return filtered;
}

}  // namespace

// The SH projection of the radiance (for mean_radiance), the irradiance table (for
// irradiance_over_pi) and the cone-filtered map (for radiance_filtered).
void Environment::build() {
  if (kind_ == EnvironmentKind::constant) {
    // Exact: only L_00 = L * Y_00 * 4 pi is non-zero.
    sh_.fill(glm::vec3(0.0f));
    sh_[0] = constant_ * float(0.28209479177387814 * 4.0 * std::numbers::pi);
    // Band 0 alone: the same for every normal (the other bands add exact zeros).
    constant_irradiance_over_pi_ = sh_irradiance_over_pi(glm::vec3(0.0f, 0.0f, 1.0f));
    filtered_ = cv::Mat(settings_.filtered_height_px, 2 * settings_.filtered_height_px, CV_32FC3,
                        cv::Scalar(constant_.x, constant_.y, constant_.z));
    return;
  }
  // The radiance on an equirect grid: the image itself, or the analytic sky at texel centres.
  const cv::Mat grid = kind_ == EnvironmentKind::sky ? tabulated_sky(*this) : image_;
  sh_ = sh_projection(grid);
  const cv::Mat source = filter_source(grid);
  irradiance_ = irradiance_table(source);
  filtered_ = cone_filtered(source, settings_);
}

}  // namespace ssdo
