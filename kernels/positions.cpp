#include "kernels/positions.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/positions.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <algorithm>

#include "core/parallel.h"
#include "kernels/iota_lanes.h"
#include "kernels/mask_lanes.h"
#include "kernels/position_lanes.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

cv::Rect prepare_view_vectors(const cv::Mat& depth_view, const cv::Mat& mask, cv::Mat& out, cv::Rect roi) {
  CV_Assert(depth_view.type() == CV_32FC1 && mask.type() == CV_8UC1 &&
            mask.size() == depth_view.size());
  if (out.size() != depth_view.size() || out.type() != CV_32FC3) out.create(depth_view.size(), CV_32FC3);
  return resolve_roi(roi, depth_view.size());
}

void view_positions_from_depth(const cv::Mat& depth_view, const cv::Mat& mask,
                               const Camera& camera, cv::Mat& position_view, cv::Rect roi,
                               int nthreads) {
  namespace hn = hwy::HWY_NAMESPACE;
  const cv::Rect r = prepare_view_vectors(depth_view, mask, position_view, roi);
  const PixelDepthLanes solve(camera);
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    const hn::ScalableTag<float> d;
    const int lanes = int(hn::Lanes(d));
    for (int y = rows.start; y < rows.end; ++y) {
      const float* depth = depth_view.ptr<float>(y);
      const uint8_t* m = mask.ptr<uint8_t>(y);
      float* out = position_view.ptr<float>(y);
      const auto py = hn::Set(d, float(y) + 0.5f);
      int x = r.x;
      for (; x + lanes <= r.x + r.width; x += lanes) {
        const auto px = pixel_centres_lanes(d, x);
        hn::Vec<decltype(d)> px_view, py_view, pz_view;
        solve(px, py, hn::LoadU(d, depth + x), px_view, py_view, pz_view);
        const auto fg = foreground_lanes(m + x);
        hn::StoreInterleaved3(hn::IfThenElseZero(fg, px_view), hn::IfThenElseZero(fg, py_view),
                              hn::IfThenElseZero(fg, pz_view), d, out + size_t(3) * size_t(x));
      }
      for (; x < r.x + r.width; ++x)
        store_position_or_zero(camera, m[x] != 0, x + 0.5f, y + 0.5f, depth[x], out + size_t(3) * size_t(x));
    }
  });
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

HWY_EXPORT(view_positions_from_depth);
void view_positions_from_depth(const cv::Mat& depth_view, const cv::Mat& mask, const Camera& camera,
                               cv::Mat& position_view, cv::Rect roi, int nthreads) {
  HWY_DYNAMIC_DISPATCH(view_positions_from_depth)(depth_view, mask, camera, position_view, roi, nthreads);
}

// Not per pixel: the baseline's code serves every CPU.
cv::Rect prepare_view_vectors(const cv::Mat& depth_view, const cv::Mat& mask, cv::Mat& out, cv::Rect roi) {
  return HWY_NAMESPACE::prepare_view_vectors(depth_view, mask, out, roi);
}

}  // namespace ssdo
#endif  // HWY_ONCE
