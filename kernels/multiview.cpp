#include "kernels/multiview.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "core/parallel.h"
#include "kernels/settings_check.h"

namespace ssdo {
namespace {

constexpr float kInfinity = std::numeric_limits<float>::infinity();
// The views' overlap and contradiction are measured on every 4th pixel of every 4th row.
constexpr int kMeasureStridePx = 4;

// A view as seen from this frame: this frame's view space straight to the view's clip
// space and planar depth (both affine, so along a pixel's ray they are linear in depth).
struct ViewGeometry {
  glm::mat4 clip_from_frame_view;  // view_to_clip_v * world_to_view_v * view_to_world
  glm::vec4 depth_from_frame_view; // planar depth in the view: -(row z of the rigid part)
  const cv::Mat* depth_view;
  float width_px, height_px;
};

ViewGeometry view_geometry(const Camera& frame, const DepthView& v) {
  const glm::mat4 rigid = v.camera.world_to_view * frame.view_to_world;
  // glm is column-major: the z row is (m[0][2], m[1][2], m[2][2], m[3][2]).
  const glm::vec4 depth_row(-rigid[0][2], -rigid[1][2], -rigid[2][2], -rigid[3][2]);
  return {v.camera.view_to_clip * rigid, depth_row, &v.depth_view, float(v.camera.width_px),
          float(v.camera.height_px)};
}

// What a view says about a point.
enum class Verdict : uint8_t {
  unknown,   // outside its image or behind its eye
  free,      // in front of the surface it stores there
  occupied,  // behind that surface, within the thickness
  beyond,    // farther behind it than the thickness: no say
};

// A verdict that decides a point (the rule of PointVerdicts, multiview.h).
inline bool decides(Verdict v) { return v == Verdict::free || v == Verdict::occupied; }

// A point along one pixel's ray, as seen by one view: clip = clip0 + d clip1 and planar
// depth depth0 + d depth1 at planar depth d in this frame.
struct RayInView {
  glm::vec4 clip0, clip1;
  float depth0, depth1;
};

[[gnu::always_inline]] inline Verdict classify(const ViewGeometry& v, const RayInView& r, float d,
                                                float bias_relative, float thickness) {
  const glm::vec4 clip = r.clip0 + d * r.clip1;
  if (!(clip.w > 0.0f)) return Verdict::unknown;
  const float inv_w = 1.0f / clip.w;
  const float px = 0.5f * (clip.x * inv_w + 1.0f) * v.width_px;
  const float py = 0.5f * (1.0f - clip.y * inv_w) * v.height_px;
  if (!(px >= 0.0f && px < v.width_px && py >= 0.0f && py < v.height_px)) return Verdict::unknown;
  const cv::Mat& depth = *v.depth_view;
  const int w = depth.cols, h = depth.rows;
  // The 2x2 pixel centres around (px, py), clamped at the image's edges (px - 0.5 >= -0.5:
  // truncation is the floor wherever the clamp does not apply).
  const int x0 = std::min(int(px - 0.5f), w - 1), x1 = std::min(x0 + 1, w - 1);
  const int y0 = std::min(int(py - 0.5f), h - 1), y1 = std::min(y0 + 1, h - 1);
  const float* row0 = depth.ptr<float>(y0);
  const float* row1 = depth.ptr<float>(y1);
  const float nearest_surface = depth.ptr<float>(std::min(int(py), h - 1))[std::min(int(px), w - 1)];
  const float min_surface = std::min(std::min(row0[x0], row0[x1]), std::min(row1[x0], row1[x1]));
  const float depth_q = r.depth0 + d * r.depth1;
  // +inf (background) at all four: the view sees through to the sky there.
  if (depth_q < min_surface * (1.0f - bias_relative)) return Verdict::free;
  if (depth_q > nearest_surface && depth_q - nearest_surface <= thickness) return Verdict::occupied;
  return Verdict::beyond;
}

struct Constants {
  MultiViewSettings s;
  std::vector<ViewGeometry> views;
};

// One pixel's ray in every view, and which views may speak for it.
struct PixelRay {
  std::vector<RayInView> in_view;
  std::vector<uint8_t> active;  // 0: the view sees this pixel's own surface as free space
};

// rays: the frame's (pixel_rays of its camera).
inline void pixel_ray(const Constants& k, const PixelRays& rays, int x, int y, PixelRay& ray) {
  const float px = float(x) + 0.5f, py = float(y) + 0.5f;
  // The ray's points are affine in planar depth d: p(d) = a + d b (perspective: a = 0).
  const glm::vec3 a = rays.origin(px, py), b = rays.direction(px, py);
  for (size_t i = 0; i < k.views.size(); ++i) {
    const ViewGeometry& v = k.views[i];
    ray.in_view[i] = {v.clip_from_frame_view * glm::vec4(a, 1.0f), v.clip_from_frame_view * glm::vec4(b, 0.0f),
                      glm::dot(v.depth_from_frame_view, glm::vec4(a, 1.0f)),
                      glm::dot(v.depth_from_frame_view, glm::vec4(b, 0.0f))};
  }
}

// Occupancy of the point at planar depth d on a pixel's ray (the rule in multiview.h);
// `informed` is set when some view had a say.
bool occupied_at(const Constants& k, const PixelRay& ray, float d, float own_back, bool& informed) {
  bool voted = false;
  for (size_t i = 0; i < k.views.size(); ++i) {
    if (!ray.active[i]) continue;
    const Verdict v = classify(k.views[i], ray.in_view[i], d, k.s.depth_bias_relative, k.s.thickness_world);
    if (v == Verdict::free) {
      informed = true;
      return false;
    }
    voted |= v == Verdict::occupied;
  }
  if (d <= own_back) return true;
  informed |= voted;
  return voted;
}

// Walks the ray from the visible surface at `front` to front + reach_world: the depth of the
// first change from occupied to free, refined by bisection; +inf when occupied throughout;
// own_back when no view had a say.
float back_depth(const Constants& k, const PixelRay& ray, float front, float own_back) {
  const int n = k.s.samples;
  bool informed = false;
  float lo = front, hi = kInfinity;
  for (int i = 1; i <= n; ++i) {
    const float d = front + k.s.reach_world * float(i) / float(n);
    if (!occupied_at(k, ray, d, own_back, informed)) {
      hi = d;
      break;
    }
    lo = d;
  }
  if (!informed) return own_back;
  if (hi == kInfinity) return kInfinity;
  for (int j = 0; j < k.s.refinements; ++j) {
    const float mid = 0.5f * (lo + hi);
    (occupied_at(k, ray, mid, own_back, informed) ? lo : hi) = mid;
  }
  return 0.5f * (lo + hi);
}

// This frame's own occluder interval ends at the file's back layer, or at the thickness.
float own_back_depth(const MultiViewInputs& in, const MultiViewSettings& s, int x, int y, float front) {
  if (in.depth_back_view == nullptr || in.depth_back_view->empty()) return front + s.thickness_world;
  const float b = in.depth_back_view->ptr<float>(y)[x];
  return b > front ? b : front;
}

// Per view, over this frame's foreground surface points (every kMeasureStridePx-th pixel of
// every kMeasureStridePx-th row: a fraction needs no more): how many it can see, and how
// many of those it sees free space in front of (counts per row, summed in row order).
void measure_views(const MultiViewInputs& in, const Constants& k, std::vector<ViewUse>& uses, int nthreads) {
  const int rows = in.depth_view.rows, nv = int(k.views.size());
  std::vector<int64_t> seen(size_t(rows) * size_t(nv), 0), contradicted(seen.size(), 0);
  const PixelRays rays = pixel_rays(in.camera);
  parallel_rows(cv::Range(0, rows), nthreads, [&](const cv::Range& range) {
    PixelRay ray{std::vector<RayInView>(size_t(nv)), std::vector<uint8_t>(size_t(nv), 1)};
    for (int y = range.start; y < range.end; ++y) {
      if (y % kMeasureStridePx != 0) continue;
      const float* depth_row = in.depth_view.ptr<float>(y);
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      for (int x = 0; x < in.depth_view.cols; x += kMeasureStridePx) {
        if (!mask_row[x]) continue;
        pixel_ray(k, rays, x, y, ray);
        for (int i = 0; i < nv; ++i) {
          const Verdict v = classify(k.views[size_t(i)], ray.in_view[size_t(i)], depth_row[x],
                                     k.s.depth_bias_relative, k.s.thickness_world);
          seen[size_t(y) * size_t(nv) + size_t(i)] += v != Verdict::unknown;
          contradicted[size_t(y) * size_t(nv) + size_t(i)] += v == Verdict::free;
        }
      }
    }
  });
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

void write_back_layer(const MultiViewInputs& in, const Constants& k, cv::Mat& back, int nthreads) {
  const size_t nv = k.views.size();
  back.create(in.depth_view.size(), CV_32FC1);
  const PixelRays rays = pixel_rays(in.camera);
  parallel_rows(cv::Range(0, in.depth_view.rows), nthreads, [&](const cv::Range& range) {
    PixelRay ray{std::vector<RayInView>(nv), std::vector<uint8_t>(nv, 1)};
    for (int y = range.start; y < range.end; ++y) {
      const float* depth_row = in.depth_view.ptr<float>(y);
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      float* back_row = back.ptr<float>(y);
      for (int x = 0; x < in.depth_view.cols; ++x) {
        if (!mask_row[x]) {
          back_row[x] = kInfinity;
          continue;
        }
        const float front = depth_row[x];
        pixel_ray(k, rays, x, y, ray);
        // A view that sees this pixel's own surface as free space disagrees with this frame
        // here (an object that moved): it has no say on this pixel's ray.
        for (size_t i = 0; i < nv; ++i)
          ray.active[i] = classify(k.views[i], ray.in_view[i], front, k.s.depth_bias_relative,
                                   k.s.thickness_world) != Verdict::free;
        back_row[x] = back_depth(k, ray, front, own_back_depth(in, k.s, x, y, front));
      }
    }
  });
}

// The views (those measure_views marked used, when `uses` is given) as seen from `frame`.
Constants views_from(const Camera& frame, std::span<const DepthView> views, const MultiViewSettings& s,
                     std::span<const ViewUse> uses = {}) {
  Constants k{s, {}};
  for (size_t i = 0; i < views.size(); ++i)
    if (uses.empty() || uses[i].used) k.views.push_back(view_geometry(frame, views[i]));
  return k;
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
  if (!used.views.empty()) write_back_layer(in, used, depth_back_view, nthreads);
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
      const glm::vec2 radius_px = glm::min(glm::vec2(max_radius_px), radius_world * camera.pixels_per_unit(depth_row[x]));
      const float to_edge_x = std::min(float(x) + 0.5f, w - float(x) - 0.5f);
      reach = std::max({reach, radius_px.x - to_edge_x, radius_px.y - to_edge_y});
    }
    reach_per_row[y] = reach;
  }
}

// Keeps the smaller of `slot` and `value`, whatever other threads write to it.
inline void atomic_min(float& slot, float value) {
  std::atomic_ref<float> a(slot);
  float current = a.load(std::memory_order_relaxed);
  while (value < current && !a.compare_exchange_weak(current, value, std::memory_order_relaxed)) {
  }
}

// Forward-projects view v's surfaces (one pixel of each stride x stride block) into the
// widened camera; the nearest depth of those landing in the band is kept.
void splat_view_into_band(const DepthView& v, const Camera& frame, const GuardBand& band, int stride_px,
                          cv::Mat& depth_view, int nthreads) {
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
        if (depth_in_frame > 0.0f) atomic_min(depth_view.ptr<float>(texel.y)[texel.x], depth_in_frame);
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

Camera widened_camera(const Camera& camera, int margin_px) {
  Camera wide = camera;
  wide.width_px = camera.width_px + 2 * margin_px;
  wide.height_px = camera.height_px + 2 * margin_px;
  const float sx = float(camera.width_px) / float(wide.width_px), sy = float(camera.height_px) / float(wide.height_px);
  for (int c = 0; c < 4; ++c) {  // rows 0 and 1 of the projection: NDC x and y
    wide.view_to_clip[c][0] *= sx;
    wide.view_to_clip[c][1] *= sy;
  }
  return wide;
}

cv::Rect GuardBand::inside() const {
  return {margin_px, margin_px, camera.width_px - 2 * margin_px, camera.height_px - 2 * margin_px};
}

namespace {

// How far past the frame's edges the band's farthest surface lies, texels, rounded up to a
// multiple of 4 (as guard_band_texels); 0 when no view saw anything there.
int band_extent(const cv::Mat& depth_view, const cv::Rect& inside) {
  int extent = 0;
  for (int y = 0; y < depth_view.rows; ++y) {
    const float* row = depth_view.ptr<float>(y);
    const int dy = std::max({0, inside.y - y, y - (inside.br().y - 1)});
    for (int x = 0; x < depth_view.cols; ++x) {
      if (!(row[x] < kInfinity)) continue;
      const int dx = std::max({0, inside.x - x, x - (inside.br().x - 1)});
      extent = std::max({extent, dx, dy});
    }
  }
  return (extent + 3) / 4 * 4;
}

// The band's mask (its surfaces) and back layer (the occupancy of the views behind them, as
// for the frame's own pixels; their own interval the assumed thickness), then the frame's
// own inside.
void fill_band(const MultiViewInputs& in, const cv::Mat& depth_back_view, std::span<const DepthView> views,
               std::span<const ViewUse> uses, const MultiViewSettings& s, GuardBand& band, int nthreads) {
  const cv::Rect inside = band.inside();
  band.mask = band.depth_view < kInfinity;
  band.mask(inside).setTo(0);
  write_back_layer({band.depth_view, band.mask, band.camera}, views_from(in.camera, views, s, uses),
                   band.depth_back_view, nthreads);
  in.depth_view.copyTo(band.depth_view(inside));
  in.mask.copyTo(band.mask(inside));
  depth_back_view.copyTo(band.depth_back_view(inside));
}

}  // namespace

void extend_with_views(const MultiViewInputs& in, const cv::Mat& depth_back_view, std::span<const DepthView> views,
                       std::span<const ViewUse> uses, const MultiViewSettings& s, int margin_px, GuardBand& band,
                       int nthreads) {
  CV_Assert(validate(s).empty() && margin_px >= 0 && uses.size() == views.size());
  CV_Assert(depth_back_view.type() == CV_32FC1 && depth_back_view.size() == in.depth_view.size());
  band.margin_px = margin_px;
  band.camera = widened_camera(in.camera, margin_px);
  const cv::Size size(band.camera.width_px, band.camera.height_px);
  band.depth_view.create(size, CV_32FC1);
  band.depth_view.setTo(kInfinity);
  for (size_t i = 0; i < views.size(); ++i) {
    if (!uses[i].used) continue;
    const int stride_px = std::max(1, views[i].camera.width_px / std::max(1, in.camera.width_px));
    splat_view_into_band(views[i], in.camera, band, stride_px, band.depth_view, nthreads);
  }
  // Only as wide as the views saw: a band of nothing costs the estimators its area for no
  // occluder (views of the same pose, or that turned away, see nothing past the edges).
  const int extent_px = std::min(margin_px, band_extent(band.depth_view, band.inside()));
  if (extent_px < margin_px) {
    const int cut = margin_px - extent_px;
    band.depth_view = band.depth_view(cv::Rect(cut, cut, size.width - 2 * cut, size.height - 2 * cut)).clone();
    band.margin_px = extent_px;
    band.camera = widened_camera(in.camera, extent_px);
  }
  fill_band(in, depth_back_view, views, uses, s, band, nthreads);
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

namespace {

// Whether some view sees the point at planar depth d on the ray as free space or has it
// behind its surface within the thickness.
bool decided_at(const Constants& k, const PixelRay& ray, float d) {
  for (size_t i = 0; i < k.views.size(); ++i)
    if (decides(classify(k.views[i], ray.in_view[i], d, k.s.depth_bias_relative, k.s.thickness_world))) return true;
  return false;
}

}  // namespace

cv::Mat decided_bins_behind_surfaces(const MultiViewInputs& in, std::span<const DepthView> views,
                                     const MultiViewSettings& s, float surface_scale, float bin_depth, int bins,
                                     int nthreads) {
  CV_Assert(validate(s).empty() && bins >= 1 && bins <= 8);
  CV_Assert(in.depth_view.type() == CV_32FC1 && in.mask.type() == CV_8UC1 && in.mask.size() == in.depth_view.size());
  const Constants k = views_from(in.camera, views, s);
  cv::Mat decided(in.depth_view.size(), CV_8UC1, cv::Scalar(0));
  if (k.views.empty()) return decided;
  const PixelRays rays = pixel_rays(in.camera);
  parallel_rows(cv::Range(0, in.depth_view.rows), nthreads, [&](const cv::Range& range) {
    PixelRay ray{std::vector<RayInView>(k.views.size()), {}};
    for (int y = range.start; y < range.end; ++y) {
      const float* depth_row = in.depth_view.ptr<float>(y);
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      uint8_t* out = decided.ptr<uint8_t>(y);
      for (int x = 0; x < in.depth_view.cols; ++x) {
        const float d = depth_row[x];
        if (!mask_row[x] || !(d > 0.0f && std::isfinite(d))) continue;
        pixel_ray(k, rays, x, y, ray);
        unsigned bits = 0;
        for (int i = 0; i < bins; ++i)
          bits |= unsigned(decided_at(k, ray, d * surface_scale + (float(i) + 0.5f) * bin_depth)) << i;
        out[x] = uint8_t(bits);
      }
    }
  });
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
  const Constants& k = impl_->k;
  const glm::vec4 q(point_view, 1.0f);
  for (const ViewGeometry& v : k.views) {
    // The point as a ray of zero direction, read at d = 0.
    const RayInView at_point{v.clip_from_frame_view * q, glm::vec4(0.0f), glm::dot(v.depth_from_frame_view, q), 0.0f};
    if (decides(classify(v, at_point, 0.0f, k.s.depth_bias_relative, k.s.thickness_world))) return true;
  }
  return false;
}

}  // namespace ssdo
