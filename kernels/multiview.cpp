#include "kernels/multiview.h"
#include "kernels/multiview_rays.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

#include "core/parallel.h"
#include "kernels/settings_check.h"

namespace ssdo {
namespace {

using multiview_detail::Constants;
using multiview_detail::kInfinity;
using multiview_detail::ViewGeometry;
using multiview_detail::view_geometry;
using multiview_detail::views_from;

// The views' overlap and contradiction are measured on every 4th pixel of every 4th row.
constexpr int kMeasureStridePx = 4;

// Per view, over this frame's foreground surface points (every kMeasureStridePx-th pixel of
// every kMeasureStridePx-th row: a fraction needs no more): how many it can see, and how
// many of those it sees free space in front of (counts per row, summed in row order).
void measure_views(const MultiViewInputs& in, const Constants& k, std::vector<ViewUse>& uses, int nthreads) {
  const int rows = in.depth_view.rows, nv = int(k.views.size());
  std::vector<int64_t> seen(size_t(rows) * size_t(nv), 0), contradicted(seen.size(), 0);
  multiview_detail::count_view_verdicts(in, k, kMeasureStridePx, seen, contradicted, nthreads);
  int64_t foreground = 0;
  for (int y = 0; y < rows; y += kMeasureStridePx) {
    const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
    for (int x = 0; x < in.depth_view.cols; x += kMeasureStridePx) foreground += mask_row[x] != 0;
  }
  foreground = std::max<int64_t>(1, foreground);
  for (int i = 0; i < nv; ++i) {
    int64_t s = 0, c = 0;
    for (int y = 0; y < rows; ++y) {
      s += seen[size_t(y) * size_t(nv) + size_t(i)];
      c += contradicted[size_t(y) * size_t(nv) + size_t(i)];
    }
    uses[size_t(i)].overlap = float(double(s) / double(foreground));
    uses[size_t(i)].contradiction = s > 0 ? float(double(c) / double(s)) : 0.0f;
    uses[size_t(i)].used = s > 0 && uses[size_t(i)].contradiction <= k.s.max_contradiction;
  }
}

}  // namespace

std::string validate(const MultiViewSettings& s) {
  using detail::out_of_range;
  if (!(s.thickness_world > 0.0f && std::isfinite(s.thickness_world)))
    return out_of_range("thickness_world", s.thickness_world, "(0, inf)");
  if (!(s.reach_world > 0.0f && std::isfinite(s.reach_world)))
    return out_of_range("reach_world", s.reach_world, "(0, inf)");
  if (!(s.depth_bias_relative >= 0.0f && s.depth_bias_relative <= 0.1f))
    return out_of_range("depth_bias_relative", s.depth_bias_relative, "[0, 0.1]");
  if (s.samples < 2 || s.samples > 64) return out_of_range("samples", float(s.samples), "[2, 64]");
  if (s.refinements < 0 || s.refinements > 16) return out_of_range("refinements", float(s.refinements), "[0, 16]");
  if (!(s.max_contradiction >= 0.0f && s.max_contradiction <= 1.0f))
    return out_of_range("max_contradiction", s.max_contradiction, "[0, 1]");
  return {};
}

std::vector<ViewUse> occupancy_from_views(const MultiViewInputs& in, std::span<const DepthView> views,
                                          const MultiViewSettings& s, cv::Mat& depth_back_view, int nthreads) {
  const std::vector<ViewUse> uses = measure_view_use(in, views, s, nthreads);
  depth_back_view.release();
  const Constants used = views_from(in.camera, views, s, uses);
  if (!used.views.empty()) multiview_detail::write_back_layer(in, used, depth_back_view, nthreads);
  return uses;
}

namespace {

// One texel per factor x factor block of v: the block's nearest depth (NaN never wins).
DepthView coarsened_view(const DepthView& v, int factor, int nthreads) {
  DepthView coarse{v.camera, {}, v.name};
  const cv::Size size((v.depth_view.cols + factor - 1) / factor, (v.depth_view.rows + factor - 1) / factor);
  coarse.camera.width_px = size.width;
  coarse.camera.height_px = size.height;
  coarse.depth_view.create(size, CV_32FC1);
  parallel_rows(cv::Range(0, size.height), nthreads, [&](const cv::Range& rows) {
    for (int j = rows.start; j < rows.end; ++j) {
      float* out = coarse.depth_view.ptr<float>(j);
      std::fill(out, out + size.width, kInfinity);
      for (int y = j * factor; y < std::min((j + 1) * factor, v.depth_view.rows); ++y) {
        const float* row = v.depth_view.ptr<float>(y);
        for (int i = 0; i < size.width; ++i) {
          float nearest = out[i];
          for (int x = i * factor; x < std::min((i + 1) * factor, v.depth_view.cols); ++x)
            nearest = row[x] < nearest ? row[x] : nearest;
          out[i] = nearest;
        }
      }
    }
  });
  return coarse;
}

}  // namespace

std::vector<DepthView> views_at_density(std::span<const DepthView> views, int grid_width_px, int nthreads) {
  std::vector<DepthView> dense;
  for (const DepthView& v : views) {
    const int factor = int(std::lround(double(v.depth_view.cols) / double(std::max(1, grid_width_px))));
    dense.push_back(factor >= 2 ? coarsened_view(v, factor, nthreads) : v);
  }
  return dense;
}

// ---- The guard band ----

namespace {

// The reach past the edges of the pixels of rows [range): per row, the largest
// (projected radius - distance to an edge) over its foreground pixels.
void band_reach_of_rows(const cv::Mat& depth_view, const cv::Mat& mask, const Camera& camera, float radius_world,
                        float max_radius_px, const cv::Range& range, float* reach_per_row) {
  const float w = float(depth_view.cols), h = float(depth_view.rows);
  for (int y = range.start; y < range.end; ++y) {
    const float* depth_row = depth_view.ptr<float>(y);
    const uint8_t* mask_row = mask.ptr<uint8_t>(y);
    const float to_edge_y = std::min(float(y) + 0.5f, h - float(y) - 0.5f);
    float reach = 0.0f;
    for (int x = 0; x < depth_view.cols; ++x) {
      if (!mask_row[x] || !(depth_row[x] > 0.0f && std::isfinite(depth_row[x]))) continue;
      const glm::vec2 radius_px =
          glm::min(glm::vec2(max_radius_px), radius_world * camera.pixels_per_unit(depth_row[x]));
      const float to_edge_x = std::min(float(x) + 0.5f, w - float(x) - 0.5f);
      reach = std::max({reach, radius_px.x - to_edge_x, radius_px.y - to_edge_y});
    }
    reach_per_row[y] = reach;
  }
}

// Keeps the smaller of `slot` and `value`, whatever other threads write to it.
inline void atomic_min(uint64_t& slot, uint64_t value) {
  std::atomic_ref<uint64_t> a(slot);
  uint64_t current = a.load(std::memory_order_relaxed);
  while (value < current && !a.compare_exchange_weak(current, value, std::memory_order_relaxed)) {
  }
}

// A surface splatted into the band: its planar depth in this frame in the high half (a
// positive float's bits order as the float), the view pixel it came from in the low half
// (BandSources), so that the minimum is the nearest surface, ties going to the first view
// and pixel.
constexpr uint64_t kNoSurface = ~uint64_t(0);
inline uint64_t band_key(float depth_view, uint32_t source) {
  return (uint64_t(std::bit_cast<uint32_t>(depth_view)) << 32) | source;
}
inline float key_depth(uint64_t key) { return std::bit_cast<float>(uint32_t(key >> 32)); }

// The view pixels numbered across the views: view i's pixel (x, y) is offset[i] + y w_i + x.
struct BandSources {
  std::vector<uint32_t> offset;  // per view, then the total
  explicit BandSources(std::span<const DepthView> views) {
    uint64_t total = 0;
    for (const DepthView& v : views) {
      offset.push_back(uint32_t(total));
      total += uint64_t(v.depth_view.total());
    }
    CV_Assert(total < kNoSurface >> 32);  // 4 G pixels in all
    offset.push_back(uint32_t(total));
  }
  // The view and pixel index of a source.
  std::pair<size_t, size_t> find(uint32_t source) const {
    const size_t i = size_t(std::upper_bound(offset.begin(), offset.end(), source) - offset.begin()) - 1;
    return {i, size_t(source - offset[i])};
  }
};

// Forward-projects view i's surfaces (one pixel of each stride x stride block) into the
// widened camera; the nearest of those landing in the band (`keys`, the band's texels in
// row order) is kept.
void splat_view_into_band(std::span<const DepthView> views, size_t i, const BandSources& sources, const Camera& frame,
                          const GuardBand& band, int stride_px, std::vector<uint64_t>& keys, int nthreads) {
  const DepthView& v = views[i];
  const glm::mat4 frame_from_view = frame.world_to_view * v.camera.view_to_world;
  const glm::mat4 clip_from_view = band.camera.view_to_clip * frame_from_view;
  const cv::Rect inside = band.inside();
  const float w = float(band.camera.width_px), h = float(band.camera.height_px);
  const int rows = (v.depth_view.rows + stride_px - 1) / stride_px;
  const PixelRays rays = pixel_rays(v.camera);
  parallel_rows(cv::Range(0, rows), nthreads, [&](const cv::Range& range) {
    for (int j = range.start; j < range.end; ++j) {
      const int y = j * stride_px;
      const float* source_row = v.depth_view.ptr<float>(y);
      for (int x = 0; x < v.depth_view.cols; x += stride_px) {
        const float d = source_row[x];
        if (!(d > 0.0f && std::isfinite(d))) continue;
        const glm::vec4 p(rays.point(float(x) + 0.5f, float(y) + 0.5f, d), 1.0f);
        const glm::vec4 clip = clip_from_view * p;
        if (!(clip.w > 0.0f)) continue;
        const float px = 0.5f * (clip.x / clip.w + 1.0f) * w, py = 0.5f * (1.0f - clip.y / clip.w) * h;
        if (!(px >= 0.0f && px < w && py >= 0.0f && py < h)) continue;
        const cv::Point texel{int(px), int(py)};
        if (inside.contains(texel)) continue;
        const float depth_in_frame = -(frame_from_view * p).z;
        const uint32_t source = sources.offset[i] + uint32_t(y) * uint32_t(v.depth_view.cols) + uint32_t(x);
        if (depth_in_frame > 0.0f)
          atomic_min(keys[size_t(texel.y) * size_t(band.camera.width_px) + size_t(texel.x)],
                     band_key(depth_in_frame, source));
      }
    }
  });
}

}  // namespace

int guard_band_texels(const cv::Mat& depth_view, const cv::Mat& mask, const Camera& camera, float radius_world,
                      float max_radius_px, int nthreads) {
  CV_Assert(depth_view.type() == CV_32FC1 && mask.type() == CV_8UC1 && mask.size() == depth_view.size());
  std::vector<float> reach_per_row(size_t(depth_view.rows), 0.0f);
  parallel_rows(cv::Range(0, depth_view.rows), nthreads, [&](const cv::Range& range) {
    band_reach_of_rows(depth_view, mask, camera, radius_world, max_radius_px, range, reach_per_row.data());
  });
  const float reach = reach_per_row.empty() ? 0.0f : *std::max_element(reach_per_row.begin(), reach_per_row.end());
  if (!(reach > 0.0f)) return 0;
  const int largest = std::max(depth_view.cols, depth_view.rows) / 4 / 4 * 4;
  return std::min(largest, (int(std::ceil(reach)) + 3) / 4 * 4);
}

Camera widened_camera(const Camera& camera, const BandMargins& m) {
  Camera wide = camera;
  wide.width_px = camera.width_px + m.left + m.right;
  wide.height_px = camera.height_px + m.top + m.bottom;
  const float sx = float(camera.width_px) / float(wide.width_px), sy = float(camera.height_px) / float(wide.height_px);
  const float tx = float(m.left - m.right) / float(wide.width_px), ty = float(m.bottom - m.top) / float(wide.height_px);
  for (int c = 0; c < 4; ++c) {  // rows 0 and 1 of the projection: NDC x and y (times clip w, row 3)
    wide.view_to_clip[c][0] *= sx;
    wide.view_to_clip[c][1] *= sy;
    if (tx != 0.0f) wide.view_to_clip[c][0] += tx * camera.view_to_clip[c][3];
    if (ty != 0.0f) wide.view_to_clip[c][1] += ty * camera.view_to_clip[c][3];
  }
  return wide;
}

cv::Rect GuardBand::inside() const {
  return {margins.left, margins.top, camera.width_px - margins.left - margins.right,
          camera.height_px - margins.top - margins.bottom};
}

namespace {

// How far past each edge of the frame the band's farthest surface on that side lies,
// texels, rounded up to a multiple of 4 (as guard_band_texels); 0 where no view saw anything.
BandMargins band_extent(const cv::Mat& depth_view, const cv::Rect& inside) {
  BandMargins extent;
  for (int y = 0; y < depth_view.rows; ++y) {
    const float* row = depth_view.ptr<float>(y);
    for (int x = 0; x < depth_view.cols; ++x) {
      if (!(row[x] < kInfinity)) continue;
      extent.left = std::max(extent.left, inside.x - x);
      extent.right = std::max(extent.right, x - (inside.br().x - 1));
      extent.top = std::max(extent.top, inside.y - y);
      extent.bottom = std::max(extent.bottom, y - (inside.br().y - 1));
    }
  }
  for (int* side : {&extent.left, &extent.top, &extent.right, &extent.bottom}) *side = (*side + 3) / 4 * 4;
  return extent;
}

// The band's mask (its surfaces) and back layer (the occupancy of the views behind them, as
// for the frame's own pixels; their own interval the assumed thickness), then the frame's
// own inside.
void fill_band(const MultiViewInputs& in, const cv::Mat& depth_back_view, std::span<const DepthView> views,
               std::span<const ViewUse> uses, const MultiViewSettings& s, GuardBand& band, int nthreads) {
  const cv::Rect inside = band.inside();
  band.mask = band.depth_view < kInfinity;
  band.mask(inside).setTo(0);
  multiview_detail::write_back_layer({band.depth_view, band.mask, band.camera}, views_from(in.camera, views, s, uses),
                                     band.depth_back_view, nthreads);
  in.depth_view.copyTo(band.depth_view(inside));
  in.mask.copyTo(band.mask(inside));
  depth_back_view.copyTo(band.depth_back_view(inside));
}

}  // namespace

namespace {

// The depth of the band's texels: their nearest surface's, +inf where none.
cv::Mat band_depth(const std::vector<uint64_t>& keys, const cv::Size& size) {
  cv::Mat depth(size, CV_32FC1);
  for (int y = 0; y < size.height; ++y) {
    float* row = depth.ptr<float>(y);
    const uint64_t* key = keys.data() + size_t(y) * size_t(size.width);
    for (int x = 0; x < size.width; ++x) row[x] = key[x] == kNoSurface ? kInfinity : key_depth(key[x]);
  }
  return depth;
}

// The band's albedo and lighting (GuardBand): each band texel's from the view pixel of its
// surface, `kept` the band's texels in `keys` (a grid keys_width wide).
void band_light(std::span<const DepthView> views, std::span<const ViewUse> uses, const BandSources& sources,
                const std::vector<uint64_t>& keys, int keys_width, const cv::Rect& kept, GuardBand& band) {
  bool any_albedo = false, any_lighting = false;
  for (size_t i = 0; i < views.size(); ++i) {
    any_albedo |= uses[i].used && !views[i].albedo.empty();
    any_lighting |= uses[i].used && !views[i].lighting.empty();
  }
  band.albedo.release();
  band.lighting.release();
  if (any_albedo) band.albedo = cv::Mat::zeros(kept.size(), CV_32FC3);
  if (any_lighting) band.lighting = cv::Mat::zeros(kept.size(), CV_32FC3);
  if (!any_albedo && !any_lighting) return;
  const cv::Rect inside = band.inside();
  for (int y = 0; y < kept.height; ++y)
    for (int x = 0; x < kept.width; ++x) {
      const uint64_t key = keys[size_t(y + kept.y) * size_t(keys_width) + size_t(x + kept.x)];
      if (key == kNoSurface || inside.contains({x, y})) continue;
      const auto [i, pixel] = sources.find(uint32_t(key));
      const DepthView& v = views[i];
      const int vy = int(pixel / size_t(v.depth_view.cols)), vx = int(pixel % size_t(v.depth_view.cols));
      if (!v.albedo.empty()) band.albedo.at<cv::Vec3f>(y, x) = v.albedo.at<cv::Vec3f>(vy, vx);
      if (!v.lighting.empty()) band.lighting.at<cv::Vec3f>(y, x) = v.lighting.at<cv::Vec3f>(vy, vx);
    }
}

}  // namespace

void extend_with_views(const MultiViewInputs& in, const cv::Mat& depth_back_view, std::span<const DepthView> views,
                       std::span<const ViewUse> uses, const MultiViewSettings& s, int margin_px, GuardBand& band,
                       int nthreads) {
  CV_Assert(validate(s).empty() && margin_px >= 0 && uses.size() == views.size());
  CV_Assert(depth_back_view.type() == CV_32FC1 && depth_back_view.size() == in.depth_view.size());
  for (const DepthView& v : views)
    CV_Assert((v.albedo.empty() || (v.albedo.type() == CV_32FC3 && v.albedo.size() == v.depth_view.size())) &&
              (v.lighting.empty() || (v.lighting.type() == CV_32FC3 && v.lighting.size() == v.depth_view.size())));
  band.margins = BandMargins{margin_px, margin_px, margin_px, margin_px};
  band.camera = widened_camera(in.camera, band.margins);
  const cv::Size size(band.camera.width_px, band.camera.height_px);
  std::vector<uint64_t> keys(size_t(size.area()), kNoSurface);
  const BandSources sources(views);
  for (size_t i = 0; i < views.size(); ++i) {
    if (!uses[i].used) continue;
    const int stride_px = std::max(1, views[i].camera.width_px / std::max(1, in.camera.width_px));
    splat_view_into_band(views, i, sources, in.camera, band, stride_px, keys, nthreads);
  }
  band.depth_view = band_depth(keys, size);
  // Only as wide as the views saw: a band of nothing costs the estimators its area for no
  // occluder (views of the same pose, or that turned away, see nothing past the edges). Each
  // side on its own: a camera moving sideways sees past the left and right edges only.
  BandMargins extent = band_extent(band.depth_view, band.inside());
  for (int* side : {&extent.left, &extent.top, &extent.right, &extent.bottom}) *side = std::min(*side, margin_px);
  const cv::Rect kept(margin_px - extent.left, margin_px - extent.top, in.camera.width_px + extent.left + extent.right,
                      in.camera.height_px + extent.top + extent.bottom);
  if (!(extent == band.margins)) {
    band.depth_view = band.depth_view(kept).clone();
    band.margins = extent;
    band.camera = widened_camera(in.camera, extent);
  }
  fill_band(in, depth_back_view, views, uses, s, band, nthreads);
  band_light(views, uses, sources, keys, size.width, kept, band);
}

std::vector<ViewUse> measure_view_use(const MultiViewInputs& in, std::span<const DepthView> views,
                                      const MultiViewSettings& s, int nthreads) {
  CV_Assert(validate(s).empty());
  CV_Assert(in.depth_view.type() == CV_32FC1 && in.mask.type() == CV_8UC1 && in.mask.size() == in.depth_view.size());
  std::vector<ViewUse> uses(views.size());
  Constants k{s, {}};
  for (size_t i = 0; i < views.size(); ++i) {
    uses[i].name = views[i].name;
    CV_Assert(views[i].depth_view.type() == CV_32FC1 && views[i].depth_view.cols == views[i].camera.width_px &&
              views[i].depth_view.rows == views[i].camera.height_px);
    k.views.push_back(view_geometry(in.camera, views[i]));
  }
  if (!views.empty()) measure_views(in, k, uses, nthreads);
  return uses;
}

cv::Mat decided_bins_behind_surfaces(const MultiViewInputs& in, std::span<const DepthView> views,
                                     const MultiViewSettings& s, float surface_scale, float bin_depth, int bins,
                                     int nthreads) {
  CV_Assert(validate(s).empty() && bins >= 1 && bins <= 8);
  CV_Assert(in.depth_view.type() == CV_32FC1 && in.mask.type() == CV_8UC1 && in.mask.size() == in.depth_view.size());
  const Constants k = views_from(in.camera, views, s);
  cv::Mat decided(in.depth_view.size(), CV_8UC1, cv::Scalar(0));
  if (k.views.empty()) return decided;
  multiview_detail::write_decided_bins(in, k, surface_scale, bin_depth, bins, decided, nthreads);
  return decided;
}

struct PointVerdicts::Impl {
  Constants k;
};

PointVerdicts::PointVerdicts(const Camera& frame_camera, std::span<const DepthView> views,
                             const MultiViewSettings& s) {
  CV_Assert(validate(s).empty());
  impl_ = std::make_unique<Impl>(Impl{views_from(frame_camera, views, s)});
}

PointVerdicts::~PointVerdicts() = default;

bool PointVerdicts::empty() const { return impl_->k.views.empty(); }

bool PointVerdicts::decided(const glm::vec3& point_view) const {
  uint8_t decided = 0;
  multiview_detail::decide_points(impl_->k, {&point_view, 1}, {&decided, 1});
  return decided != 0;
}

void PointVerdicts::decided(std::span<const glm::vec3> points_view, std::span<uint8_t> decided) const {
  CV_Assert(decided.size() == points_view.size());
  multiview_detail::decide_points(impl_->k, points_view, decided);
}

}  // namespace ssdo
