#include "kernels/composite.h"

#include <cmath>
#include <tuple>

#include "kernels/parallel.h"

namespace ssdo {

namespace {

constexpr CompositeTerm kAllTerms[] = {CompositeTerm::ambient, CompositeTerm::ambient_ao,
                                       CompositeTerm::ssdo_direct, CompositeTerm::ssdo_indirect,
                                       CompositeTerm::lighting};
constexpr CompositeMode kAllModes[] = {CompositeMode::off, CompositeMode::ssao, CompositeMode::ssdo,
                                       CompositeMode::ssao_ssdo};

bool usable(const cv::Mat* m) { return m && !m->empty(); }

glm::vec3 rgb(const cv::Mat* m, int x, int y, glm::vec3 missing) {
  if (!usable(m)) return missing;
  const cv::Vec3f& v = m->at<cv::Vec3f>(y, x);
  return {v[0], v[1], v[2]};
}

}  // namespace

std::string_view to_string(CompositeTerm t) {
  switch (t) {
    case CompositeTerm::ambient: return "ambient";
    case CompositeTerm::ambient_ao: return "ambient_ao";
    case CompositeTerm::ssdo_direct: return "ssdo_direct";
    case CompositeTerm::ssdo_indirect: return "ssdo_indirect";
    case CompositeTerm::lighting: return "lighting";
  }
  return "?";
}

std::string_view to_string(CompositeMode m) {
  switch (m) {
    case CompositeMode::off: return "off";
    case CompositeMode::ssao: return "ssao";
    case CompositeMode::ssdo: return "ssdo";
    case CompositeMode::ssao_ssdo: return "ssao+ssdo";
  }
  return "?";
}

std::optional<CompositeTerm> parse_composite_term(std::string_view s) {
  for (CompositeTerm t : kAllTerms)
    if (s == to_string(t)) return t;
  return std::nullopt;
}

std::optional<CompositeMode> parse_composite_mode(std::string_view s) {
  for (CompositeMode m : kAllModes)
    if (s == to_string(m)) return m;
  return std::nullopt;
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
    const std::string name(to_string(t.term));
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

void compute_composite(const CompositeInputs& in, const CompositeSettings& s, cv::Mat& out, cv::Rect roi,
                       int nthreads) {
  CV_Assert(validate(in, s).empty());
  const cv::Size size = in.mask.size();
  if (out.size() != size || out.type() != CV_32FC3) out.create(size, CV_32FC3);
  // Per-term weights (0 = not selected), fixed order so the sum does not depend on the list order.
  float w[5] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  for (const WeightedTerm& t : s.terms) w[int(t.term)] = t.weight;
  const float w_ambient = w[int(CompositeTerm::ambient)], w_ambient_ao = w[int(CompositeTerm::ambient_ao)];
  const float w_direct = w[int(CompositeTerm::ssdo_direct)], w_indirect = w[int(CompositeTerm::ssdo_indirect)];
  const float w_lighting = w[int(CompositeTerm::lighting)];
  const bool env_background = !usable(in.background) && in.environment && in.camera;

  const cv::Rect r = resolve_roi(roi, size);
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* m = in.mask.ptr<uint8_t>(y);
      cv::Vec3f* o = out.ptr<cv::Vec3f>(y);
      for (int x = r.x; x < r.x + r.width; ++x) {
        glm::vec3 c(0.0f);
        if (!m[x]) {
          if (usable(in.background)) {
            c = rgb(in.background, x, y, glm::vec3(0.0f));
          } else if (env_background) {
            const glm::vec3 d_view = in.camera->view_ray_direction({x + 0.5f, y + 0.5f});
            c = in.environment->radiance(in.camera->world_from_view_direction(d_view));
          }
          o[x] = cv::Vec3f(c.x, c.y, c.z);
          continue;
        }
        const glm::vec3 albedo = rgb(in.albedo, x, y, glm::vec3(1.0f));
        const float ao = usable(in.ao) ? in.ao->at<float>(y, x) : 1.0f;
        glm::vec3 irradiance_like = (w_ambient + w_ambient_ao * ao) * s.ambient_radiance;
        if (w_direct > 0.0f) irradiance_like += w_direct * rgb(in.direct, x, y, glm::vec3(0.0f));
        if (w_indirect > 0.0f) irradiance_like += w_indirect * rgb(in.indirect, x, y, glm::vec3(0.0f));
        c = albedo * irradiance_like;
        if (w_lighting > 0.0f) c += w_lighting * rgb(in.lighting, x, y, glm::vec3(0.0f));
        o[x] = cv::Vec3f(c.x, c.y, c.z);
      }
    }
  });
}

}  // namespace ssdo
