#include "kernels/ao.h"

#include <cmath>

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
  switch (method) {
    case AoMethod::hemisphere: {
      constexpr int kSamples[] = {8, 16, 32, 64};
      s.samples = kSamples[level];
      break;
    }
    case AoMethod::hbao: {
      constexpr int kDirections[] = {4, 6, 8, 16};
      constexpr int kSteps[] = {4, 6, 8, 16};
      s.directions = kDirections[level];
      s.steps = kSteps[level];
      break;
    }
    case AoMethod::gtao: {
      constexpr int kSlices[] = {1, 2, 4, 9};
      constexpr int kSteps[] = {4, 6, 8, 16};
      s.directions = kSlices[level];
      s.steps = kSteps[level];
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

std::string validate(const AoSettings& s) {
  auto bad = [](const char* field, double value, const char* range) {
    return std::string(field) + " = " + std::to_string(value) + " is out of range " + range;
  };
  if (!(s.radius_world > 0.0f) || !std::isfinite(s.radius_world))
    return bad("radius_world", s.radius_world, "(0, inf)");
  if (!(s.max_radius_px >= 2.0f && s.max_radius_px <= 4096.0f))
    return bad("max_radius_px", s.max_radius_px, "[2, 4096]");
  if (s.samples < 1 || s.samples > 1024) return bad("samples", s.samples, "[1, 1024]");
  if (s.directions < 1 || s.directions > 4096) return bad("directions", s.directions, "[1, 4096]");
  if (s.steps < 1 || s.steps > 1024) return bad("steps", s.steps, "[1, 1024]");
  if (!(s.thickness_world > 0.0f)) return bad("thickness_world", s.thickness_world, "(0, inf]");
  if (!(s.falloff_fraction >= 0.0f && s.falloff_fraction <= 1.0f))
    return bad("falloff_fraction", s.falloff_fraction, "[0, 1]");
  if (!(s.depth_bias_relative >= 0.0f && s.depth_bias_relative <= 0.1f))
    return bad("depth_bias_relative", s.depth_bias_relative, "[0, 0.1]");
  return {};
}

void compute_ao(const AoInputs& in, const AoSettings& settings, AoOutput& out, cv::Rect roi,
                int nthreads) {
  CV_Assert(in.depth_view.type() == CV_32FC1);
  CV_Assert(in.mask.type() == CV_8UC1 && in.mask.size() == in.depth_view.size());
  CV_Assert(in.normal_view.type() == CV_32FC3 && in.normal_view.size() == in.depth_view.size());
  CV_Assert(in.position_view.type() == CV_32FC3 && in.position_view.size() == in.depth_view.size());
  CV_Assert(validate(settings).empty());
  const cv::Size size = in.depth_view.size();
  if (out.ao.size() != size || out.ao.type() != CV_32FC1) out.ao.create(size, CV_32FC1);
  const bool has_bent_normal = settings.method != AoMethod::hemisphere;
  if (has_bent_normal && (out.bent_normal_view.size() != size || out.bent_normal_view.type() != CV_32FC3))
    out.bent_normal_view.create(size, CV_32FC3);
  if (!has_bent_normal) out.bent_normal_view.release();
  const cv::Rect r = resolve_roi(roi, size);
  switch (settings.method) {
    case AoMethod::hemisphere: detail::ao_hemisphere(in, settings, out, r, nthreads); break;
    case AoMethod::hbao: detail::ao_hbao(in, settings, out, r, nthreads); break;
    case AoMethod::gtao: detail::ao_gtao(in, settings, out, r, nthreads); break;
    case AoMethod::raymarch: detail::ao_raymarch(in, settings, out, r, nthreads); break;
  }
}

}  // namespace ssdo
