// Screen-space directional occlusion (Ritschel, Grosch and Seidel 2009, "Approximating
// Dynamic Global Illumination in Image Space", I3D): directional environment light with
// screen-space visibility (direct) and one diffuse bounce between the surfaces the depth
// buffer shows (indirect).
//
// Light units (the Cycles light-pass convention, DESIGN.md "Light terms"):
//   direct(P)   = E_env(P) / pi   = (1/pi) integral over the hemisphere of L_env(w) V(w) cos dw
//   indirect(P) = E_bounce(P) / pi = (1/pi) integral of L_sender(w) cos dw
// i.e. irradiance over pi, "divided by albedo": a white unoccluded surface under a uniform
// environment of radiance 1 has direct = 1, and the outgoing diffuse radiance of P is
// albedo(P) x (direct + indirect). Both are CV_32FC3 RGB in the environment's radiance units.
//
// Estimators (method = ssdo). N sample directions w_i, cosine-distributed about the normal n
// (pdf cos / pi; R2 sequence, rotated per pixel), each tested at k points
// P + lambda_ij w_i, lambda_ij = m (j + xi_i) / (k - 1 + xi_i), xi_i uniform in (0, 1], m
// the part of r that projects on screen, r = radius_world clamped to max_radius_px on
// screen. k = 1 is the paper's single point at a uniform distance in (0, r]; k > 1 marches
// the radius, its last point at m. The first point found behind the depth buffer (within
// the thickness) makes w_i occluded; sample_refinements bisection steps then locate where
// w_i enters the occluder, and its pixel q is the sender (surface point P_q, normal n_q,
// outgoing radiance L_q). Bisection also searches between a point in front of the depth
// buffer and the next one farther behind it than the thickness (the ray crossed a surface
// between two points). Points over background or off screen see nothing (the screen
// cannot tell), so a direction with no occluded point is visible.
//   direct   = (1/N) sum_{i visible} L_env,filtered(w_i)
//     (the Monte-Carlo estimate of E/pi with pdf cos/pi: the cos and the pi cancel; paper
//     eq. 1 with cosine-weighted instead of uniform directions). A white surface with no
//     occluder under L = 1 gets exactly 1. L_env,filtered is Environment::radiance_filtered,
//     whose cone should match the footprint 2 pi / N of a sample
//     (filter_cone_half_angle_for_samples(N); the 15 deg default suits N ~ 30).
//     Variant bent_normal: (visible / N) x E_tab(bent normal) / pi, bent normal = normalised
//     sum of the visible w_i. Variant open_minus_occluded (default), a control variate:
//       direct = max(0, E_tab(n) / pi - (1/N) sum_{i occluded} L_env,filtered(w_i))
//     (same expectation up to the filter and table errors, exact where nothing is occluded;
//     E_tab: Environment::irradiance_over_pi, the tabulated cosine convolution).
//   indirect, solid angle (default): the radiance arriving from an occluded direction is the
//     occluder's, so with the same cosine-distributed directions
//       indirect = (1/N) sum_{i occluded, n_q . (P - P_q) > 0} L_q
//     (no area or distance heuristic; with k large it is the oracle's estimator).
//   indirect, form factor (paper eq. 2): each occluded sample is a patch of area
//     A_s = pi r^2 / N at P_q sending towards P:
//       E_bounce = sum_i L_q A_s cos(theta_s) cos(theta_r) / max(d^2, d_min^2)
//       indirect = E_bounce / pi = (r^2 / N) sum_i L_q cos(theta_s) cos(theta_r) / max(d^2, d_min^2)
//     with d = |P - P_q|, cos(theta_s) = n_q . (P - P_q) / d (<= 0: back-facing, no
//     contribution), cos(theta_r) = n . (P_q - P) / d, d_min = sender_distance_min_world
//     (the paper clamps d to 1 to bound the singularity of the point-to-patch form factor).
// Sender radiance L_q: `lighting` when given (outgoing diffuse radiance, e.g. Cycles
// DiffCol x DiffDir); otherwise a first pass of this kernel over the whole image,
// L_q = albedo_q x direct_q (albedo white when absent), so the bounce needs only depth,
// normals and albedo.
//
// Oracle (method = oracle): g x g stratified cosine-distributed directions, each marched in
// `oracle_steps` steps up to r; the first step behind the depth buffer (same occlusion test)
// ends the ray: it gives the sender pixel, the direction contributes its sender's radiance
// to indirect (if the sender faces P) and nothing to direct; a ray that leaves the radius,
// the screen or meets only background contributes the unfiltered L_env(w) to direct. This is
// the screen-space best case of both terms, to separate estimator error from what the
// screen lacks (hidden surfaces, off-screen geometry, occluders farther than r).
//
// Occlusion test of a point S seen at pixel q: S is occluded when it lies behind the
// surface stored at q by more than depth_bias_relative x depth(S) and by less than
// thickness_world. The surface depth at S's exact sub-pixel position is taken from q's
// tangent plane (position_view and normal_view of q) for perspective cameras, so flat
// surfaces do not shadow themselves at grazing angles; the pixel's stored depth otherwise.
// Method ssdo reads the march's taps farther than 16 px from P in a pyramid of the depth
// buffer (each texel one full-resolution pixel of its 2x2 children, as in McGuire et al.
// 2012, "Scalable Ambient Obscurance"), for cache locality; its bisection steps and the
// oracle always read full resolution.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>

#include <opencv2/core.hpp>

#include "kernels/ao.h"  // Preset
#include "core/camera.h"
#include "kernels/environment.h"

namespace ssdo {

enum class SsdoMethod { ssdo, oracle };
enum class SsdoDirectEstimator {
  per_sample,   // (1/N) sum over visible samples of the cone-filtered radiance (paper)
  bent_normal,  // visible fraction x E_tab(bent normal) / pi: smooth, biased in corners
  // E_tab(n) / pi - (1/N) sum over occluded samples of the cone-filtered radiance: the
  // unoccluded integral from the irradiance table, Monte Carlo only for what is occluded (a control
  // variate); no filter bias and no noise on open surfaces.
  open_minus_occluded,
};
enum class SsdoIndirectEstimator { form_factor, solid_angle };

std::string_view to_string(SsdoMethod m);
std::optional<SsdoMethod> parse_ssdo_method(std::string_view s);

struct SsdoSettings {
  SsdoMethod method = SsdoMethod::ssdo;
  // r_max: radius of the sampled hemisphere, scene units, (0, inf). Occluders and senders
  // farther than this from P are not seen. 1.0 = the Cycles AO distance of the reference dumps.
  float radius_world = 1.0f;
  // Largest projected radius, pixels of the picture, [2, 4096]: close to the camera r
  // shrinks so that r x pixels_per_unit <= max_radius_px (bounds the spread of the taps in
  // memory; on the half grid half as many texels, as AoSettings::max_radius_px).
  float max_radius_px = 512.0f;
  // N: samples (directions) per pixel (method ssdo), [1, 1024].
  int samples = 16;
  // k: points tested per sample direction (method ssdo), [1, 64]. 1 = the paper's single
  // point at a uniform distance in (0, r]; k > 1 = a stratified march over the whole radius
  // (first point behind the depth buffer decides), k times the taps, much closer to ray
  // visibility (see the measurements in the tests).
  int sample_steps = 4;
  // Bisection steps that locate where a sample direction enters its occluder, between the
  // last visible and the first occluded point, [0, 16]: the sender pixel is that entry
  // point's. 0 = the first occluded point of the k (biased dark: see ssdo.cpp).
  int sample_refinements = 3;
  // Assumed thickness of every surface in the depth buffer, scene units, (0, inf]: a point
  // farther than this behind the stored depth is not occluded (avoids dark halos around
  // foreground objects in front of a distant background; inf = height field).
  float thickness_world = 1.0f;
  // Depth bias relative to the sample's depth, [0, 0.1]: rejects self-occlusion from depth
  // quantisation (relative, so it holds for float and half-float depth alike).
  float depth_bias_relative = 1e-3f;
  // Multiplier of the indirect term, [0, 16]. 1 = physically based.
  float indirect_strength = 1.0f;
  // d_min of the form-factor estimator, scene units, [0, inf): distances below it are
  // clamped. The paper clamps at 1; with r = 1 (every sender closer than 1) that scales the
  // bounce down by 70-90% on the ray-caster scenes, 0.25 was the least wrong of 1, 0.5,
  // 0.25 and 0.1 with k <= 4. Unused by the solid-angle estimator and the oracle.
  float sender_distance_min_world = 0.25f;
  // Default open_minus_occluded: exact on open surfaces (no cone-filter bias: per_sample
  // with the 15 deg cone is up to 7% off on an open plane under the Cycles sky), and within
  // noise of per_sample and bent_normal where occluded (ssdo_test.cpp measures all three).
  SsdoDirectEstimator direct_estimator = SsdoDirectEstimator::open_minus_occluded;
  // Default solid_angle: against the oracle it has about half the error of the form factor
  // (whose area heuristic A_s = pi r^2 / N has no exact meaning for screen samples).
  SsdoIndirectEstimator indirect_estimator = SsdoIndirectEstimator::solid_angle;
  // 1 = every pixel; 2 = method ssdo runs on the half-resolution grid (a quarter of the
  // pixels) and a depth- and normal-aware upsample fills the pixels in between (compute_terms,
  // kernels/half_resolution.h). The oracle always runs at full resolution.
  int resolution_divisor = 1;
  // Oracle: g, the directions per axis of the stratified grid (g^2 directions), [1, 256],
  // and the steps per direction, [1, 4096].
  int oracle_grid = 16;
  int oracle_steps = 64;
  // Noise seed: outputs are a pure function of (inputs, settings, seed).
  uint32_t seed = 0;
};

// The named presets (values of SsdoSettings) of each method.
SsdoSettings ssdo_preset(SsdoMethod method, Preset preset);

// Returns an empty string when the settings are valid, else what is wrong (field, value,
// range). Called once at the boundary; the kernel only asserts.
std::string validate(const SsdoSettings& s);

// The method runs on the half-resolution grid (resolution_divisor 2, method ssdo; the
// oracle always at full resolution).
bool runs_on_half_grid(const SsdoSettings& s);

struct SsdoInputs {
  const cv::Mat& depth_view;     // CV_32FC1 planar depth (+inf on background)
  const cv::Mat& normal_view;    // CV_32FC3 unit view-space normals
  const cv::Mat& position_view;  // CV_32FC3 view-space positions (view_positions_from_depth)
  const cv::Mat& mask;           // CV_8UC1, 255 = foreground
  const Camera& camera;
  const Environment& environment;
  const cv::Mat* albedo = nullptr;    // CV_32FC3 or null (= white): sender albedo
  const cv::Mat* lighting = nullptr;  // CV_32FC3 or null: sender outgoing radiance
  // CV_32FC1 second depth layer (GBuffer::depth_back_view) or null: each tap's occluder is
  // back - front of the pixel it reads instead of thickness_world (depth peeling, Ritschel
  // et al. 2009, sec. 3.3).
  const cv::Mat* depth_back_view = nullptr;
  // Where the picture's pixel (0, 0) lies in these images (AoInputs::frame_origin_px): the
  // per-pixel noise is a function of the picture's pixel.
  cv::Point frame_origin_px{0, 0};
};

struct SsdoOutput {
  cv::Mat direct;    // CV_32FC3, E_env / pi (see above); 0 on background
  cv::Mat indirect;  // CV_32FC3, E_bounce / pi x indirect_strength; 0 on background
};

// Computes direct and indirect for the pixels of `roi` (empty = all), on the grid of the
// inputs (resolution_divisor is compute_terms' to apply). Outputs are allocated
// at the input size when empty or of another size/type; only roi is written. Without
// `lighting` a first pass computes direct over the whole image (the senders of roi may lie
// anywhere on screen). The result does not depend on nthreads or roi.
void compute_ssdo(const SsdoInputs& in, const SsdoSettings& settings, SsdoOutput& out,
                  cv::Rect roi = {}, int nthreads = 0);

}  // namespace ssdo
