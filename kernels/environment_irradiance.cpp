// The irradiance table, kernels/environment_irradiance.h.
#include "kernels/environment_irradiance.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/environment_irradiance.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "core/parallel.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {
namespace {

// Solid angle of a texel of row j of a w x h equirect (the band between two elevations has
// area 2 pi (sin top - sin bottom), shared by its w texels).
double pixel_solid_angle(int j, int w, int h) {
  const double top = std::numbers::pi * (0.5 - double(j) / h), bottom = std::numbers::pi * (0.5 - double(j + 1) / h);
  return (2.0 * std::numbers::pi / w) * (std::sin(top) - std::sin(bottom));
}

}  // namespace

// Normals and texels share the columns' azimuths, so n . d_t depends on
// the two rows and the column difference only (cos el_n cos el_t cos(d az) + sin el_n sin
// el_t): a table row is a sum over source rows and column shifts of weight x shifted source
// row, with the weights computed once per (row, row, shift) and the zero ones (the far
// hemisphere) skipped. The same operations in the same order on every instruction set.
cv::Mat irradiance_table(const cv::Mat& source, int nthreads) {
  const int w = source.cols, h = source.rows;
  std::vector<double> sin_el(static_cast<size_t>(h)), cos_el(static_cast<size_t>(h)), cos_shift(static_cast<size_t>(w));
  for (int j = 0; j < h; ++j) {
    const double el = std::numbers::pi * (0.5 - (j + 0.5) / h);
    sin_el[size_t(j)] = std::sin(el), cos_el[size_t(j)] = std::cos(el);
  }
  for (int d = 0; d < w; ++d) cos_shift[size_t(d)] = std::cos(2.0 * std::numbers::pi * d / w);
  // Each source row's channels as planes, twice over, so that a shift is a contiguous window.
  std::vector<float> planes(size_t(h) * 3 * 2 * w);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < 2 * w; ++i)
      for (int c = 0; c < 3; ++c) planes[(size_t(j) * 3 + c) * 2 * w + i] = source.at<cv::Vec3f>(j, i % w)[c];
  cv::Mat table(source.size(), CV_32FC3);
  parallel_rows(cv::Range(0, h), nthreads, [&](const cv::Range& rows) {
    std::vector<float> acc(size_t(3 * w));
    for (int jn = rows.start; jn < rows.end; ++jn) {
      std::fill(acc.begin(), acc.end(), 0.0f);
      double weight_sum = 0.0;
      for (int jt = 0; jt < h; ++jt) {
        const double omega = pixel_solid_angle(jt, w, h);
        const double a = cos_el[size_t(jn)] * cos_el[size_t(jt)], b = sin_el[size_t(jn)] * sin_el[size_t(jt)];
        for (int d = 0; d < w; ++d) {
          const double cosine = a * cos_shift[size_t(d)] + b;
          if (cosine <= 0.0) continue;
          const float wt = float(omega * cosine);
          weight_sum += wt;
          // Normal column i sees texel column i - d (mod w): window [w - d, 2 w - d) of the planes.
          for (int c = 0; c < 3; ++c) {
            const float* src = planes.data() + (size_t(jt) * 3 + c) * 2 * w + (w - d);
            float* dst = acc.data() + size_t(c) * w;
            for (int i = 0; i < w; ++i) dst[i] += wt * src[i];
          }
        }
      }
      cv::Vec3f* out = table.ptr<cv::Vec3f>(jn);
      const float inv = float(1.0 / weight_sum);
      for (int i = 0; i < w; ++i)
        out[i] = cv::Vec3f(acc[size_t(i)] * inv, acc[size_t(w + i)] * inv, acc[size_t(2 * w + i)] * inv);
    }
  }, 1);
  return table;
}


}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

HWY_EXPORT(irradiance_table);

cv::Mat irradiance_table(const cv::Mat& source, int nthreads) {
  CV_Assert(source.type() == CV_32FC3 && !source.empty());
  return HWY_DYNAMIC_DISPATCH(irradiance_table)(source, nthreads);
}

}  // namespace ssdo
#endif  // HWY_ONCE
