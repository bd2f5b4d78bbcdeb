#include "kernels/composite.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/composite.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <cmath>
#include <tuple>
#include <vector>

#include "core/enum_names.h"
#include "core/parallel.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

namespace {

bool usable(const cv::Mat* m) { return m && !m->empty(); }

}  // namespace

namespace {

// The composite's per-term weights, 0 = not selected.
struct TermWeights {
  float ambient, ambient_ao, direct, indirect, lighting;
  glm::vec3 ambient_radiance;
};

// One row of the inputs, from pixel 0 of the row. A missing albedo or AO points at a row
// of ones: multiplying by 1 is exact, so this equals the "missing = white / unoccluded"
// value of composite.h bit for bit.
struct InputRow {
  const float* albedo;    // 3 floats per pixel
  const float* ao;        // 1 float per pixel
  const float* direct;    // 3 floats per pixel, or null when the term is off
  const float* indirect;  // 3 floats per pixel, or null when the term is off
  const float* lighting;  // 3 floats per pixel, or null when the term is off
};

// Foreground pixels [x_begin, x_end) of one row:
//   c = albedo x ((w_ambient + w_ambient_ao ao) ambient + w_direct direct + w_indirect indirect)
//       + w_lighting lighting,
// each product and sum in this order (the order does not depend on the term list). The term
// switches are template parameters so that the loop has no per-pixel branch, plain
// pointers and can vectorise.
template <bool kDirect, bool kIndirect, bool kLighting>
void foreground_span(const InputRow& in, const TermWeights& w, int x_begin, int x_end, float* out) {
  const float ar = w.ambient_radiance.x, ag = w.ambient_radiance.y, ab = w.ambient_radiance.z;
  for (int x = x_begin; x < x_end; ++x) {
    const float ambient = w.ambient + w.ambient_ao * in.ao[x];
    float r = ambient * ar, g = ambient * ag, b = ambient * ab;
    if constexpr (kDirect) {
      const float* d = in.direct + 3 * x;
      r += w.direct * d[0], g += w.direct * d[1], b += w.direct * d[2];
    }
    if constexpr (kIndirect) {
      const float* d = in.indirect + 3 * x;
      r += w.indirect * d[0], g += w.indirect * d[1], b += w.indirect * d[2];
    }
    const float* a = in.albedo + 3 * x;
    r = a[0] * r, g = a[1] * g, b = a[2] * b;
    if constexpr (kLighting) {
      const float* l = in.lighting + 3 * x;
      r += w.lighting * l[0], g += w.lighting * l[1], b += w.lighting * l[2];
    }
    float* o = out + 3 * x;
    o[0] = r, o[1] = g, o[2] = b;
  }
}

using ForegroundSpan = void (*)(const InputRow&, const TermWeights&, int, int, float*);

ForegroundSpan foreground_span_for(bool direct, bool indirect, bool lighting) {
  static constexpr ForegroundSpan kSpans[8] = {
      foreground_span<false, false, false>, foreground_span<false, false, true>,
      foreground_span<false, true, false>,  foreground_span<false, true, true>,
      foreground_span<true, false, false>,  foreground_span<true, false, true>,
      foreground_span<true, true, false>,   foreground_span<true, true, true>};
  return kSpans[4 * int(direct) + 2 * int(indirect) + int(lighting)];
}

}  // namespace

void compute_composite(const CompositeInputs& in, const CompositeSettings& s, cv::Mat& out, cv::Rect roi,
                       int nthreads) {
  CV_Assert(ssdo::validate(in, s).empty());
  const cv::Size size = in.mask.size();
  if (out.size() != size || out.type() != CV_32FC3) out.create(size, CV_32FC3);
  // Per-term weights (0 = not selected), fixed order so the sum does not depend on the list order.
  float w[5] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  for (const WeightedTerm& t : s.terms) w[int(t.term)] = t.weight;
  const TermWeights weights{w[int(CompositeTerm::ambient)],     w[int(CompositeTerm::ambient_ao)],
                            w[int(CompositeTerm::ssdo_direct)], w[int(CompositeTerm::ssdo_indirect)],
                            w[int(CompositeTerm::lighting)],    s.ambient_radiance};
  // A term of weight 0 (or -0) is skipped, not added as 0 x input: an infinite or NaN input
  // of an unused term must not reach the sum.
  const bool use_direct = weights.direct > 0.0f, use_indirect = weights.indirect > 0.0f;
  const bool use_lighting = weights.lighting > 0.0f;
  const ForegroundSpan foreground = foreground_span_for(use_direct, use_indirect, use_lighting);
  const bool has_albedo = usable(in.albedo), has_ao = usable(in.ao);
  const std::vector<float> ones(has_albedo && has_ao ? 0 : 3 * size_t(size.width), 1.0f);
  const cv::Mat* background = usable(in.background) ? in.background : nullptr;
  const bool env_background = !background && in.environment && in.camera;

  const cv::Rect r = resolve_roi(roi, size);
  const int x_end = r.x + r.width;
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* m = in.mask.ptr<uint8_t>(y);
      float* o = out.ptr<float>(y);
      const InputRow row{has_albedo ? in.albedo->ptr<float>(y) : ones.data(),
                         has_ao ? in.ao->ptr<float>(y) : ones.data(),
                         use_direct ? in.direct->ptr<float>(y) : nullptr,
                         use_indirect ? in.indirect->ptr<float>(y) : nullptr,
                         use_lighting ? in.lighting->ptr<float>(y) : nullptr};
      const float* bg = background ? background->ptr<float>(y) : nullptr;
      // Alternating runs of foreground (mask != 0) and background pixels.
      for (int x = r.x; x < x_end;) {
        int run_end = x;
        while (run_end < x_end && m[run_end]) ++run_end;
        foreground(row, weights, x, run_end, o);
        for (x = run_end; x < x_end && !m[x]; ++x) {
          float* c = o + 3 * x;
          if (bg) {
            c[0] = bg[3 * x], c[1] = bg[3 * x + 1], c[2] = bg[3 * x + 2];
          } else if (env_background) {
            const glm::vec3 d_view = in.camera->view_ray_direction({x + 0.5f, y + 0.5f});
            const glm::vec3 l = in.environment->radiance(in.camera->world_from_view_direction(d_view));
            c[0] = l.x, c[1] = l.y, c[2] = l.z;
          } else {
            c[0] = 0.0f, c[1] = 0.0f, c[2] = 0.0f;
          }
        }
      }
    }
  });
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

// Names and settings, not pixels: compiled once, outside the per-target code.
using HWY_NAMESPACE::usable;

namespace {

constexpr std::pair<CompositeTerm, std::string_view> kTermNames[] = {
    {CompositeTerm::ambient, "ambient"},         {CompositeTerm::ambient_ao, "ambient_ao"},
    {CompositeTerm::ssdo_direct, "ssdo_direct"}, {CompositeTerm::ssdo_indirect, "ssdo_indirect"},
    {CompositeTerm::lighting, "lighting"}};
constexpr std::pair<CompositeMode, std::string_view> kModeNames[] = {
    {CompositeMode::off, "off"}, {CompositeMode::ssao, "ssao"}, {CompositeMode::ssdo, "ssdo"},
    {CompositeMode::ssao_ssdo, "ssao+ssdo"}};

}  // namespace

std::string_view to_string(CompositeTerm t) { return enum_name<CompositeTerm>(kTermNames, t); }
std::string_view to_string(CompositeMode m) { return enum_name<CompositeMode>(kModeNames, m); }
std::optional<CompositeTerm> parse_composite_term(std::string_view s) {
  return parse_enum<CompositeTerm>(kTermNames, s);
}
std::optional<CompositeMode> parse_composite_mode(std::string_view s) {
  return parse_enum<CompositeMode>(kModeNames, s);
}

std::vector<WeightedTerm> composite_mode_terms(CompositeMode mode) {
  switch (mode) {
    case CompositeMode::off: return {{CompositeTerm::ambient, 1.0f}};
    case CompositeMode::ssao: return {{CompositeTerm::ambient_ao, 1.0f}};
    case CompositeMode::ssdo:
      return {{CompositeTerm::ssdo_direct, 1.0f}, {CompositeTerm::ssdo_indirect, 1.0f}};
    case CompositeMode::ssao_ssdo:
      return {{CompositeTerm::ambient_ao, 1.0f},
              {CompositeTerm::ssdo_direct, 1.0f},
              {CompositeTerm::ssdo_indirect, 1.0f}};
  }
  return {};
}

std::string validate(const CompositeInputs& in, const CompositeSettings& s) {
  if (in.mask.type() != CV_8UC1 || in.mask.empty()) return "mask must be a non-empty CV_8UC1 image";
  const cv::Size size = in.mask.size();
  auto check = [&](const cv::Mat* m, int type, const char* name) -> std::string {
    if (!usable(m)) return {};
    if (m->type() != type || m->size() != size)
      return std::string(name) + " must be " + (type == CV_32FC1 ? "CV_32FC1" : "CV_32FC3") +
             " of the mask's size";
    return {};
  };
  for (const auto& [m, type, name] :
       {std::tuple{in.albedo, CV_32FC3, "albedo"}, std::tuple{in.ao, CV_32FC1, "ao"},
        std::tuple{in.direct, CV_32FC3, "direct"}, std::tuple{in.indirect, CV_32FC3, "indirect"},
        std::tuple{in.lighting, CV_32FC3, "lighting"}, std::tuple{in.background, CV_32FC3, "background"}})
    if (std::string e = check(m, type, name); !e.empty()) return e;
  if (in.environment && !in.camera) return "environment given without camera";
  if (in.camera && (in.camera->width_px != size.width || in.camera->height_px != size.height))
    return "camera size differs from the mask's";
  if (!(s.ambient_radiance.x >= 0.0f && s.ambient_radiance.y >= 0.0f && s.ambient_radiance.z >= 0.0f))
    return "ambient_radiance must be >= 0";
  bool seen[5] = {false, false, false, false, false};
  for (const WeightedTerm& t : s.terms) {
    const std::string name(ssdo::to_string(t.term));
    if (seen[int(t.term)]) return "term " + name + " selected twice";
    seen[int(t.term)] = true;
    if (!(t.weight >= 0.0f && t.weight <= 16.0f))
      return "weight of " + name + " = " + std::to_string(t.weight) + " is out of range [0, 16]";
    if (t.term == CompositeTerm::ssdo_direct && !usable(in.direct)) return "term " + name + " needs direct";
    if (t.term == CompositeTerm::ssdo_indirect && !usable(in.indirect)) return "term " + name + " needs indirect";
    if (t.term == CompositeTerm::lighting && !usable(in.lighting)) return "term " + name + " needs lighting";
  }
  return {};
}

HWY_EXPORT(compute_composite);
void compute_composite(const CompositeInputs& in, const CompositeSettings& s, cv::Mat& out, cv::Rect roi,
                       int nthreads) {
  HWY_DYNAMIC_DISPATCH(compute_composite)(in, s, out, roi, nthreads);
}

}  // namespace ssdo
#endif  // HWY_ONCE
