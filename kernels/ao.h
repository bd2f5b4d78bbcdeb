// Ambient occlusion: the settings, presets and entry point shared by every method.
// A method is a value of AoSettings::method, not a separate code path to copy; each
// method's core lives in its own file (ao_hemisphere.cpp, ao_hbao.cpp, ao_gtao.cpp,
// ao_raymarch.cpp) behind compute_ao().
//
// Convention: AO in [0, 1], 1 = unoccluded; the cosine-weighted fraction of the
// normal's hemisphere that is free of occluders within radius_world (as Cycles' AO pass).
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <string_view>

#include <opencv2/core.hpp>

#include "core/camera.h"
#include "kernels/thickness.h"

namespace ssdo {

enum class AoMethod { hemisphere, hbao, gtao, raymarch };
enum class Preset { low, medium, high, ultra };
// How deep a visible surface is taken to be behind its stored depth, where the frame has no
// second depth layer (AoInputs::depth_back_view): AoSettings::thickness_world, or estimated
// from the frame's silhouettes (kernels/thickness.h).
enum class ThicknessModel { constant, silhouettes };

std::string_view to_string(AoMethod m);
std::string_view to_string(Preset p);
std::optional<AoMethod> parse_ao_method(std::string_view s);
std::optional<Preset> parse_preset(std::string_view s);

// Defaults and presets were chosen against the ray-traced AO of Cycles (binary, cosine-
// weighted, within 1 unit) on the three shared 640x360 dumps (cornell, greeble, depthgap)
// and against this project's raymarch oracle (which isolates the screen-space estimator's
// error from what no screen-space method can see: off-screen and hidden geometry), by
// mean absolute error over foreground pixels, as XeGTAO tuned its defaults against a
// ray-traced reference. Only coarse, scale-free choices were made (thickness as a multiple
// of the radius from {0.25, 0.5, 1, inf}; tap distribution power from {1, 2}), so the
// values carry to scenes of any scale and field of view.
struct AoSettings {
  AoMethod method = AoMethod::gtao;
  // Radius of the occlusion sphere, scene units, (0, inf). Occluders farther than this
  // from the shaded point do not count. 1.0 matches the Cycles AO distance default.
  float radius_world = 1.0f;
  // Largest projected radius, pixels of the picture, [2, 4096]: bounds the cost of
  // close-up pixels, and reaches as far on every grid (compute_ao counts pixels of the
  // images it gets; compute_terms gives a method on the half grid half as many texels).
  float max_radius_px = 512.0f;
  // Hemisphere: samples per pixel, [1, 1024].
  int samples = 16;
  // HBAO directions / GTAO slices (each slice = 2 directions) / raymarch directions, [1, 4096].
  int directions = 4;
  // Steps per direction (HBAO, GTAO, raymarch), [1, 1024].
  int steps = 8;
  // GTAO: a pixel's estimate also takes the slices of the 3x3 texels around it on its
  // surface, as a control variate: AO = R + (v - R o) / slices, R their ratio of visible to
  // open measure, v and o the pixel's own sums (ao_gtao.cpp). The neighbours' slice angles
  // take out most of the noise and the bias of a ratio over few slices; the pixel's own
  // term keeps the expectation its own (no blur across the texels). For presets of one
  // slice (low); from two slices on it changes little (docs/accuracy.md).
  bool pool_slices = false;
  // Assumed thickness of every surface seen in the depth buffer, scene units, [0, inf]:
  // a point farther than this behind the stored depth is free space (infinity = height
  // field: everything behind a visible surface is solid). 0 (default) = automatic:
  // kThicknessPerRadius * radius_world (see effective_thickness_world()).
  float thickness_world = 0.0f;
  // Where the frame has no second depth layer, the methods that read one (GTAO, raymarch;
  // reads_back_layer) take it from the frame's silhouettes on the grid they run on
  // (silhouettes), or take thickness_world everywhere (constant). The GTAO presets use the
  // silhouettes: against Cycles they cut GTAO's error by a third at equal taps
  // (docs/accuracy.md, "Thickness from silhouettes"). Constant by default here, so that the
  // closed-form scenes of the tests keep their one constant.
  ThicknessModel thickness_model = ThicknessModel::constant;
  SilhouetteThicknessSettings silhouettes;  // the estimate's settings
  // Fraction of the radius over which occluders fade out, [0, 1] (0 = hard cut like
  // Cycles). Used by the height-field estimators (hemisphere, HBAO, GTAO with infinite
  // thickness); GTAO's visibility mask and raymarch cut at the radius exactly. 0 by
  // default: the reference is a hard cut, and a fade only brightens (HBAO high against the
  // raymarch oracle on cornell: MAE 0.057 with 0.2, 0.035 with 0).
  float falloff_fraction = 0.0f;
  // Depth bias relative to the pixel's depth, [0, 0.1]: rejects self-occlusion from depth
  // quantisation (a relative bias holds for float and half-float depth alike; half floats
  // round to 4.9e-4 of the value, the default 1e-3 covers that twice).
  float depth_bias_relative = 1e-3f;
  // Grid the method runs on, [1, 2]: 1 = every pixel; 2 = one pixel of each 2x2 block
  // (a quarter of the work), then a depth- and normal-aware upsample to full resolution
  // (compute_terms, kernels/half_resolution.h; compute_ao itself runs on the grid it gets).
  // AO varies at the scale of the radius, usually many pixels, so half resolution loses
  // little away from thin features (measured in the settings' tests and the benchmarks).
  int resolution_divisor = 1;
  // Multi-bounce approximation (Jimenez et al. 2016, eq. 10) when albedo is given.
  bool multibounce = false;
  // Noise seed: outputs are a pure function of (inputs, settings, seed).
  uint32_t seed = 0;
};

// The automatic thickness, as a multiple of the radius: an occluder within the radius is
// taken to be half a radius deep. Against Cycles on the shared frames, the raymarch oracle's
// MAE with thickness {0.25, 0.5, 1, inf} x radius was lowest at 0.5 on every frame (cornell
// 0.060 vs 0.073 at 1 and 0.110 at inf; depthgap 0.008 vs 0.019 at 1 and 0.095 at inf: a
// height field puts halos round every floating object). Relative to the radius so that a
// scene of another scale, with its AO distance, keeps the same behaviour.
inline constexpr float kThicknessPerRadius = 0.5f;

// thickness_world, or kThicknessPerRadius * radius_world when it is 0 (automatic).
float effective_thickness_world(const AoSettings& s);

// The method runs on the half-resolution grid (resolution_divisor 2; raymarch, the oracle,
// always at full resolution).
bool runs_on_half_grid(const AoSettings& s);
// Whether the method writes a bent normal (every method but the hemisphere's point samples).
bool has_bent_normal(const AoSettings& s);
// Whether the method reads a second depth layer, given or estimated (GTAO's visibility mask
// and raymarch: the methods that model an occluder's thickness per tap).
bool reads_back_layer(const AoSettings& s);
// Whether compute_ao estimates the second depth layer from silhouettes when it gets none.
bool estimates_back_layer(const AoSettings& s);

// The named presets of each method (values of AoSettings).
AoSettings ao_preset(AoMethod method, Preset preset);

// Returns an empty string when the settings are valid, else what is wrong (field, value,
// range). Called once at the boundary; kernels only assert.
std::string validate(const AoSettings& s);

struct AoInputs {
  const cv::Mat& depth_view;     // CV_32FC1 planar depth (+inf on background)
  const cv::Mat& normal_view;    // CV_32FC3 unit view-space normals
  const cv::Mat& position_view;  // CV_32FC3 view-space positions (view_positions_from_depth)
  const cv::Mat& mask;           // CV_8UC1, 255 = foreground
  const Camera& camera;
  const cv::Mat* albedo = nullptr;  // CV_32FC3 or null (multi-bounce only)
  // CV_32FC1 second depth layer (GBuffer::depth_back_view, or one estimated) or null. When
  // given, the methods that model occluder thickness (reads_back_layer: raymarch, GTAO's
  // visibility mask) take each tap's own thickness depth_back_view - depth_view instead of
  // thickness_world (+inf back = solid behind). Null with ThicknessModel::silhouettes:
  // compute_ao estimates it.
  const cv::Mat* depth_back_view = nullptr;
  // Where the picture's pixel (0, 0) lies in these images: (0, 0) for a whole frame; plus the
  // widths of the left and top sides of a guard band of off-screen texels
  // (kernels/multiview.h, extend_with_views); minus a crop's offset in the picture
  // (GBuffer::data_origin_px, in these images' pixels). The per-pixel noise is a function of
  // the picture's pixel, so a band changes only the pixels whose taps reach it, and a crop
  // gets the whole frame's noise.
  cv::Point frame_origin_px{0, 0};
};

struct AoOutput {
  cv::Mat ao;                // CV_32FC1 in [0,1], 1 = unoccluded; 1 on background
  cv::Mat bent_normal_view;  // CV_32FC3 unit view-space bent normal, or empty when the
                             // method has none; (0,0,0) on background
};

// Computes AO for the pixels of `roi` (empty = all) with the method in settings, on the
// grid of the inputs (resolution_divisor is compute_terms' to apply). Output images are
// allocated at the input size when empty; only roi is written. Without a second depth
// layer and with estimates_back_layer(settings), the layer is first estimated over the
// whole grid (estimate_back_depth; about 2 ms for a 960 x 540 grid on two cores).
void compute_ao(const AoInputs& in, const AoSettings& settings, AoOutput& out,
                cv::Rect roi = {}, int nthreads = 0);

}  // namespace ssdo
