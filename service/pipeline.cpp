#include "service/pipeline.h"

#include <chrono>
#include <exception>
#include <sstream>

#include "kernels/positions.h"

namespace ssdo {

namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

bool parse_terms(const std::string& list, TermSelection& terms, std::string& error) {
  TermSelection t{false, false, false};
  std::stringstream ss(list);
  std::string item;
  bool any = false;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    any = true;
    if (item == "ao") t.ao = true;
    else if (item == "ssdo") t.ssdo = true;
    else if (item == "composite") t.composite = true;
    else if (item == "all") t = {true, true, true};
    else {
      error = "unknown term '" + item + "' (terms: ao, ssdo, composite, all)";
      return false;
    }
  }
  if (!any) {
    error = "no term selected (terms: ao, ssdo, composite, all)";
    return false;
  }
  terms = t;
  return true;
}

std::string to_string(const TermSelection& terms) {
  std::string s;
  auto add = [&](bool on, const char* name) {
    if (!on) return;
    if (!s.empty()) s += ",";
    s += name;
  };
  add(terms.ao, "ao");
  add(terms.ssdo, "ssdo");
  add(terms.composite, "composite");
  return s;
}

const cv::Mat* ComputedFrame::find(const std::string& name) const {
  for (const OutputTerm& t : terms)
    if (t.name == name) return &t.image;
  return nullptr;
}

ComputedFrame compute_frame(const GBuffer& g, const FrameRequest& request) {
  ComputedFrame frame;
  const int threads = request.threads;
  cv::Mat position_view = g.position_view;
  if (position_view.empty())
    view_positions_from_depth(g.depth_view, g.mask, g.camera, position_view, {}, threads);

  if (request.terms.ao || request.terms.composite) {
    const AoInputs in{g.depth_view, g.normal_view, position_view, g.mask, g.camera,
                      g.has_albedo() ? &g.albedo : nullptr};
    AoOutput ao;
    compute_ao(in, request.ao, ao, {}, threads);
    cv::Mat ao_denoised;
    denoise_bilateral(ao.ao, g.depth_view, g.normal_view, g.mask, request.denoise, ao_denoised, {},
                      threads);
    frame.terms.push_back({"ao", ao.ao, SampleType::float32, false});
    frame.terms.push_back({"ao_denoised", ao_denoised, SampleType::float32, false});
    if (!ao.bent_normal_view.empty())
      frame.terms.push_back({"bent_normal", ao.bent_normal_view, SampleType::half, true});
  }
  return frame;
}

FrameResult process_frame(const FrameRequest& request) {
  FrameResult result;
  result.input_path = request.input_path;
  result.output_path = request.output_path;
  try {
    auto t0 = std::chrono::steady_clock::now();
    ReadOptions read = request.read;
    ReadResult frame = read_gbuffer(request.input_path, read);
    result.times.read_ms = ms_since(t0);
    result.info = frame.info;
    if (!frame.ok()) {
      result.error = frame.error;
      return result;
    }

    t0 = std::chrono::steady_clock::now();
    ComputedFrame computed = compute_frame(frame.gbuffer, request);
    result.times.compute_ms = ms_since(t0);

    if (!request.output_path.empty()) {
      t0 = std::chrono::steady_clock::now();
      const std::string err =
          write_outputs(request.output_path, computed.terms, frame.gbuffer.camera, request.write);
      result.times.write_ms = ms_since(t0);
      if (!err.empty()) {
        result.error = err;
        return result;
      }
      for (const OutputTerm& t : computed.terms) result.terms_written.push_back(t.name);
    }
  } catch (const std::exception& e) {
    result.error = request.input_path + ": " + e.what();
  }
  return result;
}

}  // namespace ssdo
