#include "kernels/temporal_change.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/temporal_change.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <vector>

#include "core/parallel.h"
#include "kernels/distance_transform.h"
#include "kernels/iota_lanes.h"
#include "kernels/mask_lanes.h"
#include "kernels/reprojection.h"
#include "kernels/reprojection_lanes.h"

// The pass over the frame's pixels (whether a mark lies within the radius of each one's
// point), a vector of pixels at a time: it reads every pixel of the frame, where the search
// for marks reads only the lattice's points.
HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;
using reprojection_lanes::DF;
using reprojection_lanes::MF;
using reprojection_lanes::VF;
using DI = hn::RebindToSigned<DF>;
using VI = hn::Vec<DI>;

// The most float lanes of any target: the size of per-lane scratch arrays.
constexpr size_t kMaxLanes = HWY_MAX_BYTES / sizeof(float);

// The filter's bilinear taps reach up to a texel past the projected point: the radius in
// pixels is widened by one (and by the lattice's step, mark_stride_px).
constexpr float kMarkMarginPx = 1.0f;

// Per lane, the pixels of `camera` around a point's projection within which the sphere of
// radius s.radius_world around the point (planar depth d, > 0) lies: the sphere is nowhere
// nearer than d - R, where a length R covers R x pixels_per_unit(d - R) pixels (for a
// pinhole f R / (d - R), at least the sphere's projected radius f R / sqrt(d^2 - R^2)); at
// most s.max_radius_px (the estimators reach no farther), and that when the eye is within
// about R of the point. Widened by kMarkMarginPx.
VF changed_radius_lanes(const Camera& camera, VF depth_view, const TemporalSettings& s) {
  const DF d;
  const VF nearest = hn::Sub(depth_view, hn::Set(d, s.radius_world));
  const MF ok = hn::Gt(nearest, hn::Mul(hn::Set(d, 0.01f), depth_view));
  // Camera::pixels_per_unit(nearest): clip.w on the axis, w = m[2][3] (-nearest) + m[3][3]
  // (> 0 in front of the eye); max(a / w, b / w) = max(a, b) / w.
  const glm::mat4& m = camera.view_to_clip;
  const VF w = hn::Add(hn::Mul(hn::Set(d, m[2][3]), hn::Neg(nearest)), hn::Set(d, m[3][3]));
  const float per_unit = std::max(0.5f * float(camera.width_px) * std::abs(m[0][0]),
                                  0.5f * float(camera.height_px) * std::abs(m[1][1]));
  const VF pixels_per_unit = hn::Div(hn::Set(d, per_unit), hn::IfThenElse(ok, w, hn::Set(d, 1.0f)));
  const VF r = hn::Min(hn::Mul(hn::Set(d, s.radius_world), pixels_per_unit), hn::Set(d, s.max_radius_px));
  return hn::IfThenElse(ok, hn::Add(r, hn::Set(d, kMarkMarginPx)), hn::Set(d, s.max_radius_px + kMarkMarginPx));
}

// 255 in the lanes of `on`, else 0, as bytes into out[0 .. count).
void store_bytes(MF on, size_t count, uint8_t* out) {
  const DI di;
  const hn::Rebind<uint8_t, DF> d8;
  HWY_ALIGN uint8_t bytes[kMaxLanes];
  hn::Store(hn::DemoteTo(d8, hn::IfThenElseZero(hn::RebindMask(di, on), hn::Set(di, 255))), d8, bytes);
  std::copy(bytes, bytes + count, out);
}

// A frame's marks as the pass reads them: the squared distances on its lattice
// (squared_distance_to_marks of the search's marks; empty when there is none) and the
// lattice's step.
struct MarkDistances {
  const cv::Mat& squared;  // lattice points^2
  int step;

  // The lanes `valid` in which a mark lies within radius_px of the continuous pixel
  // coordinates (px, py): the distance of the nearest lattice point (at most step / sqrt(2)
  // away, so within radius_px + step of it). Coordinates of lanes not `valid` are not read.
  MF within(VF px, VF py, VF radius_px, MF valid) const {
    const DF d;
    const DI di;
    const VF step_px = hn::Set(d, float(step)), half = hn::Set(d, 0.5f), zero = hn::Zero(d);
    auto nearest_point = [&](VF pixel, int points) {  // round(clamp((pixel - 0.5) / step))
      const VF u = hn::Div(hn::Sub(hn::IfThenElseZero(valid, pixel), half), step_px);
      const VF clamped = hn::Min(hn::Max(u, zero), hn::Set(d, float(points - 1)));
      return hn::ConvertTo(di, hn::Floor(hn::Add(clamped, half)));
    };
    const auto i = nearest_point(px, squared.cols), j = nearest_point(py, squared.rows);
    const auto at = hn::Add(hn::Mul(j, hn::Set(di, int32_t(squared.step[0] / sizeof(float)))), i);
    const VF squared_points = hn::GatherIndex(d, squared.ptr<float>(0), at);
    const VF reach = hn::Div(hn::Add(radius_px, step_px), step_px);
    return hn::And(valid, hn::Le(squared_points, hn::Mul(reach, reach)));
  }
};

// What the pass reads of the two frames.
struct ChangedPass {
  const TemporalFrame& frame;
  const TemporalFrame& neighbour;
  const TemporalSettings& s;
  const PixelRays& rays;  // frame's pixel points in the neighbour's view
  const MarkDistances& to_frame_marks;
  const MarkDistances& to_neighbour_marks;

  // Pixels x0 .. x0 + N - 1 of row y (N: the lanes; those at or past the row's end are
  // not): 255 where a foreground pixel's surroundings changed, else 0, into out; returns how
  // many changed.
  int64_t lanes(int y, int x0, uint8_t* out) const {
    const DF d;
    const size_t n = hn::Lanes(d), count = std::min(n, size_t(frame.depth_view.cols - x0));
    const float* depth_row = frame.depth_view.ptr<float>(y) + x0;
    HWY_ALIGN float depth_tail[kMaxLanes];
    if (count < n) {  // the row's last pixels; lanes past them background
      std::fill(std::copy(depth_row, depth_row + count, depth_tail), depth_tail + n, 1.0f);
      depth_row = depth_tail;
    }
    const MF fg = foreground_lanes(frame.mask.ptr<uint8_t>(y) + x0, count);
    const VF depth = hn::IfThenElse(fg, hn::LoadU(d, depth_row), hn::Set(d, 1.0f));
    const VF px = pixel_centres_lanes(d, x0), py = hn::Set(d, float(y) + 0.5f);
    MF near = hn::FirstN(d, 0);
    if (!to_frame_marks.squared.empty())
      near = to_frame_marks.within(px, py, changed_radius_lanes(frame.camera, depth, s), fg);
    if (!to_neighbour_marks.squared.empty()) {  // the neighbour's marks around the point's projection
      const reprojection_lanes::Vec3L p = reprojection_lanes::ray_point(rays, px, py, depth);
      const VF depth_there = hn::Neg(p.z);
      const reprojection_lanes::ProjectedLanes there = reprojection_lanes::project(neighbour.camera, p);
      const MF seen = hn::And(hn::And(fg, there.valid), hn::Gt(depth_there, hn::Zero(d)));
      const VF radius = changed_radius_lanes(neighbour.camera, hn::IfThenElse(seen, depth_there, hn::Set(d, 1.0f)), s);
      near = hn::Or(near, to_neighbour_marks.within(there.pixel_x, there.pixel_y, radius, seen));
    }
    store_bytes(near, count, out + x0);
    return int64_t(hn::CountTrue(d, near));
  }
};

// Whether `to` sees through the points of `from` on lattice row j, i = i0 .. i0 + N - 1 (N:
// the lanes; those at or past the row's last point are not): the smallest depth of the 2x2
// texel centres of `to` around a point's projection that lie in the image and are
// foreground is farther than the point by more than tolerance_relative x its depth (the
// tolerance of the tangent-plane test, TemporalSettings::depth_tolerance_relative). No
// point behind `to`'s eye or without a texel of the 2x2 in the image is: nothing is seen
// there. 255 where seen through, else 0, into out; returns how many.
struct SeenThroughPass {
  const TemporalFrame& from;
  const TemporalFrame& to;
  const PixelRays& rays;  // from's pixel points in to's view
  float tolerance_relative;
  int step;    // the lattice's, pixels
  int points;  // per lattice row

  // Foreground lanes of to's 2x2 texel t (t & 1: the next column, t >> 1: the next row)
  // around texel (x0, y0) of each lane in `inside`, and their depths.
  MF texel(VI x0, VI y0, int t, MF inside, VF& depth) const {
    const DF d;
    const DI di;
    const VI tx = hn::Add(x0, hn::Set(di, t & 1)), ty = hn::Add(y0, hn::Set(di, t >> 1));
    const auto in_image = hn::And(hn::And(hn::Gt(tx, hn::Set(di, -1)), hn::Lt(tx, hn::Set(di, to.depth_view.cols))),
                                  hn::And(hn::Gt(ty, hn::Set(di, -1)), hn::Lt(ty, hn::Set(di, to.depth_view.rows))));
    const MF in = hn::And(inside, hn::RebindMask(d, in_image));
    const auto in_i = hn::RebindMask(di, in);
    const VI depth_at = hn::IfThenElseZero(
        in_i, hn::Add(hn::Mul(ty, hn::Set(di, int32_t(to.depth_view.step[0] / sizeof(float)))), tx));
    depth = hn::GatherIndex(d, to.depth_view.ptr<float>(0), depth_at);
    HWY_ALIGN int32_t mask_at[kMaxLanes];
    hn::Store(hn::IfThenElseZero(in_i, hn::Add(hn::Mul(ty, hn::Set(di, int32_t(to.mask.step[0]))), tx)), di, mask_at);
    HWY_ALIGN uint8_t mask[kMaxLanes];
    for (size_t l = 0; l < hn::Lanes(d); ++l) mask[l] = to.mask.data[mask_at[l]];
    return hn::And(in, foreground_lanes(mask));
  }

  // Lattice points i0 .. i0 + N - 1 of row j, as above, into out[i0 ..].
  int64_t lanes(int j, int i0, uint8_t* out) const {
    const DF d;
    const DI di;
    const size_t n = hn::Lanes(d), count = std::min(n, size_t(points - i0));
    const int y = j * step;
    HWY_ALIGN float depth_at_points[kMaxLanes];
    HWY_ALIGN uint8_t mask_at_points[kMaxLanes] = {};
    for (size_t l = 0; l < count; ++l) {
      const int x = (i0 + int(l)) * step;
      depth_at_points[l] = from.depth_view.ptr<float>(y)[x];
      mask_at_points[l] = from.mask.ptr<uint8_t>(y)[x];
    }
    std::fill(depth_at_points + count, depth_at_points + n, 1.0f);
    const MF fg = foreground_lanes(mask_at_points);
    const VF depth = hn::IfThenElse(fg, hn::Load(d, depth_at_points), hn::Set(d, 1.0f));
    const VF px = pixel_centres_lanes(d, i0 * step, step);
    const VF py = hn::Set(d, float(y) + 0.5f);
    const reprojection_lanes::Vec3L p = reprojection_lanes::ray_point(rays, px, py, depth);
    const VF point_depth = hn::Neg(p.z);
    const reprojection_lanes::ProjectedLanes there = reprojection_lanes::project(to.camera, p);
    MF inside = hn::And(hn::And(fg, there.valid), hn::Gt(point_depth, hn::Zero(d)));
    // The texel centres around the projection: floor(pixel - 0.5) and the next ones.
    const VF outside = hn::Set(d, -2.0f);
    const VF gx = hn::IfThenElse(inside, hn::Sub(there.pixel_x, hn::Set(d, 0.5f)), outside);
    const VF gy = hn::IfThenElse(inside, hn::Sub(there.pixel_y, hn::Set(d, 0.5f)), outside);
    inside = hn::And(inside, hn::And(hn::Gt(gx, hn::Set(d, -1.0f)), hn::Gt(gy, hn::Set(d, -1.0f))));
    inside = hn::And(inside, hn::And(hn::Lt(gx, hn::Set(d, float(to.depth_view.cols))),
                                     hn::Lt(gy, hn::Set(d, float(to.depth_view.rows)))));
    const VI x0 = hn::ConvertTo(di, hn::Floor(hn::IfThenElseZero(inside, gx)));
    const VI y0 = hn::ConvertTo(di, hn::Floor(hn::IfThenElseZero(inside, gy)));
    VF nearest = hn::Set(d, std::numeric_limits<float>::infinity());
    for (int t = 0; t < 4; ++t) {
      VF texel_depth;
      const MF seen = texel(x0, y0, t, inside, texel_depth);
      nearest = hn::IfThenElse(seen, hn::Min(nearest, texel_depth), nearest);
    }
    const MF marked =
        hn::And(inside, hn::Gt(nearest, hn::Mul(point_depth, hn::Set(d, 1.0f + tolerance_relative))));
    store_bytes(marked, count, out + i0);
    return int64_t(hn::CountTrue(d, marked));
  }
};

// pass.lanes(row, first, out's row) over every vector of each row of `out` (CV_8UC1), rows
// in parallel: the sum of what it returns.
template <class Pass>
int64_t run_rows(const Pass& pass, cv::Mat& out, int nthreads) {
  std::atomic<int64_t> count{0};
  parallel_rows(cv::Range(0, out.rows), nthreads, [&](const cv::Range& rows) {
    int64_t strip = 0;
    for (int y = rows.start; y < rows.end; ++y)
      for (int x0 = 0; x0 < out.cols; x0 += int(hn::Lanes(DF()))) strip += pass.lanes(y, x0, out.ptr<uint8_t>(y));
    count += strip;
  }, 16);
  return count;
}

}  // namespace

// changed_surroundings' pass over the frame's pixels, given the squared distances to each
// frame's marks on its lattice (empty: no mark) and the lattices' steps: the changed image,
// and how many pixels changed.
int64_t mark_changed_pixels(const TemporalFrame& frame, const TemporalFrame& neighbour, const TemporalSettings& s,
                            const cv::Mat& to_frame_marks, int frame_step, const cv::Mat& to_neighbour_marks,
                            int neighbour_step, cv::Mat& changed, int nthreads) {
  const Reprojection r(frame.camera, neighbour.camera);
  const MarkDistances frame_marks{to_frame_marks, frame_step}, neighbour_marks{to_neighbour_marks, neighbour_step};
  const ChangedPass pass{frame, neighbour, s, r.from_rays_in_to(), frame_marks, neighbour_marks};
  changed.create(frame.depth_view.size(), CV_8UC1);
  return run_rows(pass, changed, nthreads);
}

// seen_through's test of every point of `from`'s lattice (step: its spacing in pixels) into
// marks (CV_8UC1, the lattice's size): 255 where `to` sees through the point, else 0;
// returns how many.
int64_t mark_seen_through(const TemporalFrame& from, const TemporalFrame& to, float tolerance_relative, int step,
                          cv::Mat& marks, int nthreads) {
  const Reprojection r(from.camera, to.camera);
  const SeenThroughPass pass{from, to, r.from_rays_in_to(), tolerance_relative, step, marks.cols};
  return run_rows(pass, marks, nthreads);
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

HWY_EXPORT(mark_seen_through);
HWY_EXPORT(mark_changed_pixels);

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// Marks are sought on a lattice of pixels at most this many points wide (mark_stride_px):
// a point's test (a reprojection and four texels) costs about what the filter spends on a
// texel per neighbour, so at every pixel of a 1080p frame the two passes would cost about
// as much as the filter; on the lattice they cost those of a 480 x 270 frame at any size,
// and a moved object is still found when it spans 2 x 2 of the lattice's points (the
// opening, keep_blocks), 8 pixels of a 1080p frame.
constexpr int kMarkLatticeWidth = 480;

// The lattice's step for a frame `width_px` wide: pixel (x, y) with x, y multiples of it.
int mark_stride_px(int width_px) { return std::max(1, (width_px + kMarkLatticeWidth - 1) / kMarkLatticeWidth); }

// The marks that belong to a 2x2 block of marks (a morphological opening by a 2x2 square):
// a surface one texel wide that the grids sample in one frame and miss in the other (a thin
// pole, a silhouette's aliasing) leaves a line of single marks, a moved object a region.
// Returns how many are kept.
int64_t keep_blocks(cv::Mat& marks) {
  const cv::Mat m = marks.clone();
  auto block = [&](int x, int y) {  // the 2x2 block with (x, y) top left is all marks
    return x >= 0 && y >= 0 && x + 1 < m.cols && y + 1 < m.rows && m.at<uint8_t>(y, x) && m.at<uint8_t>(y, x + 1) &&
           m.at<uint8_t>(y + 1, x) && m.at<uint8_t>(y + 1, x + 1);
  };
  int64_t kept = 0;
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x) {
      if (!m.at<uint8_t>(y, x)) continue;
      const bool keep = block(x, y) || block(x - 1, y) || block(x, y - 1) || block(x - 1, y - 1);
      marks.at<uint8_t>(y, x) = keep ? 255 : 0;
      kept += keep;
    }
  return kept;
}

// On the lattice of `from` (point (i, j): pixel (i, j) x mark_stride_px), 255 at the
// foreground pixels whose point `to` sees through (mark_seen_through), then only those in
// 2x2 blocks (keep_blocks); 0 elsewhere. CV_8UC1; marks_px: how many.
cv::Mat seen_through(const TemporalFrame& from, const TemporalFrame& to, float tolerance_relative, int64_t& marks_px,
                     int nthreads) {
  const int step = mark_stride_px(from.depth_view.cols);
  cv::Mat marks((from.depth_view.rows + step - 1) / step, (from.depth_view.cols + step - 1) / step, CV_8UC1);
  const int64_t count = HWY_DYNAMIC_DISPATCH(mark_seen_through)(from, to, tolerance_relative, step, marks, nthreads);
  marks_px = count > 0 ? keep_blocks(marks) : 0;
  return marks;
}

}  // namespace

cv::Mat changed_surroundings(const TemporalFrame& frame, const TemporalFrame& neighbour, const TemporalSettings& s,
                             int64_t& changed_px, int nthreads) {
  int64_t in_frame_px = 0, in_neighbour_px = 0;
  const float tolerance = s.depth_tolerance_relative;
  const cv::Mat frame_marks = seen_through(frame, neighbour, tolerance, in_frame_px, nthreads);
  const cv::Mat neighbour_marks = seen_through(neighbour, frame, tolerance, in_neighbour_px, nthreads);
  changed_px = 0;
  if (in_frame_px == 0 && in_neighbour_px == 0) return {};
  const cv::Mat to_frame_marks = in_frame_px > 0 ? squared_distance_to_marks(frame_marks, nthreads) : cv::Mat();
  const cv::Mat to_neighbour_marks =
      in_neighbour_px > 0 ? squared_distance_to_marks(neighbour_marks, nthreads) : cv::Mat();
  cv::Mat changed;
  changed_px = HWY_DYNAMIC_DISPATCH(mark_changed_pixels)(frame, neighbour, s, to_frame_marks,
                                                         mark_stride_px(frame.depth_view.cols), to_neighbour_marks,
                                                         mark_stride_px(neighbour.depth_view.cols), changed, nthreads);
  if (changed_px == 0) return {};
  return changed;
}

}  // namespace ssdo
#endif  // HWY_ONCE
