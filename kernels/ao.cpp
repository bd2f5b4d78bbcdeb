#include "kernels/ao.h"

#include "kernels/settings_check.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "kernels/ao_methods.h"
#include "kernels/parallel.h"

namespace ssdo {

std::string_view to_string(AoMethod m) {
  switch (m) {
    case AoMethod::hemisphere: return "hemisphere";
    case AoMethod::hbao: return "hbao";
    case AoMethod::gtao: return "gtao";
    case AoMethod::raymarch: return "raymarch";
  }
  return "?";
}

std::string_view to_string(Preset p) {
  switch (p) {
    case Preset::low: return "low";
    case Preset::medium: return "medium";
    case Preset::high: return "high";
    case Preset::ultra: return "ultra";
  }
  return "?";
}

std::optional<AoMethod> parse_ao_method(std::string_view s) {
  for (AoMethod m : {AoMethod::hemisphere, AoMethod::hbao, AoMethod::gtao, AoMethod::raymarch})
    if (s == to_string(m)) return m;
  return std::nullopt;
}

std::optional<Preset> parse_preset(std::string_view s) {
  for (Preset p : {Preset::low, Preset::medium, Preset::high, Preset::ultra})
    if (s == to_string(p)) return p;
  return std::nullopt;
}

AoSettings ao_preset(AoMethod method, Preset preset) {
  AoSettings s;
  s.method = method;
  const int level = int(preset);  // 0 low .. 3 ultra
  // Low and medium run on the half-resolution grid (resolution_divisor 2): a quarter of
  // the work for the interactive presets; high and ultra keep every pixel.
  constexpr int kDivisor[] = {2, 2, 1, 1};
  switch (method) {
    case AoMethod::hemisphere: {
      constexpr int kSamples[] = {8, 16, 32, 64};
      s.samples = kSamples[level];
      s.resolution_divisor = kDivisor[level];
      break;
    }
    case AoMethod::hbao: {
      constexpr int kDirections[] = {4, 6, 8, 16};
      constexpr int kSteps[] = {4, 6, 8, 16};
      s.directions = kDirections[level];
      s.steps = kSteps[level];
      s.resolution_divisor = kDivisor[level];
      break;
    }
    case AoMethod::gtao: {
      // Steps matter more than slices with the visibility mask: against the raymarch
      // oracle on cornell, 4 slices x 8 steps left MAE 0.040, 8 x 8 0.052 (power 2), 3 x 16
      // 0.022; the per-pixel slice rotation and the denoiser average slices spatially.
      // Ultra adds slices, not steps: 24 steps connected more taps across the gap under
      // the closed-form sphere (0.864 vs exact 0.889; 16 steps 0.886).
      constexpr int kSlices[] = {1, 2, 3, 6};
      constexpr int kSteps[] = {6, 8, 16, 16};
      s.directions = kSlices[level];
      s.steps = kSteps[level];
      s.resolution_divisor = kDivisor[level];
      break;
    }
    case AoMethod::raymarch: {
      constexpr int kDirections[] = {64, 128, 256, 1024};
      constexpr int kSteps[] = {32, 64, 96, 128};
      s.directions = kDirections[level];
      s.steps = kSteps[level];
      s.falloff_fraction = 0.0f;
      break;
    }
  }
  return s;
}

float effective_thickness_world(const AoSettings& s) {
  return s.thickness_world > 0.0f ? s.thickness_world : kThicknessPerRadius * s.radius_world;
}

std::string validate(const AoSettings& s) {
  if (std::string e = detail::check_radius(s.radius_world, s.max_radius_px); !e.empty()) return e;
  if (s.samples < 1 || s.samples > 1024) return detail::out_of_range("samples", s.samples, "[1, 1024]");
  if (s.directions < 1 || s.directions > 4096) return detail::out_of_range("directions", s.directions, "[1, 4096]");
  if (s.steps < 1 || s.steps > 1024) return detail::out_of_range("steps", s.steps, "[1, 1024]");
  if (!(s.thickness_world >= 0.0f)) return detail::out_of_range("thickness_world", s.thickness_world, "[0, inf]");
  if (!(s.falloff_fraction >= 0.0f && s.falloff_fraction <= 1.0f))
    return detail::out_of_range("falloff_fraction", s.falloff_fraction, "[0, 1]");
  if (!(s.depth_bias_relative >= 0.0f && s.depth_bias_relative <= 0.1f))
    return detail::out_of_range("depth_bias_relative", s.depth_bias_relative, "[0, 0.1]");
  if (s.resolution_divisor < 1 || s.resolution_divisor > 2)
    return detail::out_of_range("resolution_divisor", s.resolution_divisor, "[1, 2]");
  return {};
}

namespace {

void dispatch(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& r, int nthreads) {
  switch (s.method) {
    case AoMethod::hemisphere: detail::ao_hemisphere(in, s, out, r, nthreads); break;
    case AoMethod::hbao: detail::ao_hbao(in, s, out, r, nthreads); break;
    case AoMethod::gtao: detail::ao_gtao(in, s, out, r, nthreads); break;
    case AoMethod::raymarch: detail::ao_raymarch(in, s, out, r, nthreads); break;
  }
}

// Half resolution (resolution_divisor 2). Texel (i, j) of the half grid stands for the 2x2
// block of pixels (2i.., 2j..) and takes the first foreground pixel of the block in the
// order (0,0), (1,0), (0,1), (1,1): its exact depth, normal and view-space position (no
// averaging, which would invent points between a silhouette and the background). The
// camera keeps its projection with the half grid's size, so a method projecting radii and
// points sees the same scene at half the pixels.
struct HalfGrid {
  cv::Mat depth_view, normal_view, position_view, mask, albedo;
  cv::Mat source;  // CV_32SC2: the full-resolution pixel each texel took, (-1, -1) if none
  Camera camera;
};

void build_half_grid(const AoInputs& in, HalfGrid& h, int nthreads) {
  const cv::Size full = in.depth_view.size();
  const cv::Size half((full.width + 1) / 2, (full.height + 1) / 2);
  h.depth_view.create(half, CV_32FC1);
  h.normal_view.create(half, CV_32FC3);
  h.position_view.create(half, CV_32FC3);
  h.mask.create(half, CV_8UC1);
  h.source.create(half, CV_32SC2);
  const bool has_albedo = in.albedo != nullptr && !in.albedo->empty();
  if (has_albedo) h.albedo.create(half, CV_32FC3);
  h.camera = in.camera;
  h.camera.width_px = half.width;
  h.camera.height_px = half.height;
  // The methods read taps anywhere on the grid: all of it is filled, whatever the roi.
  parallel_rows(cv::Range(0, half.height), nthreads, [&](const cv::Range& rows) {
    for (int j = rows.start; j < rows.end; ++j)
      for (int i = 0; i < half.width; ++i) {
        int sx = -1, sy = -1;
        for (int k = 0; k < 4 && sx < 0; ++k) {
          const int x = 2 * i + (k & 1), y = 2 * j + (k >> 1);
          if (x < full.width && y < full.height && in.mask.ptr<uint8_t>(y)[x]) sx = x, sy = y;
        }
        h.source.ptr<cv::Vec2i>(j)[i] = cv::Vec2i(sx, sy);
        if (sx < 0) {
          h.mask.ptr<uint8_t>(j)[i] = 0;
          h.depth_view.ptr<float>(j)[i] = std::numeric_limits<float>::infinity();
          h.normal_view.ptr<cv::Vec3f>(j)[i] = cv::Vec3f(0, 0, 0);
          h.position_view.ptr<cv::Vec3f>(j)[i] = cv::Vec3f(0, 0, 0);
          if (has_albedo) h.albedo.ptr<cv::Vec3f>(j)[i] = cv::Vec3f(0, 0, 0);
          continue;
        }
        h.mask.ptr<uint8_t>(j)[i] = 255;
        h.depth_view.ptr<float>(j)[i] = in.depth_view.ptr<float>(sy)[sx];
        h.normal_view.ptr<cv::Vec3f>(j)[i] = in.normal_view.ptr<cv::Vec3f>(sy)[sx];
        h.position_view.ptr<cv::Vec3f>(j)[i] = in.position_view.ptr<cv::Vec3f>(sy)[sx];
        if (has_albedo) h.albedo.ptr<cv::Vec3f>(j)[i] = in.albedo->ptr<cv::Vec3f>(sy)[sx];
      }
  });
}

// Depth tolerance of the upsample, relative to the pixel's depth: a texel whose depth
// differs by 5% of the pixel's weighs exp(-1) of one at the same depth, so the texels of a
// surface behind a silhouette (depth gaps are tens of percent) carry ~nothing across it.
constexpr float kUpsampleDepthRelative = 0.05f;

// Depth- and normal-aware upsample (joint bilateral over the 2x2 nearest texels, bilinear
// weights times exp(-|dz| / (tol z)) times max(0, n . n_texel)^4); when all four weigh
// ~0 (a pixel whose surface no nearby texel took), the texel of the 3x3 neighbourhood
// closest in depth is copied.
void upsample(const AoInputs& in, const HalfGrid& h, const AoOutput& half_out, AoOutput& out,
              const cv::Rect& r, int nthreads) {
  const int hw = h.depth_view.cols, hh = h.depth_view.rows;
  const bool bent = !half_out.bent_normal_view.empty();
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      float* ao_row = out.ao.ptr<float>(y);
      cv::Vec3f* bent_row = bent ? out.bent_normal_view.ptr<cv::Vec3f>(y) : nullptr;
      const float fy = (float(y) + 0.5f) * 0.5f - 0.5f;
      const int j0 = int(std::floor(fy));
      const float wy1 = fy - float(j0);
      for (int x = r.x; x < r.x + r.width; ++x) {
        if (!mask_row[x]) {
          ao_row[x] = 1.0f;
          if (bent) bent_row[x] = cv::Vec3f(0, 0, 0);
          continue;
        }
        const float d = in.depth_view.ptr<float>(y)[x];
        const cv::Vec3f n = in.normal_view.ptr<cv::Vec3f>(y)[x];
        const float inv_tol = 1.0f / (kUpsampleDepthRelative * d);
        const float fx = (float(x) + 0.5f) * 0.5f - 0.5f;
        const int i0 = int(std::floor(fx));
        const float wx1 = fx - float(i0);
        float sum = 0.0f, wsum = 0.0f;
        cv::Vec3f bsum(0, 0, 0);
        for (int k = 0; k < 4; ++k) {
          const int i = std::clamp(i0 + (k & 1), 0, hw - 1), j = std::clamp(j0 + (k >> 1), 0, hh - 1);
          if (!h.mask.ptr<uint8_t>(j)[i]) continue;
          const float wb = ((k & 1) ? wx1 : 1.0f - wx1) * ((k >> 1) ? wy1 : 1.0f - wy1);
          const float dz = std::abs(h.depth_view.ptr<float>(j)[i] - d) * inv_tol;
          float c = std::max(0.0f, n.dot(h.normal_view.ptr<cv::Vec3f>(j)[i]));
          c *= c;
          const float w = wb * std::exp(-dz) * c * c;
          sum += w * half_out.ao.ptr<float>(j)[i];
          if (bent) bsum += w * half_out.bent_normal_view.ptr<cv::Vec3f>(j)[i];
          wsum += w;
        }
        // Below 1e-4 the weights are exp(-9)-small: the pixel's surface is not among
        // the four texels (a thin feature or a silhouette); ratios would amplify noise.
        if (!(wsum > 1e-4f)) {
          int bi = -1, bj = -1;
          float best = std::numeric_limits<float>::infinity();
          for (int dj = -1; dj <= 2; ++dj)
            for (int di = -1; di <= 2; ++di) {
              const int i = i0 + di, j = j0 + dj;
              if (i < 0 || j < 0 || i >= hw || j >= hh || !h.mask.ptr<uint8_t>(j)[i]) continue;
              const float dz = std::abs(h.depth_view.ptr<float>(j)[i] - d);
              if (dz < best) best = dz, bi = i, bj = j;
            }
          if (bi < 0) {  // no foreground texel near: nothing known, unoccluded
            ao_row[x] = 1.0f;
            if (bent) bent_row[x] = n;
            continue;
          }
          sum = half_out.ao.ptr<float>(bj)[bi];
          if (bent) bsum = half_out.bent_normal_view.ptr<cv::Vec3f>(bj)[bi];
          wsum = 1.0f;
        }
        ao_row[x] = std::clamp(sum / wsum, 0.0f, 1.0f);
        if (bent) {
          const float len = float(cv::norm(bsum));
          bent_row[x] = len > 1e-12f ? bsum * (1.0f / len) : n;
        }
      }
    }
  });
}

}  // namespace

void compute_ao(const AoInputs& in, const AoSettings& settings, AoOutput& out, cv::Rect roi,
                int nthreads) {
  CV_Assert(in.depth_view.type() == CV_32FC1);
  CV_Assert(in.mask.type() == CV_8UC1 && in.mask.size() == in.depth_view.size());
  CV_Assert(in.normal_view.type() == CV_32FC3 && in.normal_view.size() == in.depth_view.size());
  CV_Assert(in.position_view.type() == CV_32FC3 && in.position_view.size() == in.depth_view.size());
  CV_Assert(validate(settings).empty());
  AoSettings s = settings;
  s.thickness_world = effective_thickness_world(settings);
  const cv::Size size = in.depth_view.size();
  if (out.ao.size() != size || out.ao.type() != CV_32FC1) out.ao.create(size, CV_32FC1);
  const bool has_bent_normal = s.method != AoMethod::hemisphere;
  if (has_bent_normal && (out.bent_normal_view.size() != size || out.bent_normal_view.type() != CV_32FC3))
    out.bent_normal_view.create(size, CV_32FC3);
  if (!has_bent_normal) out.bent_normal_view.release();
  const cv::Rect r = resolve_roi(roi, size);
  if (r.empty()) return;
  if (s.resolution_divisor == 1 || s.method == AoMethod::raymarch) {
    dispatch(in, s, out, r, nthreads);
    return;
  }
  // Half grid: the texels the upsample of roi reads (pixel x reads texels
  // floor(x / 2 - 0.25) - 1 .. + 2), then upsample.
  HalfGrid h;
  const cv::Rect half_roi =
      cv::Rect(r.x / 2 - 2, r.y / 2 - 2, r.width / 2 + 5, r.height / 2 + 5) &
      cv::Rect(0, 0, (size.width + 1) / 2, (size.height + 1) / 2);
  build_half_grid(in, h, nthreads);
  const AoInputs half_in{h.depth_view, h.normal_view, h.position_view, h.mask, h.camera,
                         h.albedo.empty() ? nullptr : &h.albedo};
  AoOutput half_out;
  half_out.ao.create(h.depth_view.size(), CV_32FC1);
  if (has_bent_normal) half_out.bent_normal_view.create(h.depth_view.size(), CV_32FC3);
  dispatch(half_in, s, half_out, half_roi, nthreads);
  upsample(in, h, half_out, out, r, nthreads);
}

}  // namespace ssdo
