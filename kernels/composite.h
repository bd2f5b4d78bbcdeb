// The composite: outgoing radiance of each pixel from the selected light terms.
//
//   composite = sum over the selected terms t of weight_t x term_t, with
//     ambient        albedo x ambient_radiance              (unshadowed ambient light)
//     ambient_ao     albedo x ambient_radiance x AO          (SSAO)
//     ssdo_direct    albedo x direct                         (SSDO direct, Cycles DiffDir convention)
//     ssdo_indirect  albedo x indirect                       (SSDO bounce, Cycles DiffInd convention)
//     lighting       the frame's own lighting (outgoing radiance from lamps, already x albedo)
// With every weight 1 this is albedo x (ambient x AO + direct) + albedo x indirect + lighting:
// Cycles' DiffCol x (DiffDir + DiffInd) when the terms are SSDO direct and indirect. The
// seed course's display modes are term lists (composite_mode_terms): OFF = {ambient},
// SSAO = {ambient_ao}, SSDO = {ssdo_direct, ssdo_indirect},
// SSAO+SSDO = {ambient_ao, ssdo_direct, ssdo_indirect}.
//
// Inputs, and what a missing (null or empty) one means:
//   mask         required (its size is the frame's); 0 = background.
//   albedo       optional: missing = white (1, 1, 1).
//   ao           optional: missing = 1 (unoccluded) for ambient_ao.
//   direct, indirect, lighting
//                required by the term that reads them; validate() names a selected term
//                whose input is missing (an error, not a silent zero). Unselected: unused.
//   background   optional: radiance of background pixels (e.g. Cycles' Env pass).
//   environment  optional, with camera: background pixels see the environment along their
//                view ray (used when `background` is missing). Both missing: background = 0.
// Units: radiance in the environment's units, linear RGB; output CV_32FC3.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "kernels/environment.h"

namespace ssdo {

enum class CompositeTerm { ambient, ambient_ao, ssdo_direct, ssdo_indirect, lighting };
enum class CompositeMode { off, ssao, ssdo, ssao_ssdo };

std::string_view to_string(CompositeTerm t);
std::string_view to_string(CompositeMode m);
std::optional<CompositeTerm> parse_composite_term(std::string_view s);
std::optional<CompositeMode> parse_composite_mode(std::string_view s);

struct WeightedTerm {
  CompositeTerm term = CompositeTerm::ssdo_direct;
  float weight = 1.0f;  // multiplier, [0, 16]
};

// The term list of a display mode, every weight 1.
std::vector<WeightedTerm> composite_mode_terms(CompositeMode mode);

struct CompositeSettings {
  // The terms to add, each at most once. Default: SSDO direct + indirect (the Cycles sum).
  std::vector<WeightedTerm> terms = composite_mode_terms(CompositeMode::ssdo);
  // Radiance of the uniform ambient light of the ambient terms (RGB, >= 0). 1 = the white
  // sky under which AO is defined (ambient_ao then equals albedo x AO); a frame's composite
  // takes its environment's mean radiance (Environment::mean_radiance).
  glm::vec3 ambient_radiance{1.0f};
};

struct CompositeInputs {
  const cv::Mat& mask;                  // CV_8UC1, 255 = foreground
  const cv::Mat* albedo = nullptr;      // CV_32FC3
  const cv::Mat* ao = nullptr;          // CV_32FC1 in [0, 1]
  const cv::Mat* direct = nullptr;      // CV_32FC3 (SsdoOutput::direct)
  const cv::Mat* indirect = nullptr;    // CV_32FC3 (SsdoOutput::indirect)
  const cv::Mat* lighting = nullptr;    // CV_32FC3 outgoing radiance from the frame's lamps
  const cv::Mat* background = nullptr;  // CV_32FC3
  const Environment* environment = nullptr;
  const Camera* camera = nullptr;       // needed with `environment`
};

// Empty when the settings are valid for these inputs, else what is wrong (a term twice, a
// weight out of range, a selected term's input missing or of the wrong type/size).
std::string validate(const CompositeInputs& in, const CompositeSettings& s);

// Writes the composite of roi (empty = all) into out (CV_32FC3, allocated at the mask's size
// when empty or of another size/type). Inputs must pass validate(). Per-pixel arithmetic
// only: identical for any nthreads.
void compute_composite(const CompositeInputs& in, const CompositeSettings& s, cv::Mat& out,
                       cv::Rect roi = {}, int nthreads = 0);

}  // namespace ssdo
