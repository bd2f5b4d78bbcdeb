#include "kernels/ao.h"

#include "kernels/settings_check.h"

#include <cmath>
#include <limits>

#include "kernels/ao_methods.h"
#include "core/enum_names.h"
#include "core/parallel.h"

namespace ssdo {

namespace {

constexpr std::pair<AoMethod, std::string_view> kAoMethodNames[] = {
    {AoMethod::hemisphere, "hemisphere"}, {AoMethod::hbao, "hbao"}, {AoMethod::gtao, "gtao"},
    {AoMethod::raymarch, "raymarch"}};
constexpr std::pair<Preset, std::string_view> kPresetNames[] = {
    {Preset::low, "low"}, {Preset::medium, "medium"}, {Preset::high, "high"}, {Preset::ultra, "ultra"}};

}  // namespace

std::string_view to_string(AoMethod m) { return enum_name<AoMethod>(kAoMethodNames, m); }
std::string_view to_string(Preset p) { return enum_name<Preset>(kPresetNames, p); }
std::optional<AoMethod> parse_ao_method(std::string_view s) { return parse_enum<AoMethod>(kAoMethodNames, s); }
std::optional<Preset> parse_preset(std::string_view s) { return parse_enum<Preset>(kPresetNames, s); }

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
      // The thickness from silhouettes: against Cycles over ten shared frames it cuts the
      // error of every preset by 30-39% (medium 0.045 -> 0.027; docs/accuracy.md). Medium
      // keeps two slices, though 1 x 8 with it errs less than 2 x 8 without: one slice per
      // pixel reads light at a crease (the corner line 0.61 at 1 x 8, 0.53 at 2 x 8; the
      // slices' visible measure over their open measure is a ratio, unbiased only as the
      // slices grow in number). Low's one slice is pooled with its neighbours' (the ratio's
      // bias and most of its noise gone: ten frames 0.040 -> 0.032, the 1080p frame 0.037
      // -> 0.027); a pooled 1 x 10 for medium erred 3% more than 2 x 8 in 0.84 of its time
      // (docs/accuracy.md, "Pooled slices").
      constexpr int kSlices[] = {1, 2, 3, 6};
      constexpr int kSteps[] = {6, 8, 16, 16};
      s.directions = kSlices[level];
      s.steps = kSteps[level];
      s.pool_slices = kSlices[level] == 1;
      s.resolution_divisor = kDivisor[level];
      s.thickness_model = ThicknessModel::silhouettes;
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

bool has_bent_normal(const AoSettings& s) { return s.method != AoMethod::hemisphere; }

bool runs_on_half_grid(const AoSettings& s) {
  return s.resolution_divisor == 2 && s.method != AoMethod::raymarch;
}

bool reads_back_layer(const AoSettings& s) { return s.method == AoMethod::gtao || s.method == AoMethod::raymarch; }

bool estimates_back_layer(const AoSettings& s) {
  return s.thickness_model == ThicknessModel::silhouettes && reads_back_layer(s);
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
  if (s.thickness_model == ThicknessModel::silhouettes)
    if (std::string e = validate(s.silhouettes); !e.empty()) return "silhouettes." + e;
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
  const bool bent_normal = has_bent_normal(s);
  if (bent_normal && (out.bent_normal_view.size() != size || out.bent_normal_view.type() != CV_32FC3))
    out.bent_normal_view.create(size, CV_32FC3);
  if (!bent_normal) out.bent_normal_view.release();
  const cv::Rect r = resolve_roi(roi, size);
  if (r.empty()) return;
  if (in.depth_back_view != nullptr || !estimates_back_layer(s)) return dispatch(in, s, out, r, nthreads);
  cv::Mat back;
  estimate_back_depth(in.depth_view, in.mask, in.camera, s.silhouettes, back, nthreads);
  AoInputs with_back = in;
  with_back.depth_back_view = &back;
  dispatch(with_back, s, out, r, nthreads);
}

}  // namespace ssdo
