#include "kernels/temporal.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/temporal.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>

#include "core/parallel.h"
#include "kernels/integer_power.h"
#include "kernels/iota_lanes.h"
#include "kernels/mask_lanes.h"
#include "kernels/record_lanes.h"
#include "kernels/reprojection.h"
#include "kernels/reprojection_lanes.h"
#include "kernels/settings_check.h"
#include "kernels/temporal_change.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {
namespace {

// Every term's channels of one pixel, summed at once (AO + two RGB SSDO terms = 7).
constexpr int kMaxChannels = 16;
using Channels = std::array<float, kMaxChannels>;
// Whether a neighbour is used is measured on every 4th pixel of every 4th row.
constexpr int kMeasureStridePx = 4;

struct Neighbour {
  const TemporalFrame* frame;
  Reprojection reprojection;
  // CV_8UC1 at the frame's size: 255 where the surroundings changed (no taps), or empty
  // when none did.
  cv::Mat changed;
};

namespace hn = hwy::HWY_NAMESPACE;
using DF = hn::ScalableTag<float>;
using DI = hn::RebindToSigned<DF>;
using VF = hn::Vec<DF>;
using VI = hn::Vec<DI>;
using MF = hn::Mask<DF>;

// The most float lanes of any target: the size of per-lane scratch arrays.
constexpr size_t kMaxLanes = HWY_MAX_BYTES / sizeof(float);

// An image as the lanes gather it: channel c of texel (tx, ty) is data[ty * stride + tx *
// channels + c].
struct Plane {
  const float* data;
  int32_t stride, channels;
};
Plane plane_of(const cv::Mat& m) { return {m.ptr<float>(0), int32_t(m.step[0] / sizeof(float)), m.channels()}; }

using reprojection_lanes::broadcast;
using reprojection_lanes::dot;
using reprojection_lanes::ray_point;
using reprojection_lanes::sub;
using reprojection_lanes::Vec3L;

// A neighbour's parts as the lanes read them. Its depth is NaN on background texels (the
// mask folded in), so that the texel's one depth gather also rejects them: every test of a
// NaN depth fails (texel_weight_lanes), as the mask's did, without a byte read per lane.
struct NeighbourPlanes {
  cv::Mat foreground_depth;
  Plane depth, normal;
  // Float offsets below this read the normal's record of 4 floats inside the image
  // (triples_at).
  int32_t normal_records_below;
  std::vector<Plane> terms;  // the frame's terms' order
  // Per term, as normal_records_below (records_below: 0 for a term that is not RGB, which
  // is gathered channel by channel).
  std::vector<int32_t> term_records_below;
};

// The float offset below which a record of 4 floats from a pixel's first channel lies
// inside an image of 3 channels: every pixel's but the last one's (its channels are the
// image's last floats). 0 for other images, which are not read as records (triples_at).
int32_t records_below(const cv::Mat& m) {
  if (m.channels() != 3) return 0;
  return int32_t((m.rows - 1) * (m.step[0] / sizeof(float)) + 3 * (m.cols - 1));
}

NeighbourPlanes planes_of(const TemporalFrame& u, int nthreads) {
  NeighbourPlanes p;
  p.foreground_depth.create(u.depth_view.size(), CV_32FC1);
  parallel_rows(cv::Range(0, u.depth_view.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* depth = u.depth_view.ptr<float>(y);
      const uint8_t* mask = u.mask.ptr<uint8_t>(y);
      float* out = p.foreground_depth.ptr<float>(y);
      for (int x = 0; x < u.depth_view.cols; ++x) out[x] = mask[x] ? depth[x] : std::numeric_limits<float>::quiet_NaN();
    }
  }, 16);
  p.depth = plane_of(p.foreground_depth);
  p.normal = plane_of(u.normal_view);
  p.normal_records_below = records_below(u.normal_view);
  for (const cv::Mat* term : u.terms) {
    p.terms.push_back(plane_of(*term));
    p.term_records_below.push_back(records_below(*term));
  }
  return p;
}

// Reprojection::carry of each lane's pixel, in lanes: the point's pixel coordinates in the
// neighbour (valid: in front of its eye), its normal there and its tangent plane's distance
// as a bilinear form in the neighbour's pixels (PixelPoints::PlaneDistance).
struct CarriedLanes {
  VF pixel_x, pixel_y;
  MF valid;
  Vec3L normal;
  VF c0, cx, cy, d0, dx, dy;
};
// Built whole at its return, never default-constructed (structs of Highway vectors on Arm:
// docs/architecture.md).
CarriedLanes carry_lanes(const Reprojection& r, VF px, VF py, VF depth, const Vec3L& normal) {
  const DF d;
  const Vec3L p = ray_point(r.from_rays_in_to(), px, py, depth);
  const glm::mat3 rot = r.rotation();  // rot[column][row]
  const Vec3L n{dot({hn::Set(d, rot[0][0]), hn::Set(d, rot[1][0]), hn::Set(d, rot[2][0])}, normal),
                dot({hn::Set(d, rot[0][1]), hn::Set(d, rot[1][1]), hn::Set(d, rot[2][1])}, normal),
                dot({hn::Set(d, rot[0][2]), hn::Set(d, rot[1][2]), hn::Set(d, rot[2][2])}, normal)};
  const reprojection_lanes::ProjectedLanes pixel = reprojection_lanes::project(r.to(), p);
  const PixelRays& t = r.to_rays();
  return {pixel.pixel_x,
          pixel.pixel_y,
          pixel.valid,
          n,
          dot(n, sub(broadcast(t.o0), p)),
          dot(n, broadcast(t.ox)),
          dot(n, broadcast(t.oy)),
          dot(n, broadcast(t.u0)),
          dot(n, broadcast(t.ux)),
          dot(n, broadcast(t.uy))};
}

// Per-lane sums of a group of pixels: their channels (every term in order) and the total weight.
struct GroupSums {
  // A constructor of its own (structs of Highway vectors on Arm: docs/architecture.md).
  explicit GroupSums(VF initial_total) : total(initial_total) {}
  HWY_ALIGN float channel[kMaxChannels][kMaxLanes];
  VF total;
};

// The three channels of an image of three (data) at float offsets `at`: one 16-byte load
// per lane (the channels and the next pixel's first, load_records4) instead of three
// gathers, unless a lane reads the image's last pixel (at >= below).
Vec3L triples_at(const float* data, VI at, int32_t below) {
  const DF d;
  const DI di;
  if (!hn::AllTrue(di, hn::Lt(at, hn::Set(di, below))))
    return {hn::GatherIndex(d, data, at), hn::GatherIndex(d, data + 1, at), hn::GatherIndex(d, data + 2, at)};
  HWY_ALIGN int32_t offsets[kMaxLanes];
  hn::Store(at, di, offsets);
  VF field[4];
  load_records4(d, data, offsets, field);
  return {field[0], field[1], field[2]};
}

// The weight (temporal.h) of texels (tx, ty) of neighbour u for carried points c, times
// `bilinear`: positive where `ok` (inside, in the image, on the neighbour's foreground: a
// depth that is a number, on the same surface, facing alike), 0 elsewhere; sx, sy: the
// texels, (0, 0) where not in the image.
VF texel_weight_lanes(const NeighbourPlanes& u, const CarriedLanes& c, MF inside, VI tx, VI ty, VF bilinear,
                      VF inverse_tolerance, float normal_power, int cols, int rows, MF& ok, VI& sx, VI& sy) {
  const DF d;
  const DI di;
  ok = hn::And(inside, hn::Gt(bilinear, hn::Zero(d)));
  const VI minus_one = hn::Set(di, -1);
  ok = hn::And(ok, hn::RebindMask(d, hn::And(hn::And(hn::Gt(tx, minus_one), hn::Gt(ty, minus_one)),
                                             hn::And(hn::Lt(tx, hn::Set(di, cols)), hn::Lt(ty, hn::Set(di, rows))))));
  sx = hn::IfThenElseZero(hn::RebindMask(di, ok), tx), sy = hn::IfThenElseZero(hn::RebindMask(di, ok), ty);
  const VF depth_u = hn::GatherIndex(d, u.depth.data, hn::Add(hn::Mul(sy, hn::Set(di, u.depth.stride)), sx));
  const VI normal_at = hn::Add(hn::Mul(sy, hn::Set(di, u.normal.stride)), hn::Mul(sx, hn::Set(di, 3)));
  const Vec3L normal_u = triples_at(u.normal.data, normal_at, u.normal_records_below);
  // PixelPoints::PlaneDistance::signed_at at the texel's centre.
  const VF half = hn::Set(d, 0.5f);
  const VF tpx = hn::Add(hn::ConvertTo(d, tx), half), tpy = hn::Add(hn::ConvertTo(d, ty), half);
  const VF e = hn::Abs(hn::Add(hn::Add(hn::Add(c.c0, hn::Mul(tpx, c.cx)), hn::Mul(tpy, c.cy)),
                               hn::Mul(depth_u, hn::Add(hn::Add(c.d0, hn::Mul(tpx, c.dx)), hn::Mul(tpy, c.dy)))));
  // NaN on background texels: the test below fails there.
  const VF w_plane = hn::Sub(hn::Set(d, 1.0f), hn::Mul(e, inverse_tolerance));
  const VF cosine = dot(c.normal, normal_u);
  ok = hn::And(ok, hn::And(hn::Gt(w_plane, hn::Zero(d)), hn::Gt(cosine, hn::Zero(d))));
  const VF w = hn::Mul(bilinear, hn::Mul(w_plane, power_of(d, hn::IfThenElseZero(ok, cosine), normal_power)));
  ok = hn::And(ok, hn::Gt(w, hn::Zero(d)));
  return hn::IfThenElseZero(ok, w);
}

// Texel i (0..3: x0 + (i & 1), y0 + (i >> 1)) of the bilinear footprint of carried points
// c in neighbour u: its weight (temporal.h) added with its channels where it agrees.
void add_texel_lanes(const NeighbourPlanes& u, const CarriedLanes& c, MF inside, VI x0, VI y0, VF bilinear,
                     VF inverse_tolerance, float normal_power, int cols, int rows, GroupSums& sums) {
  const DF d;
  const DI di;
  MF ok;
  VI sx, sy;
  const VF w =
      texel_weight_lanes(u, c, inside, x0, y0, bilinear, inverse_tolerance, normal_power, cols, rows, ok, sx, sy);
  sums.total = hn::IfThenElse(ok, hn::Add(sums.total, w), sums.total);
  auto add_channel = [&](int k, VF v) {
    const VF sum = hn::Load(d, sums.channel[k]);
    hn::Store(hn::IfThenElse(ok, hn::Add(sum, hn::Mul(w, v)), sum), d, sums.channel[k]);
  };
  int k = 0;
  for (size_t t = 0; t < u.terms.size(); ++t) {
    const Plane& term = u.terms[t];
    const VI at = hn::Add(hn::Mul(sy, hn::Set(di, term.stride)), hn::Mul(sx, hn::Set(di, term.channels)));
    if (term.channels == 3) {  // an RGB term: its texels' records
      const Vec3L v = triples_at(term.data, at, u.term_records_below[t]);
      add_channel(k, v.x), add_channel(k + 1, v.y), add_channel(k + 2, v.z);
      k += 3;
      continue;
    }
    for (int ch = 0; ch < term.channels; ++ch, ++k) add_channel(k, hn::GatherIndex(d, term.data + ch, at));
  }
}

// Whether the surroundings of pixels x0 + i of row y (i: the lanes) stayed the same in
// neighbour n: true in every lane when it has no changed pixel.
MF unchanged_lanes(const Neighbour& n, int y, int x0) {
  const DF d;
  if (n.changed.empty()) return hn::FirstN(d, hn::Lanes(d));
  // Lanes past the row's end: unchanged.
  return hn::Not(foreground_lanes(n.changed.ptr<uint8_t>(y) + x0, size_t(n.changed.cols - x0)));
}

// The neighbours' bilinear taps around each one's projection of the lanes' pixels (px, py:
// the centres of pixels x0 + i of row y; foreground ones only, and those whose surroundings
// stayed the same in the neighbour), summed into sums.
void neighbour_taps_lanes(std::span<const Neighbour> neighbours, std::span<const NeighbourPlanes> planes, int y,
                          int x0, VF depth, const Vec3L& normal, MF foreground, const TemporalSettings& s,
                          GroupSums& sums) {
  const DF d;
  const VF px = pixel_centres_lanes(d, x0), py = hn::Set(d, float(y) + 0.5f);
  const VF inverse_tolerance = hn::Div(hn::Set(d, 1.0f), hn::Mul(hn::Set(d, s.depth_tolerance_relative), depth));
  for (size_t i = 0; i < neighbours.size(); ++i) {
    const Neighbour& n = neighbours[i];
    const CarriedLanes c = carry_lanes(n.reprojection, px, py, depth, normal);
    // Texel centres around the point: floor(pixel - 0.5) and the next one, in x and y.
    const VF gx = hn::Sub(c.pixel_x, hn::Set(d, 0.5f)), gy = hn::Sub(c.pixel_y, hn::Set(d, 0.5f));
    const VF fx = hn::Floor(gx), fy = hn::Floor(gy);
    const int cols = n.frame->depth_view.cols, rows = n.frame->depth_view.rows;
    MF inside = hn::And(hn::And(foreground, unchanged_lanes(n, y, x0)), c.valid);
    inside = hn::And(inside, hn::And(hn::Ge(fx, hn::Set(d, -1.0f)), hn::Ge(fy, hn::Set(d, -1.0f))));
    inside = hn::And(inside, hn::And(hn::Lt(fx, hn::Set(d, float(cols))), hn::Lt(fy, hn::Set(d, float(rows)))));
    const VF ax = hn::IfThenElseZero(inside, hn::Sub(gx, fx)), ay = hn::IfThenElseZero(inside, hn::Sub(gy, fy));
    const DI di;
    const VI x0 = hn::ConvertTo(di, hn::IfThenElseZero(inside, fx)),
             y0 = hn::ConvertTo(di, hn::IfThenElseZero(inside, fy));
    const VI one_i = hn::Set(di, 1);
    const VF one = hn::Set(d, 1.0f);
    const VF bx[2] = {hn::Sub(one, ax), ax}, by[2] = {hn::Sub(one, ay), ay};
    for (int t = 0; t < 4; ++t)
      add_texel_lanes(planes[i], c, inside, (t & 1) ? hn::Add(x0, one_i) : x0, (t >> 1) ? hn::Add(y0, one_i) : y0,
                      hn::Mul(bx[t & 1], by[t >> 1]), inverse_tolerance, s.normal_power, cols, rows, sums);
  }
}

// The frame's pixels x = x0 + step_px i of row y, one per lane: depth, normal, and whether
// each is foreground (pixels at or past x_end and background ones: depth 1, normal 0).
struct FrameLanes {
  VF depth;
  Vec3L normal;
  MF foreground;
};
FrameLanes frame_lanes(const TemporalFrame& f, int y, int x0, int step_px, int x_end) {
  const DF d;
  const float* depth_row = f.depth_view.ptr<float>(y);
  const float* normal_row = f.normal_view.ptr<float>(y);
  const uint8_t* mask_row = f.mask.ptr<uint8_t>(y);
  HWY_ALIGN float depth[kMaxLanes], nx[kMaxLanes], ny[kMaxLanes], nz[kMaxLanes], fg[kMaxLanes];
  for (size_t i = 0; i < hn::Lanes(d); ++i) {
    const int x = x0 + step_px * int(i);
    const bool in = x < x_end && mask_row[x];
    depth[i] = in ? depth_row[x] : 1.0f;
    nx[i] = in ? normal_row[3 * x] : 0.0f;
    ny[i] = in ? normal_row[3 * x + 1] : 0.0f;
    nz[i] = in ? normal_row[3 * x + 2] : 0.0f;
    fg[i] = in ? 1.0f : 0.0f;
  }
  return {
      hn::Load(d, depth), {hn::Load(d, nx), hn::Load(d, ny), hn::Load(d, nz)}, hn::Gt(hn::Load(d, fg), hn::Zero(d))};
}

// One row of the roi: each pixel's terms filtered (temporal.h), or copied where nothing
// agrees; pixels a vector of lanes at a time (the last group's extra lanes are computed as
// background and not written).
void filter_row(const TemporalFrame& f, std::span<const Neighbour> neighbours,
                std::span<const NeighbourPlanes> planes, const TemporalSettings& s, std::span<cv::Mat* const> dsts,
                int y, int x_begin, int x_end) {
  const DF d;
  const size_t lanes = hn::Lanes(d);
  for (int x0 = x_begin; x0 < x_end; x0 += int(lanes)) {
    const int count = std::min(int(lanes), x_end - x0);
    const FrameLanes pixels = frame_lanes(f, y, x0, 1, x_end);
    GroupSums sums(hn::Zero(d));
    for (auto& channel : sums.channel) hn::Store(hn::Zero(d), d, channel);
    neighbour_taps_lanes(neighbours, planes, y, x0, pixels.depth, pixels.normal, pixels.foreground, s, sums);
    HWY_ALIGN float total[kMaxLanes];
    hn::Store(sums.total, d, total);
    int k = 0;
    for (size_t t = 0; t < f.terms.size(); ++t) {
      const int channels = f.terms[t]->channels();
      const float* src = f.terms[t]->ptr<float>(y);
      float* dst = dsts[t]->ptr<float>(y);
      for (int c = 0; c < channels; ++c, ++k)
        for (int i = 0; i < count; ++i) {
          const int at = channels * (x0 + i) + c;
          dst[at] = total[i] > 0.0f ? (src[at] + sums.channel[k][i]) / (1.0f + total[i]) : src[at];
        }
    }
  }
}

// Counts of measure_neighbour over pixels x = x0 + kMeasureStridePx i (i: the lanes) of row
// y: the frame's foreground pixels, those that project into the neighbour, and those whose
// nearest texel there has no weight (background, or the plane or normal test fails).
struct MeasureCounts {
  int64_t foreground = 0, seen = 0, disagree = 0;
};
void measure_lanes(const TemporalFrame& f, const Neighbour& n, const NeighbourPlanes& u, const TemporalSettings& s,
                   int y, int x0, MeasureCounts& counts) {
  const DF d;
  const DI di;
  const FrameLanes pixels = frame_lanes(f, y, x0, kMeasureStridePx, f.depth_view.cols);
  const VF px = pixel_centres_lanes(d, x0, kMeasureStridePx);
  const VF depth_v = pixels.depth;
  const MF foreground = pixels.foreground;
  const CarriedLanes c = carry_lanes(n.reprojection, px, hn::Set(d, float(y) + 0.5f), depth_v, pixels.normal);
  const int cols = n.frame->depth_view.cols, rows = n.frame->depth_view.rows;
  MF seen = hn::And(foreground, c.valid);
  seen = hn::And(seen, hn::And(hn::Ge(c.pixel_x, hn::Zero(d)), hn::Ge(c.pixel_y, hn::Zero(d))));
  seen = hn::And(seen, hn::And(hn::Lt(c.pixel_x, hn::Set(d, float(cols))), hn::Lt(c.pixel_y, hn::Set(d, float(rows)))));
  // The texel holding the point (truncation is the floor: the coordinates are >= 0).
  const VI tx = hn::ConvertTo(di, hn::IfThenElseZero(seen, c.pixel_x));
  const VI ty = hn::ConvertTo(di, hn::IfThenElseZero(seen, c.pixel_y));
  const VF inverse_tolerance = hn::Div(hn::Set(d, 1.0f), hn::Mul(hn::Set(d, s.depth_tolerance_relative), depth_v));
  MF ok;
  VI sx, sy;
  texel_weight_lanes(u, c, seen, tx, ty, hn::Set(d, 1.0f), inverse_tolerance, s.normal_power, cols, rows, ok, sx, sy);
  counts.foreground += int64_t(hn::CountTrue(d, foreground));
  counts.seen += int64_t(hn::CountTrue(d, seen));
  counts.disagree += int64_t(hn::CountTrue(d, hn::AndNot(ok, seen)));
}

// Per neighbour, over every kMeasureStridePx-th pixel of every kMeasureStridePx-th row of
// the frame's foreground: the points that project into it and those whose nearest texel
// holds another surface (background, or the plane or normal test fails). Integer counts:
// the same for any split of the rows.
void measure_neighbour(const TemporalFrame& f, const Neighbour& n, const NeighbourPlanes& planes,
                       const TemporalSettings& s, TemporalUse& use, int nthreads) {
  std::atomic<int64_t> foreground{0}, seen{0}, disagree{0};
  const int measured_rows = (f.depth_view.rows + kMeasureStridePx - 1) / kMeasureStridePx;
  const int group_px = kMeasureStridePx * int(hn::Lanes(DF()));
  parallel_rows(cv::Range(0, measured_rows), nthreads, [&](const cv::Range& rows) {
    MeasureCounts strip;
    for (int y = rows.start * kMeasureStridePx; y < rows.end * kMeasureStridePx && y < f.depth_view.rows;
         y += kMeasureStridePx)
      for (int x0 = 0; x0 < f.depth_view.cols; x0 += group_px) measure_lanes(f, n, planes, s, y, x0, strip);
    foreground += strip.foreground, seen += strip.seen, disagree += strip.disagree;
  });
  use.overlap = foreground > 0 ? float(double(seen) / double(foreground)) : 0.0f;
  use.disagreement = seen > 0 ? float(double(disagree) / double(seen)) : 0.0f;
  use.used = seen > 0 && use.disagreement <= s.max_disagreement;
}

bool same_layout(const TemporalFrame& f, const TemporalFrame& u) {
  if (u.terms.size() != f.terms.size() || u.depth_view.size() != u.mask.size() ||
      u.normal_view.size() != u.depth_view.size())
    return false;
  for (size_t i = 0; i < f.terms.size(); ++i)
    if (u.terms[i]->type() != f.terms[i]->type() || u.terms[i]->size() != u.depth_view.size()) return false;
  return true;
}

}  // namespace

std::vector<TemporalUse> filter_temporal(const TemporalFrame& frame, std::span<const TemporalFrame> neighbours,
                                         const TemporalSettings& settings, std::span<cv::Mat* const> dsts,
                                         cv::Rect roi, int nthreads) {
  CV_Assert(ssdo::validate(settings).empty());
  CV_Assert(dsts.size() == frame.terms.size());
  int channels = 0;
  for (size_t i = 0; i < frame.terms.size(); ++i) {
    const cv::Mat& src = *frame.terms[i];
    CV_Assert(src.depth() == CV_32F && src.size() == frame.depth_view.size());
    CV_Assert(dsts[i]->data == nullptr || dsts[i]->data != src.data);
    dsts[i]->create(src.size(), src.type());
    channels += src.channels();
  }
  CV_Assert(channels <= kMaxChannels);
  std::vector<TemporalUse> uses(neighbours.size());
  std::vector<Neighbour> used;
  std::vector<NeighbourPlanes> planes;
  for (size_t i = 0; i < neighbours.size(); ++i) {
    CV_Assert(same_layout(frame, neighbours[i]));
    Neighbour n{&neighbours[i], Reprojection(frame.camera, neighbours[i].camera), {}};
    NeighbourPlanes p = planes_of(neighbours[i], nthreads);
    measure_neighbour(frame, n, p, settings, uses[i], nthreads);
    if (!uses[i].used) continue;
    if (settings.reject_changed_surroundings) {
      n.changed = changed_surroundings(frame, neighbours[i], settings, uses[i].changed_px, nthreads);
    }
    used.push_back(std::move(n));
    planes.push_back(std::move(p));
  }
  const cv::Rect r = resolve_roi(roi, frame.depth_view.size());
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) filter_row(frame, used, planes, settings, dsts, y, r.x, r.x + r.width);
  });
  return uses;
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

// Settings, not pixels: compiled once, outside the per-target code.
std::string validate(const TemporalSettings& s) {
  if (!(s.depth_tolerance_relative > 0.0f && s.depth_tolerance_relative <= 1.0f))
    return detail::out_of_range("depth_tolerance_relative", s.depth_tolerance_relative, "(0, 1]");
  if (!(s.normal_power >= 0.0f && s.normal_power <= 256.0f))
    return detail::out_of_range("normal_power", s.normal_power, "[0, 256]");
  if (!(s.max_disagreement >= 0.0f && s.max_disagreement <= 1.0f))
    return detail::out_of_range("max_disagreement", s.max_disagreement, "[0, 1]");
  return detail::check_radius(s.radius_world, s.max_radius_px);
}


HWY_EXPORT(filter_temporal);
std::vector<TemporalUse> filter_temporal(const TemporalFrame& frame, std::span<const TemporalFrame> neighbours,
                                         const TemporalSettings& settings, std::span<cv::Mat* const> dsts, cv::Rect roi,
                                         int nthreads) {
  return HWY_DYNAMIC_DISPATCH(filter_temporal)(frame, neighbours, settings, dsts, roi, nthreads);
}

}  // namespace ssdo
#endif  // HWY_ONCE
