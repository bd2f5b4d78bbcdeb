// The per-pixel passes of the multi-view occupancy (kernels/multiview.h), several pixels per
// instruction: a view's verdict on points of many rays at once, the walk along each
// pixel's ray to the end of its occluder, and the decided bins behind each surface. Every
// lane runs the operations a pixel alone runs, in the same order (no fused multiply-add:
// cmake/compute_flags.cmake), so the lanes change the speed, not the bits.
#include "kernels/multiview_rays.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/multiview_lanes.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <algorithm>
#include <vector>

#include "core/parallel.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;
using multiview_detail::Constants;
using multiview_detail::kInfinity;
using multiview_detail::ViewGeometry;

// Pixels walked together: the foreground pixels of a row, kGroup at a time, in as many
// vectors as the instruction set needs (one on AVX2).
constexpr int kGroup = 8;
using GroupTag = hn::CappedTag<float, kGroup>;

// The rays of a group of pixels in one view, [component][pixel]: clip = clip0 + d clip1 and
// planar depth depth0 + d depth1 at planar depth d in this frame (the ray's points are affine
// in d, and so are their clip coordinates and depth in the view).
struct RayLanes {
  alignas(32) float clip0[4][kGroup], clip1[4][kGroup];
  alignas(32) float depth0[kGroup], depth1[kGroup];
};

// The rays of lanes [j0, j0 + Lanes(d)) of a group in one view, as vectors.
template <class D>
struct RayVectors {
  hn::Vec<D> clip0[4], clip1[4], depth0, depth1;
};

// Built whole, never default-constructed (structs of Highway vectors on Arm:
// docs/architecture.md).
template <class D>
HWY_INLINE RayVectors<D> ray_vectors(D d, const RayLanes& r, size_t j0) {
  const auto load = [&](const float* p) { return hn::Load(d, p + j0); };
  return {{load(r.clip0[0]), load(r.clip0[1]), load(r.clip0[2]), load(r.clip0[3])},
          {load(r.clip1[0]), load(r.clip1[1]), load(r.clip1[2]), load(r.clip1[3])},
          load(r.depth0),
          load(r.depth1)};
}

// A view's verdict on the points at planar depth `depth` of the rays (multiview.h): `free`
// where it sees free space in front of the point, `occupied` where it has the point behind
// its surface within the thickness; neither where the point is outside its image, behind its
// eye (unknown) or farther behind the surface (beyond). Returns where the points are inside
// the view's image (known).
//
// Conservative free-space test: a view's depth is a sample at each pixel centre, and a point
// on a surface seen at a grazing angle may lie in front of the sample nearest to it. The
// test compares with the smallest depth of the 2x2 pixel centres around the projected point,
// clamped at the image's edges, less a relative bias for the depth's rounding; occupancy is
// measured from the nearest pixel's depth.
template <class D>
HWY_INLINE hn::Mask<D> classify_lanes(D d, const ViewGeometry& v, const RayVectors<D>& r, hn::Vec<D> depth,
                               float bias_relative, float thickness, hn::Mask<D>& free, hn::Mask<D>& occupied) {
  const hn::RebindToSigned<D> di;
  hn::Vec<D> clip[4];
  for (int c = 0; c < 4; ++c) clip[c] = hn::Add(r.clip0[c], hn::Mul(depth, r.clip1[c]));
  const auto zero = hn::Zero(d), one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
  const auto width = hn::Set(d, v.width_px), height = hn::Set(d, v.height_px);
  const auto inv_w = hn::Div(one, clip[3]);
  const auto px = hn::Mul(hn::Mul(half, hn::Add(hn::Mul(clip[0], inv_w), one)), width);
  const auto py = hn::Mul(hn::Mul(half, hn::Sub(one, hn::Mul(clip[1], inv_w))), height);
  // False on NaN, as the comparisons of a pixel alone.
  const auto inside = hn::And(hn::And(hn::Gt(clip[3], zero), hn::And(hn::Ge(px, zero), hn::Lt(px, width))),
                              hn::And(hn::Ge(py, zero), hn::Lt(py, height)));
  // Lanes outside read pixel (0, 0): their verdict is neither.
  const auto x = hn::IfThenElseZero(inside, px), y = hn::IfThenElseZero(inside, py);
  const cv::Mat& image = *v.depth_view;
  const auto max_x = hn::Set(di, image.cols - 1), max_y = hn::Set(di, image.rows - 1), one_i = hn::Set(di, 1);
  // The 2x2 pixel centres around (x, y) (x - 0.5 >= -0.5: truncation is the floor wherever
  // the clamp does not apply), and the nearest pixel.
  const auto x0 = hn::Min(hn::ConvertTo(di, hn::Sub(x, half)), max_x), x1 = hn::Min(hn::Add(x0, one_i), max_x);
  const auto y0 = hn::Min(hn::ConvertTo(di, hn::Sub(y, half)), max_y), y1 = hn::Min(hn::Add(y0, one_i), max_y);
  const auto xn = hn::Min(hn::ConvertTo(di, x), max_x), yn = hn::Min(hn::ConvertTo(di, y), max_y);
  const auto row_floats = hn::Set(di, int(image.step1()));
  const auto row0 = hn::Mul(y0, row_floats), row1 = hn::Mul(y1, row_floats);
  const float* base = image.ptr<float>();
  const auto nearest_surface = hn::GatherIndex(d, base, hn::Add(hn::Mul(yn, row_floats), xn));
  const auto min_surface = hn::Min(
      hn::Min(hn::GatherIndex(d, base, hn::Add(row0, x0)), hn::GatherIndex(d, base, hn::Add(row0, x1))),
      hn::Min(hn::GatherIndex(d, base, hn::Add(row1, x0)), hn::GatherIndex(d, base, hn::Add(row1, x1))));
  const auto depth_q = hn::Add(r.depth0, hn::Mul(depth, r.depth1));
  // +inf (background) at all four: the view sees through to the sky there.
  free = hn::And(inside, hn::Lt(depth_q, hn::Mul(min_surface, hn::Set(d, 1.0f - bias_relative))));
  const auto behind = hn::And(hn::Gt(depth_q, nearest_surface),
                              hn::Le(hn::Sub(depth_q, nearest_surface), hn::Set(d, thickness)));
  occupied = hn::AndNot(free, hn::And(inside, behind));
  return inside;
}

// The pixels of a group: their columns in one row, and their rays in every view.
struct Group {
  int y = 0, n = 0;  // n <= kGroup pixels; the other lanes repeat the last
  alignas(32) int x[kGroup];
  alignas(32) float front[kGroup], own_back[kGroup];
  std::vector<RayLanes> rays;  // per view
  // Per view, 1 in the lanes whose surface it does not see as free space (its verdicts count
  // there), else 0.
  std::vector<float> active;
};

// A matrix row times (v0, v1, v2, v3) in the order glm's mat4 x vec4 and dot() add:
// (r0 v0 + r1 v1) + (r2 v2 + r3 v3).
template <class D>
HWY_INLINE hn::Vec<D> dot4(D d, const float (&row)[4], hn::Vec<D> v0, hn::Vec<D> v1, hn::Vec<D> v2, hn::Vec<D> v3) {
  return hn::Add(hn::Add(hn::Mul(hn::Set(d, row[0]), v0), hn::Mul(hn::Set(d, row[1]), v1)),
                 hn::Add(hn::Mul(hn::Set(d, row[2]), v2), hn::Mul(hn::Set(d, row[3]), v3)));
}

// Fills the rays of the group's pixels in every view (lanes past n repeat the last pixel):
// pixel (x, y)'s ray through its centre, p(d) = a + d b (PixelRays), taken into each view as
// clip_from_frame_view (a, 1) and (b, 0), in the order glm's mat4 x vec4 and dot() add.
void set_up_rays(const Constants& k, const PixelRays& rays, Group& g) {
  const GroupTag d;
  const hn::RebindToSigned<GroupTag> di;
  for (int j = g.n; j < kGroup; ++j) g.x[j] = g.x[g.n - 1];
  const auto half = hn::Set(d, 0.5f), one = hn::Set(d, 1.0f), zero = hn::Zero(d);
  const auto py = hn::Add(hn::Set(d, float(g.y)), half);
  for (size_t j0 = 0; j0 < size_t(kGroup); j0 += hn::Lanes(d)) {
    const auto px = hn::Add(hn::ConvertTo(d, hn::Load(di, g.x + j0)), half);
    // The ray's points are affine in planar depth: p(d) = a + d b (PixelRays).
    hn::Vec<GroupTag> a[3], b[3];
    for (int c = 0; c < 3; ++c) {
      a[c] = hn::Add(hn::Add(hn::Set(d, rays.o0[c]), hn::Mul(px, hn::Set(d, rays.ox[c]))),
                     hn::Mul(py, hn::Set(d, rays.oy[c])));
      b[c] = hn::Add(hn::Add(hn::Set(d, rays.u0[c]), hn::Mul(px, hn::Set(d, rays.ux[c]))),
                     hn::Mul(py, hn::Set(d, rays.uy[c])));
    }
    for (size_t v = 0; v < k.views.size(); ++v) {
      const glm::mat4& m = k.views[v].clip_from_frame_view;
      RayLanes& lanes = g.rays[v];
      for (int c = 0; c < 4; ++c) {
        const float row[4] = {m[0][c], m[1][c], m[2][c], m[3][c]};
        hn::Store(dot4(d, row, a[0], a[1], a[2], one), d, lanes.clip0[c] + j0);
        hn::Store(dot4(d, row, b[0], b[1], b[2], zero), d, lanes.clip1[c] + j0);
      }
      const glm::vec4& r = k.views[v].depth_from_frame_view;
      const float row[4] = {r.x, r.y, r.z, r.w};
      hn::Store(dot4(d, row, a[0], a[1], a[2], one), d, lanes.depth0 + j0);
      hn::Store(dot4(d, row, b[0], b[1], b[2], zero), d, lanes.depth1 + j0);
    }
  }
}

// Occupancy of the points at planar depth `depth` on the lanes' rays (the rule in
// multiview.h, by the active views, and the frame's own interval up to own_back);
// `informed` where some view had a say (a view sees free space, or beyond own_back some
// view has the point occupied).
template <class D>
HWY_INLINE hn::Mask<D> occupied_lanes(D d, const Constants& k, const Group& g, size_t j0, hn::Vec<D> depth,
                                      hn::Vec<D> own_back, hn::Mask<D>& informed) {
  auto free_any = hn::Lt(hn::Zero(d), hn::Zero(d)), occupied_any = free_any;  // all false
  for (size_t v = 0; v < k.views.size(); ++v) {
    hn::Mask<D> free, occupied;
    classify_lanes(d, k.views[v], ray_vectors(d, g.rays[v], j0), depth, k.s.depth_bias_relative,
                   k.s.thickness_world, free, occupied);
    const auto active = hn::Ne(hn::LoadU(d, g.active.data() + v * kGroup + j0), hn::Zero(d));
    free_any = hn::Or(free_any, hn::And(active, free));
    occupied_any = hn::Or(occupied_any, hn::And(active, occupied));
  }
  const auto within_own = hn::Le(depth, own_back);
  informed = hn::Or(free_any, hn::AndNot(within_own, occupied_any));
  return hn::AndNot(free_any, hn::Or(within_own, occupied_any));
}

// The back depth of lanes [j0, j0 + Lanes(d)) of the group: walking each ray from its
// visible surface at `front` to front + reach_world, the depth of the first change from
// occupied to free, refined by bisection; +inf when occupied throughout; own_back when no
// view had a say.
template <class D>
HWY_INLINE hn::Vec<D> back_depth_lanes(D d, const Constants& k, const Group& g, size_t j0) {
  const auto front = hn::Load(d, g.front + j0), own_back = hn::Load(d, g.own_back + j0);
  const auto infinity = hn::Set(d, kInfinity), half = hn::Set(d, 0.5f);
  auto lo = front, hi = infinity;
  auto informed = hn::Lt(hn::Zero(d), hn::Zero(d));  // all false
  auto walking = hn::Eq(front, front);                // every lane (fronts are finite)
  const int n = k.s.samples;
  for (int i = 1; i <= n; ++i) {
    const auto depth = hn::Add(front, hn::Set(d, k.s.reach_world * float(i) / float(n)));
    hn::Mask<D> informed_here;
    const auto occupied = occupied_lanes(d, k, g, j0, depth, own_back, informed_here);
    informed = hn::Or(informed, hn::And(walking, informed_here));
    hi = hn::IfThenElse(hn::AndNot(occupied, walking), depth, hi);  // the walk ends here
    walking = hn::And(walking, occupied);
    lo = hn::IfThenElse(walking, depth, lo);
    if (hn::AllFalse(d, walking)) break;
  }
  const auto ended = hn::Lt(hi, infinity);
  if (!hn::AllFalse(d, hn::And(informed, ended))) {
    for (int j = 0; j < k.s.refinements; ++j) {
      const auto mid = hn::Mul(half, hn::Add(lo, hi));
      hn::Mask<D> unused;
      const auto occupied = occupied_lanes(d, k, g, j0, mid, own_back, unused);
      lo = hn::IfThenElse(occupied, mid, lo);
      hi = hn::IfThenElse(occupied, hi, mid);
    }
  }
  return hn::IfThenElse(informed, hn::IfThenElse(ended, hn::Mul(half, hn::Add(lo, hi)), infinity), own_back);
}

// Which views speak for each lane of the group (Group::active): a view that sees a pixel's
// own surface as free space disagrees with this frame there (an object that moved), so it
// has no say on that pixel's ray.
void set_up_active_views(const Constants& k, Group& g) {
  const GroupTag d;
  for (size_t j0 = 0; j0 < size_t(kGroup); j0 += hn::Lanes(d)) {
    const auto front = hn::Load(d, g.front + j0);
    for (size_t v = 0; v < k.views.size(); ++v) {
      hn::Mask<GroupTag> free, occupied;
      classify_lanes(d, k.views[v], ray_vectors(d, g.rays[v], j0), front, k.s.depth_bias_relative,
                     k.s.thickness_world, free, occupied);
      hn::StoreU(hn::IfThenZeroElse(free, hn::Set(d, 1.0f)), d, g.active.data() + v * kGroup + j0);
    }
  }
}

// The foreground pixels of every stride_px-th column of row y, kGroup at a time: `visit` gets
// each group with its rays.
template <class Visit>
void for_each_group(const MultiViewInputs& in, const Constants& k, const PixelRays& rays, int y, int stride_px,
                    Group& g, const Visit& visit) {
  const float* depth_row = in.depth_view.ptr<float>(y);
  const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
  g.y = y;
  g.n = 0;
  for (int x = 0; x < in.depth_view.cols; x += stride_px) {
    if (!mask_row[x] || !(depth_row[x] > 0.0f && std::isfinite(depth_row[x]))) continue;
    g.x[g.n++] = x;
    if (g.n == kGroup) {
      set_up_rays(k, rays, g);
      visit(g);
      g.n = 0;
    }
  }
  if (g.n > 0) {
    set_up_rays(k, rays, g);
    visit(g);
  }
}

Group make_group(const Constants& k) {
  Group g;
  g.rays.resize(k.views.size());
  g.active.resize(k.views.size() * kGroup);
  return g;
}

}  // namespace

void write_back_layer(const MultiViewInputs& in, const Constants& k, cv::Mat& back, int nthreads) {
  back.create(in.depth_view.size(), CV_32FC1);
  const PixelRays rays = pixel_rays(in.camera);
  parallel_rows(cv::Range(0, in.depth_view.rows), nthreads, [&](const cv::Range& range) {
    Group g = make_group(k);
    const GroupTag d;
    for (int y = range.start; y < range.end; ++y) {
      float* back_row = back.ptr<float>(y);
      std::fill(back_row, back_row + back.cols, kInfinity);  // background; foreground below
      for_each_group(in, k, rays, y, 1, g, [&](Group& group) {
        for (int j = 0; j < kGroup; ++j) {
          const int x = group.x[std::min(j, group.n - 1)];
          group.front[j] = in.depth_view.ptr<float>(y)[x];
          group.own_back[j] = multiview_detail::own_back_depth(in, k.s, x, y, group.front[j]);
        }
        set_up_active_views(k, group);
        alignas(32) float depths[kGroup];
        for (size_t j0 = 0; j0 < size_t(kGroup); j0 += hn::Lanes(d))
          hn::Store(back_depth_lanes(d, k, group, j0), d, depths + j0);
        for (int j = 0; j < group.n; ++j) back_row[group.x[j]] = depths[j];
      });
    }
  });
}

void write_decided_bins(const MultiViewInputs& in, const Constants& k, float surface_scale, float bin_depth, int bins,
                        cv::Mat& decided, int nthreads) {
  const PixelRays rays = pixel_rays(in.camera);
  parallel_rows(cv::Range(0, in.depth_view.rows), nthreads, [&](const cv::Range& range) {
    Group g = make_group(k);
    const GroupTag d;
    const hn::RebindToSigned<GroupTag> di;
    for (int y = range.start; y < range.end; ++y) {
      uint8_t* out = decided.ptr<uint8_t>(y);
      for_each_group(in, k, rays, y, 1, g, [&](Group& group) {
        alignas(32) int32_t bits[kGroup];
        for (int j = 0; j < kGroup; ++j)
          group.front[j] = in.depth_view.ptr<float>(y)[group.x[std::min(j, group.n - 1)]];
        for (size_t j0 = 0; j0 < size_t(kGroup); j0 += hn::Lanes(d)) {
          const auto surface = hn::Mul(hn::Load(d, group.front + j0), hn::Set(d, surface_scale));
          auto lane_bits = hn::Zero(di);
          for (int i = 0; i < bins; ++i) {
            // Some view sees the bin's centre as free space or has it behind its surface.
            const auto depth = hn::Add(surface, hn::Set(d, (float(i) + 0.5f) * bin_depth));
            auto decides = hn::Lt(hn::Zero(d), hn::Zero(d));  // all false
            for (size_t v = 0; v < k.views.size() && !hn::AllTrue(d, decides); ++v) {
              hn::Mask<GroupTag> free, occupied;
              classify_lanes(d, k.views[v], ray_vectors(d, group.rays[v], j0), depth, k.s.depth_bias_relative,
                             k.s.thickness_world, free, occupied);
              decides = hn::Or(decides, hn::Or(free, occupied));
            }
            lane_bits = hn::Or(lane_bits, hn::IfThenElseZero(hn::RebindMask(di, decides), hn::Set(di, 1 << i)));
          }
          hn::Store(lane_bits, di, bits + j0);
        }
        for (int j = 0; j < group.n; ++j) out[group.x[j]] = uint8_t(bits[j]);
      });
    }
  });
}

void decide_points(const Constants& k, std::span<const glm::vec3> points_view, std::span<uint8_t> decided) {
  const GroupTag d;
  RayLanes ray;  // one view's at a time
  alignas(32) float decided_lanes[kGroup];
  for (size_t p0 = 0; p0 < points_view.size(); p0 += kGroup) {
    const size_t n = std::min(points_view.size() - p0, size_t(kGroup));
    std::fill(decided_lanes, decided_lanes + kGroup, 0.0f);
    for (size_t v = 0; v < k.views.size(); ++v) {
      // Each point as a ray of zero direction, read at d = 0 (lanes past n repeat the last).
      for (int j = 0; j < kGroup; ++j) {
        const glm::vec4 q(points_view[p0 + std::min(size_t(j), n - 1)], 1.0f);
        const glm::vec4 clip = k.views[v].clip_from_frame_view * q;
        for (int c = 0; c < 4; ++c) {
          ray.clip0[c][j] = clip[c];
          ray.clip1[c][j] = 0.0f;
        }
        ray.depth0[j] = glm::dot(k.views[v].depth_from_frame_view, q);
        ray.depth1[j] = 0.0f;
      }
      bool all_decided = true;
      for (size_t j0 = 0; j0 < size_t(kGroup); j0 += hn::Lanes(d)) {
        const auto before = hn::Ne(hn::Load(d, decided_lanes + j0), hn::Zero(d));
        if (hn::AllTrue(d, before)) continue;
        hn::Mask<GroupTag> free, occupied;
        classify_lanes(d, k.views[v], ray_vectors(d, ray, j0), hn::Zero(d), k.s.depth_bias_relative,
                       k.s.thickness_world, free, occupied);
        const auto now = hn::Or(before, hn::Or(free, occupied));
        hn::Store(hn::IfThenElseZero(now, hn::Set(d, 1.0f)), d, decided_lanes + j0);
        all_decided = all_decided && hn::AllTrue(d, now);
      }
      if (all_decided) break;  // no later view changes a decided point
    }
    for (size_t j = 0; j < n; ++j) decided[p0 + j] = decided_lanes[j] != 0.0f;
  }
}

void count_view_verdicts(const MultiViewInputs& in, const Constants& k, int stride_px, std::span<int64_t> seen,
                         std::span<int64_t> contradicted, int nthreads) {
  const PixelRays rays = pixel_rays(in.camera);
  const size_t nv = k.views.size();
  const int measured_rows = (in.depth_view.rows + stride_px - 1) / stride_px;
  parallel_rows(cv::Range(0, measured_rows), nthreads, [&](const cv::Range& range) {
    Group g = make_group(k);
    const GroupTag d;
    for (int y = range.start * stride_px; y < range.end * stride_px && y < in.depth_view.rows; y += stride_px) {
      for_each_group(in, k, rays, y, stride_px, g, [&](Group& group) {
        for (int j = 0; j < kGroup; ++j)
          group.front[j] = in.depth_view.ptr<float>(y)[group.x[std::min(j, group.n - 1)]];
        for (size_t j0 = 0; j0 < size_t(group.n); j0 += hn::Lanes(d)) {
          const auto pixels = hn::FirstN(d, size_t(group.n) - j0);  // not the repeated lanes
          for (size_t v = 0; v < nv; ++v) {
            hn::Mask<GroupTag> free, occupied;
            const auto known =
                classify_lanes(d, k.views[v], ray_vectors(d, group.rays[v], j0), hn::Load(d, group.front + j0),
                               k.s.depth_bias_relative, k.s.thickness_world, free, occupied);
            seen[size_t(y) * nv + v] += int64_t(hn::CountTrue(d, hn::And(pixels, known)));
            contradicted[size_t(y) * nv + v] += int64_t(hn::CountTrue(d, hn::And(pixels, free)));
          }
        }
      });
    }
  });
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo::multiview_detail {

HWY_EXPORT(write_back_layer);
HWY_EXPORT(write_decided_bins);
HWY_EXPORT(count_view_verdicts);
HWY_EXPORT(decide_points);

void decide_points(const Constants& k, std::span<const glm::vec3> points_view, std::span<uint8_t> decided) {
  HWY_DYNAMIC_DISPATCH(decide_points)(k, points_view, decided);
}

void write_back_layer(const MultiViewInputs& in, const Constants& k, cv::Mat& back, int nthreads) {
  HWY_DYNAMIC_DISPATCH(write_back_layer)(in, k, back, nthreads);
}

void write_decided_bins(const MultiViewInputs& in, const Constants& k, float surface_scale, float bin_depth, int bins,
                        cv::Mat& decided, int nthreads) {
  HWY_DYNAMIC_DISPATCH(write_decided_bins)(in, k, surface_scale, bin_depth, bins, decided, nthreads);
}

void count_view_verdicts(const MultiViewInputs& in, const Constants& k, int stride_px, std::span<int64_t> seen,
                         std::span<int64_t> contradicted, int nthreads) {
  HWY_DYNAMIC_DISPATCH(count_view_verdicts)(in, k, stride_px, seen, contradicted, nthreads);
}

}  // namespace ssdo::multiview_detail
#endif  // HWY_ONCE
