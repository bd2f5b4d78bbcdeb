#include "kernels/ssdo.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/ssdo.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include "kernels/settings_check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numbers>
#include <optional>
#include <utility>
#include <vector>

#include "kernels/hemisphere_sampling.h"
#include "kernels/iota_lanes.h"
#include "kernels/noise.h"
#include "kernels/record_lanes.h"
#include "core/enum_names.h"
#include "core/parallel.h"
#include "core/uninitialized.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

// validate()'s bound on sample_steps; the march's per-pixel arrays are sized by it.
constexpr int kMaxSampleSteps = 64;
namespace {

// Largest relative change of the surface depth that q's tangent plane may apply at a
// sub-pixel offset of at most half a pixel. A plane seen at an angle a from grazing changes
// depth by ~(pixel angle) / tan(a) per pixel: at 160 px and 60 deg (pixel angle 0.0065 rad)
// that is 4.7% at 8 deg and 19% at 2 deg, so half a pixel stays below 25% down to ~1.5 deg.
// The bound keeps silhouette pixels of curved surfaces (tangent plane almost parallel to the
// ray) from extrapolating far beyond the pixel.
constexpr float kPlaneCorrectionMaxRelative = 0.25f;

// What a tap reads of a texel: one 8-byte record (taps scatter over up to max_radius_px
// around the pixel, and their cache misses are a large part of the kernel's cost: eight
// records per cache line, and a tile's taps fit the first-level cache twice as well as
// with 16 bytes). For a plane seen in perspective, 1 / depth is an affine function of the
// pixel coordinates, so a tangent plane gives the surface depth anywhere near the texel's
// centre from the depth there, d, and the plane's relative screen gradients g = d x
// d(1 / depth) / d(pixel): 1 / depth = (1 + g . offset) / d (test_lanes).
struct TapTexel {
  float depth_view;  // planar depth at the texel's centre; +inf where mask = 0 (nothing there)
  // g (x in the low 16 bits, y in the high), each as bfloat16 (a float's upper 16 bits,
  // rounded: 8 significant bits); 0 where the plane is not used. The correction g . offset
  // is at most kPlaneCorrectionMaxRelative of the depth where it is applied, so the
  // rounding moves the surface by at most 2^-9 x 0.25 = 5e-4 of its depth, below the depth
  // bias' 1e-3 (by 2e-6 of the depth for a plane at 60 deg from the view, within a pixel).
  uint32_t gradient;
};
static_assert(sizeof(TapTexel) == 8);

// v's upper 16 bits, rounded to nearest even (bfloat16; v finite).
inline uint32_t bfloat16_bits(float v) {
  uint32_t u;
  std::memcpy(&u, &v, sizeof(u));
  return (u + 0x7FFFu + ((u >> 16) & 1u)) >> 16;
}

// What a sender contributes needs its position and normal: read only for occluded samples.
struct SenderTexel {
  glm::vec3 position_view;
  glm::vec3 normal_view;
};

// Taps far from the receiver read a coarser level of a pyramid of TapTexels (McGuire et
// al. 2012, "Scalable Ambient Obscurance", sec. 4.3): nearby texels of one level share
// cache lines, which the scattered far taps of a large radius otherwise miss. Level l has
// ceil(size / 2^l) texels; each keeps the tangent plane of one full-resolution pixel of
// its 2x2 children (its source: the rotated-grid choice of SAO, no averaging across depth
// edges), evaluated at the texel's centre. A tap at a distance rho from the receiver's pixel
// reads level floor(log2(rho / kMipStartPx)) + 1 when rho >= kMipStartPx, else level 0:
// the contact region, where occlusion changes fastest, is always read at full resolution.
constexpr float kMipStartPx = 16.0f;

// Pixels are visited in tiles kTileWidthPx wide and kStripRows high (strips of kStripRows
// rows, tile by tile along them; one thread walks its whole range of rows tile column by
// tile column): the taps of a tile's pixels overlap, so a tile reuses texels from cache
// that row-by-row order (whose taps span 2 r rows of the whole width) fetches again.
// 128 px wide tiles of these 8-byte texels suit the cache better than 32, 64 or 256.
constexpr int kTileWidthPx = 128;
constexpr int kStripRows = 32;
constexpr int kMaxLevels = 8;

// A pixel's sample directions are marched kSampleBatch at a time: first every point of
// every direction of the batch is tested (loops without branches over up to
// kSampleBatch x kMaxSampleSteps points, which vectorise and whose texel reads and
// divisions overlap), then each direction's march reads its points' results in order (the
// points after the one that decides are tested but not used).
constexpr int kSampleBatch = 8;

// The sender pass records each sample's sender when the record fits this budget (N x 4
// bytes per pixel); above it the receiver pass marches again: same result, more time.
constexpr size_t kRecordBudgetBytes = size_t(256) << 20;

// The tap pyramid (method ssdo) and the senders' records of one frame, allocated once per
// call, outside the per-pixel loops. The levels lie one below the other in one array of
// rows of `width` texels: with H' = the height rounded up to a multiple of 2^(n_levels - 1),
// level l has H' / 2^l rows from row 2 H' - 2 H' / 2^l on (its texels at the start of each
// row), so that a tap's texel index is arithmetic, without a table per level.
struct TapPyramid {
  int width = 0;
  int n_levels = 1;  // 1 = no pyramid (the oracle reads full resolution only)
  int level_width[kMaxLevels] = {}, level_height[kMaxLevels] = {};
  int64_t rows_2h = 0;  // 2 H'
  UninitializedVector<TapTexel> taps;
  UninitializedVector<SenderTexel> senders;  // row-major, width per row, every pixel
  std::vector<float> thickness;  // per texel of `taps` (Constants::pyramid_thickness), or empty

  size_t level_row(int l, int y) const { return size_t(rows_2h - (rows_2h >> l) + y) * size_t(width); }
};

// Per-frame constants: the views, the camera folded into matrices, the settings.
struct Constants {
  const TapTexel* pyramid;     // TapPyramid::taps
  // Per texel of the pyramid, the thickness of its source pixel's occluder from the second
  // depth layer (SsdoInputs::depth_back_view), or null: s.thickness_world everywhere.
  const float* pyramid_thickness;
  int pyramid_rows_2h;         // TapPyramid::rows_2h
  int n_levels;
  const SenderTexel* senders;  // row-major, width_px per row
  const cv::Mat* depth;
  const cv::Mat* normal;
  const cv::Mat* position;
  const cv::Mat* mask;
  const cv::Mat* albedo;    // may be null
  const cv::Mat* lighting;  // may be null
  const Camera* camera;
  const Environment* env;
  glm::mat4 clip_from_view;
  glm::mat3 env_from_view;  // = env_from_world * world_from_view (Camera::world_from_view_direction)
  float width_px, height_px;
  SsdoSettings s;
  // The estimators the settings select, and d_min^2 of the form factor.
  bool bent_normal;
  bool control_variate;  // open_minus_occluded
  // E_tab(n) / pi at each pixel's normal n (CV_32FC3; irradiance_at_normals) for
  // open_minus_occluded lit by a map or a sky, else null: looked up per pixel then.
  const cv::Mat* irradiance_at_normal;
  bool form_factor;
  float sender_distance_min2_world;
  // (cos, sin) of 2 pi a2 i for the samples i of the R2 sequence (a2 its second
  // generator): a pixel's azimuths 2 pi (shift_v + a2 i) are these rotated by 2 pi shift_v,
  // so the sample loop needs no trig (the fractional part the sequence takes does not
  // change an angle's cosine or sine).
  const float* azimuth_cos;
  const float* azimuth_sin;
  cv::Point frame_origin_px;  // SsdoInputs::frame_origin_px: the noise is the frame pixel's
  StratifiedNoise noise;      // of s.seed: a pixel's shift of the R2 sequence (sample_shift)
};
// Cosine-distributed direction (pdf cos / pi) from (u, v) in [0, 1)^2 (Malley's method).
inline glm::vec3 cosine_direction(float u, float v, const glm::vec3& t, const glm::vec3& b,
                                  const glm::vec3& n) {
  const float radius = std::sqrt(u);
  const float phi = 2.0f * std::numbers::pi_v<float> * v;
  return t * (radius * std::cos(phi)) + b * (radius * std::sin(phi)) + n * std::sqrt(std::max(0.0f, 1.0f - u));
}

// The length of the part of [0, r] over which the point clip_p + lambda clip_w (homogeneous
// clip coordinates of a ray from an on-screen receiver) stays inside the view frustum's side
// planes, -w <= x, y <= w, w > 0 (Liang and Barsky 1984, "A New Concept and Method for
// Line Clipping", ACM TOG 3(1): each plane a + lambda b >= 0 bounds lambda by -a / b when b < 0).
// Slightly shortened so that the end point itself projects inside the frame.
// Without branches, so that a loop over directions vectorises.
inline float on_screen_length(const glm::vec4& clip_p, const glm::vec4& clip_w, float r) {
  float lambda_max = r;
  auto bound = [&](float a, float b) {
    const float limit = std::min(lambda_max, std::max(0.0f, -a / b));
    lambda_max = b < 0.0f ? limit : lambda_max;
  };
  bound(clip_p.w - clip_p.x, clip_w.w - clip_w.x);
  bound(clip_p.w + clip_p.x, clip_w.w + clip_w.x);
  bound(clip_p.w - clip_p.y, clip_w.w - clip_w.y);
  bound(clip_p.w + clip_p.y, clip_w.w + clip_w.y);
  bound(clip_p.w, clip_w.w);
  return lambda_max * (1.0f - 1e-4f);
}

// visible: in front of the surface the screen shows there (or over background);
// occluded: behind it by more than the depth bias and less than the thickness; behind:
// farther behind it than the thickness (taken as passing behind a thin surface);
// off_screen: the point projects outside the frame (or behind the eye); a straight ray
// whose point has left the frame does not come back, so marches stop there.
enum class Tap { visible, occluded, behind, off_screen };

// Outgoing radiance of sender pixel q (see ssdo.h).
inline glm::vec3 sender_radiance(const Constants& c, const cv::Mat& sender_direct, int qx, int qy) {
  if (c.lighting) {
    const cv::Vec3f& l = c.lighting->at<cv::Vec3f>(qy, qx);
    return {l[0], l[1], l[2]};
  }
  const cv::Vec3f& d = sender_direct.at<cv::Vec3f>(qy, qx);
  glm::vec3 l(d[0], d[1], d[2]);
  if (c.albedo) {
    const cv::Vec3f& a = c.albedo->at<cv::Vec3f>(qy, qx);
    l *= glm::vec3(a[0], a[1], a[2]);
  }
  return l;
}

inline glm::vec3 to_glm(const cv::Vec3f& v) { return {v[0], v[1], v[2]}; }

// The effective radius at P: radius_world, shrunk so that it spans at most max_radius_px.
inline float effective_radius(const Constants& c, float depth_view) {
  const glm::vec2 ppu = c.camera->pixels_per_unit(depth_view);
  const float ppu_max = std::max(ppu.x, ppu.y);
  return std::min(c.s.radius_world, c.s.max_radius_px / ppu_max);
}

// A receiver P at pixel (x, y): its view-space position and normal and the radius r there.
struct Receiver {
  glm::vec3 p, n;
  float r;
};

inline Receiver receiver_at(const Constants& c, int x, int y) {
  const glm::vec3 p = to_glm(c.position->at<cv::Vec3f>(y, x));
  const glm::vec3 n = to_glm(c.normal->at<cv::Vec3f>(y, x));
  return {p, n, effective_radius(c, c.depth->at<float>(y, x))};
}

// What the rays from a receiver share: the tangent frame (t, b, n), P in clip coordinates
// and the pixel's centre.
struct RayFrame {
  glm::vec3 t, b;
  glm::vec4 clip_p;
  glm::vec2 origin_px;
};

inline RayFrame ray_frame(const Constants& c, const Receiver& rcv, int x, int y) {
  RayFrame f;
  sampling::orthonormal_basis(rcv.n, f.t, f.b);
  f.clip_p = c.clip_from_view * glm::vec4(rcv.p, 1.0f);
  f.origin_px = glm::vec2(float(x) + 0.5f, float(y) + 0.5f);
  return f;
}

// The indirect light an occluded sample brings from its sender pixel q (P_q, n_q, L_q),
// added to indirect_sum: L_q (solid angle), or L_q cos(theta_s) cos(theta_r) / max(d^2,
// d_min^2) (form factor, paper eq. 2, its constant A_s / pi applied once per pixel).
inline void add_sender(const Constants& c, const Receiver& rcv, const cv::Mat& sender_direct, int qx, int qy,
                       glm::vec3& indirect_sum) {
  const int width = int(c.width_px);
  const SenderTexel& sender = c.senders[size_t(qy) * size_t(width) + size_t(qx)];
  const glm::vec3& pq = sender.position_view;
  const glm::vec3& nq = sender.normal_view;
  const glm::vec3 to_receiver = rcv.p - pq;
  const float d2 = glm::dot(to_receiver, to_receiver);
  // A sender at P itself has no defined direction (a zero-area coincidence).
  if (!(d2 > 0.0f)) return;
  const float cos_s = glm::dot(nq, to_receiver);  // x d
  if (!(cos_s > 0.0f)) return;                    // back-facing sender
  if (c.form_factor) {
    const float cos_r = -glm::dot(rcv.n, to_receiver);  // x d
    if (!(cos_r > 0.0f)) return;
    const float cos_cos = cos_s * cos_r / d2;
    indirect_sum += sender_radiance(c, sender_direct, qx, qy) * (cos_cos / std::max(d2, c.sender_distance_min2_world));
  } else {
    indirect_sum += sender_radiance(c, sender_direct, qx, qy);
  }
}

// A pixel's rotation of the R2 sequence (Cranley-Patterson shift (shift_u, shift_v)), with
// cos and sin of the azimuth shift 2 pi shift_v. The shift is the sequence's point n S (n
// the pixel's Hilbert index, S its samples; StratifiedNoise), so that the pixel's directions
// are the points n S .. n S + S - 1: neighbouring pixels take neighbouring runs of the
// sequence, and a patch of them, which the denoise averages, covers the sphere as evenly as
// one pixel with all their samples would. (A shift at index n, as GTAO's rotation, would give
// the next pixel the same directions but one.) Measured against the oracle:
// docs/accuracy.md, "SSDO against Cycles".
struct SampleShift {
  float u, v;
  float cos_v, sin_v;
};

inline SampleShift sample_shift(const Constants& c, int x, int y) {
  SampleShift h;
  const int frame_x = x - c.frame_origin_px.x, frame_y = y - c.frame_origin_px.y;
  const uint32_t n = StratifiedNoise::index(frame_x, frame_y) * uint32_t(c.s.samples);
  h.u = c.noise.u(n);
  h.v = c.noise.v(n);
  sincos_turns(h.v, h.cos_v, h.sin_v);
  return h;
}

// Up to kSampleBatch sample directions i = first + s: each direction's w and clip-space
// direction, in arrays indexed by s so that the loops over directions vectorise, and per
// point (index step x count + s) its distance lambda along w, depth, clip coordinates and
// test result with its pixel.
struct SampleBatch {
  static constexpr int kPoints = kSampleBatch * kMaxSampleSteps;
  int first, count;
  float u_at[kSampleBatch];
  // Zero past `count` (the environment's and the march's lanes read every direction of the
  // batch).
  float wx[kSampleBatch] = {}, wy[kSampleBatch] = {}, wz[kSampleBatch] = {};
  float cwx[kSampleBatch] = {}, cwy[kSampleBatch] = {}, cww[kSampleBatch] = {};  // clip z is not needed
  // Each direction's jitter xi and the spacing m / (k - 1 + xi) of its points.
  float xi_at[kSampleBatch], step_at[kSampleBatch];
  // kPoints is a multiple of any vector's lanes: test_points fills whole vectors.
  float lambda[kPoints], depth_s[kPoints];
  float clip_x[kPoints], clip_y[kPoints];
  float clip_w[kPoints];
  Tap tap_at[kPoints];
  int32_t qx_at[kPoints], qy_at[kPoints];

  glm::vec3 w(int s) const { return {wx[s], wy[s], wz[s]}; }
};

// Sample directions (paper sec. 3.1): w_i cosine-distributed about n (pdf cos / pi, so
// that the estimators of eq. 1 and 2 need no cos / pdf factor), from the R2 point i, and
// the length m of the part of the radius each march covers.
inline void sample_directions(const Constants& c, const Receiver& rcv, const RayFrame& f, const SampleShift& shift,
                              int x, int y, SampleBatch& b) {
  const int frame_x = x - c.frame_origin_px.x, frame_y = y - c.frame_origin_px.y;  // the noise's pixel
  for (int s = 0; s < b.count; ++s) {
    float v;
    r2_point(uint32_t(b.first + s), shift.u, shift.v, b.u_at[s], v);
  }
  const glm::mat4& m = c.clip_from_view;
  const int steps = c.s.sample_steps;
  for (int s = 0; s < b.count; ++s) {
    const int i = b.first + s;
    const float u = b.u_at[s];
    // cosine_direction(u, v, t, b, n) with the azimuth 2 pi v by rotation (see Constants).
    const float cos_phi = shift.cos_v * c.azimuth_cos[i] - shift.sin_v * c.azimuth_sin[i];
    const float sin_phi = shift.sin_v * c.azimuth_cos[i] + shift.cos_v * c.azimuth_sin[i];
    const float radius = std::sqrt(u);
    const float along_t = radius * cos_phi, along_b = radius * sin_phi;
    const float along_n = std::sqrt(std::max(0.0f, 1.0f - u));
    b.wx[s] = f.t.x * along_t + f.b.x * along_b + rcv.n.x * along_n;
    b.wy[s] = f.t.y * along_t + f.b.y * along_b + rcv.n.y * along_n;
    b.wz[s] = f.t.z * along_t + f.b.z * along_b + rcv.n.z * along_n;
    // clip_from_view * (w, 0), in glm's order of operations.
    const glm::vec4 cw = (m[0] * b.wx[s] + m[1] * b.wy[s]) + (m[2] * b.wz[s] + m[3] * 0.0f);
    b.cwx[s] = cw.x, b.cwy[s] = cw.y, b.cww[s] = cw.w;
    // Points along w at lambda_ij = m (j + xi_i) / (k - 1 + xi_i), j = 0..k-1, xi_i in
    // (0, 1], m = the on-screen part of r: k = 1 is the paper's single point at a uniform
    // distance in (0, r]; k > 1 marches the radius with the last point at m, so that an
    // occluder the ray meets anywhere within r is found (with the last point at
    // m (k - 1 + xi) / k, occluders in the last interval were missed at random: a dark
    // bias of the bounce of up to half against the oracle on the shared frames).
    b.xi_at[s] = 1.0f - noise01(frame_x, frame_y, 2u + uint32_t(i), c.s.seed);  // (0, 1]
    // The march covers the part of the radius that stays on screen: beyond the frame
    // nothing can be tested, and a coarse step that leaps off screen would otherwise end
    // the march before it tests an occluder at the frame's edge (walls that leave the
    // frame, e.g.).
    const float march = on_screen_length(f.clip_p, cw, rcv.r);
    b.step_at[s] = march / (steps > 1 ? float(steps - 1) + b.xi_at[s] : 1.0f);
  }
}

namespace hn = hwy::HWY_NAMESPACE;

// The occlusion test (paper sec. 3.1: a point is occluded when it lies behind the depth
// buffer) of the points S of a vector's lanes, given their clip coordinates (clip_x,
// clip_y, ., clip_w) and planar depth depth_s, for the receiver at pixel coordinates
// origin_px. Returns the Tap of each lane; (qx, qy) receive the pixel S projects to (0 off
// screen or behind the eye): on `occluded`, the sender. Without branches (every case is
// computed and selected), so that the texel reads of many points overlap.
// - The texel: the pyramid level of S's distance from the receiver (one level per octave
//   from kMipStartPx on); full_resolution: level 0 whatever the distance (the bisection
//   steps: on the shared frames, bisecting on coarse texels left the bounce 27-31% from
//   the oracle, on full-resolution texels 13-17%).
// - The surface depth on S's own ray: the texel's tangent plane (its source pixel's) at
//   S's offset from the texel's centre, as 1 / depth affine in screen position, clamped to
//   kPlaneCorrectionMaxRelative of the texel's depth.
// - The thickness: the texel's source pixel's, from the second depth layer, or the
//   settings' thickness_world.
template <class D, class V = hn::Vec<D>, class VI = hn::Vec<hn::RebindToSigned<D>>>
HWY_INLINE VI test_lanes(D d, const Constants& c, const glm::vec2& origin_px, V clip_x, V clip_y, V clip_w, V depth_s,
                         bool full_resolution, VI& qx, VI& qy) {
  const hn::RebindToSigned<D> di;
  const hn::RebindToUnsigned<D> du;
  using M = hn::Mask<D>;
  const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
  const V width_v = hn::Set(d, c.width_px), height_v = hn::Set(d, c.height_px);
  const VI width_i = hn::Set(di, int32_t(c.width_px));
  // Projection.
  const V inv_w = hn::Div(one, clip_w);
  const V px = hn::Mul(hn::Mul(half, hn::Add(hn::Mul(clip_x, inv_w), one)), width_v);
  const V py = hn::Mul(hn::Mul(half, hn::Sub(one, hn::Mul(clip_y, inv_w))), height_v);
  const M on_screen = hn::And(hn::And(hn::Gt(clip_w, zero), hn::And(hn::Ge(px, zero), hn::Lt(px, width_v))),
                              hn::And(hn::Ge(py, zero), hn::Lt(py, height_v)));
  qx = hn::ConvertTo(di, hn::IfThenElseZero(on_screen, px));
  qy = hn::ConvertTo(di, hn::IfThenElseZero(on_screen, py));
  VI texel;
  V centre_x, centre_y;  // the texel's centre, pixels
  if (full_resolution || c.n_levels == 1) {
    texel = hn::Add(hn::Mul(qy, width_i), qx);
    centre_x = hn::Add(hn::ConvertTo(d, qx), half);
    centre_y = hn::Add(hn::ConvertTo(d, qy), half);
  } else {
    const V dx = hn::Sub(px, hn::Set(d, origin_px.x)), dy = hn::Sub(py, hn::Set(d, origin_px.y));
    const V rho2 = hn::Mul(hn::Add(hn::Mul(dx, dx), hn::Mul(dy, dy)), hn::Set(d, 1.0f / (kMipStartPx * kMipStartPx)));
    // min(top level, (exponent of rho2) / 2 + 1), or 0 below kMipStartPx: rho in [16, 32) px
    // is rho2 in [1, 4), exponent 0..1, level 1; [32, 64) px level 2; ... (a NaN rho2, whose
    // exponent may read negative, is below kMipStartPx by the compare).
    const VI exponent = floor_log2_lanes(di, rho2);
    const VI level =
        hn::IfThenElseZero(hn::RebindMask(di, hn::Ge(rho2, one)),
                           hn::Min(hn::Set(di, c.n_levels - 1), hn::Add(hn::ShiftRight<1>(exponent), hn::Set(di, 1))));
    const VI rows_2h = hn::Set(di, c.pyramid_rows_2h);
    const VI texel_x = hn::operator>>(qx, level), texel_y = hn::operator>>(qy, level);
    const VI row = hn::Add(hn::Sub(rows_2h, hn::operator>>(rows_2h, level)), texel_y);
    texel = hn::Add(hn::Mul(row, width_i), texel_x);
    // A texel of level l spans 2^l pixels (a float's exponent field set to l).
    const V texel_px = hn::BitCast(d, hn::ShiftLeft<23>(hn::Add(level, hn::Set(di, 127))));
    centre_x = hn::Mul(hn::Add(hn::ConvertTo(d, texel_x), half), texel_px);
    centre_y = hn::Mul(hn::Add(hn::ConvertTo(d, texel_y), half), texel_px);
  }
  alignas(64) int32_t index[hn::MaxLanes(di)];
  hn::Store(texel, di, index);
  V t[2];  // TapTexel's fields
  load_records2(d, c.pyramid, index, t);
  const V thickness =
      c.pyramid_thickness ? hn::GatherIndex(d, c.pyramid_thickness, texel) : hn::Set(d, c.s.thickness_world);
  // The class.
  const V depth_q = t[0];
  const M background = hn::Not(hn::Lt(depth_q, hn::Set(d, std::numeric_limits<float>::infinity())));
  const auto gradient = hn::BitCast(du, t[1]);
  const V gx = hn::BitCast(d, hn::ShiftLeft<16>(gradient));
  const V gy = hn::BitCast(d, hn::And(gradient, hn::Set(du, 0xFFFF0000u)));
  // 1 / depth = (1 + g . offset) / depth_q at S's offset from the texel's centre (TapTexel),
  // so depth = depth_q / depth_ratio with depth_ratio = 1 + g . offset: one division; the
  // plane is in front of the eye there when depth_ratio > 0.
  const V depth_ratio =
      hn::Add(one, hn::Add(hn::Mul(gx, hn::Sub(px, centre_x)), hn::Mul(gy, hn::Sub(py, centre_y))));
  const V limit = hn::Mul(hn::Set(d, kPlaneCorrectionMaxRelative), depth_q);
  const V clamped =
      hn::Min(hn::Add(depth_q, limit), hn::Max(hn::Sub(depth_q, limit), hn::Div(depth_q, depth_ratio)));
  const V behind = hn::Sub(depth_s, hn::IfThenElse(hn::Gt(depth_ratio, zero), clamped, depth_q));
  const M beyond_bias = hn::Gt(behind, hn::Mul(hn::Set(d, c.s.depth_bias_relative), depth_s));
  const M within_thickness = hn::Lt(behind, thickness);
  static_assert(int(Tap::visible) == 0 && int(Tap::occluded) == 1 && int(Tap::behind) == 2 &&
                int(Tap::off_screen) == 3);
  const VI in_view =
      hn::IfThenElseZero(hn::RebindMask(di, hn::AndNot(background, beyond_bias)),
                         hn::IfThenElse(hn::RebindMask(di, within_thickness), hn::Set(di, 1), hn::Set(di, 2)));
  return hn::IfThenElse(hn::RebindMask(di, on_screen), in_view, hn::Set(di, 3));
}

// The occlusion test of every point of every direction of the batch: the points (a loop
// over them that vectorises), then their tests in full-width lanes (test_lanes), without
// branches, so that the texel reads of all the batch's points overlap.
inline void test_points(const Constants& c, const Receiver& rcv, const RayFrame& f, SampleBatch& b) {
  const int steps = c.s.sample_steps;
  for (int j = 0; j < steps; ++j)
    for (int s = 0; s < b.count; ++s) {
      const int k = j * b.count + s;
      b.lambda[k] = b.step_at[s] * (float(j) + b.xi_at[s]);
      b.depth_s[k] = -(rcv.p.z + b.lambda[k] * b.wz[s]);
      b.clip_x[k] = f.clip_p.x + b.lambda[k] * b.cwx[s];
      b.clip_y[k] = f.clip_p.y + b.lambda[k] * b.cwy[s];
      b.clip_w[k] = f.clip_p.w + b.lambda[k] * b.cww[s];
    }
  const hn::ScalableTag<float> d;
  const hn::RebindToSigned<decltype(d)> di;
  static_assert(SampleBatch::kPoints % hn::MaxLanes(d) == 0);
  const size_t points = size_t(b.count * steps);
  // The last vector's lanes past `points` test a point at the eye (clip w 0: off screen).
  const size_t padded = hwy::RoundUpTo(points, hn::Lanes(d));
  for (float* a : {b.depth_s, b.clip_x, b.clip_y, b.clip_w}) std::fill(a + points, a + padded, 0.0f);
  for (size_t k = 0; k < padded; k += hn::Lanes(d)) {
    auto qx = hn::Zero(di), qy = hn::Zero(di);
    const auto tap = test_lanes(d, c, f.origin_px, hn::LoadU(d, b.clip_x + k), hn::LoadU(d, b.clip_y + k),
                                hn::LoadU(d, b.clip_w + k), hn::LoadU(d, b.depth_s + k), false, qx, qy);
    hn::StoreU(tap, di, reinterpret_cast<int32_t*>(b.tap_at) + k);
    hn::StoreU(qx, di, b.qx_at + k);
    hn::StoreU(qy, di, b.qy_at + k);
  }
}

// The lanes of `tap` (Tap values) that are `value`, as a mask of d.
template <class D, class VI>
HWY_INLINE hn::Mask<D> tap_is(D d, VI tap, Tap value) {
  return hn::RebindMask(d, hn::Eq(tap, hn::Set(hn::RebindToSigned<D>(), int32_t(value))));
}

// A ray per lane: from a receiver P (its clip coordinates and view z) along a direction w
// (w's clip coordinates and view z; clip z is not needed).
template <class V>
struct RayLanes {
  V clip_x, clip_y, clip_w, p_z;
  V dir_x, dir_y, dir_w, dir_z;
};

// The rays from the receiver (rcv, f) along the lanes' directions.
template <class D, class V = hn::Vec<D>>
HWY_INLINE RayLanes<V> receiver_rays(D d, const Receiver& rcv, const RayFrame& f, V dir_x, V dir_y, V dir_w, V dir_z) {
  return {hn::Set(d, f.clip_p.x), hn::Set(d, f.clip_p.y), hn::Set(d, f.clip_p.w), hn::Set(d, rcv.p.z),
          dir_x,                  dir_y,                  dir_w,                  dir_z};
}

// The rays from the receiver along the batch's directions s0 ...
template <class D, class V = hn::Vec<D>>
HWY_INLINE RayLanes<V> batch_rays(D d, const Receiver& rcv, const RayFrame& f, const SampleBatch& b, size_t s0) {
  return receiver_rays(d, rcv, f, hn::LoadU(d, b.cwx + s0), hn::LoadU(d, b.cwy + s0), hn::LoadU(d, b.cww + s0),
                       hn::LoadU(d, b.wz + s0));
}

// test_lanes of the points P + lambda w of the lanes' rays: clip coordinates clip_p + lambda
// cw, planar depth -(P + lambda w).z.
template <class D, class V = hn::Vec<D>, class VI = hn::Vec<hn::RebindToSigned<D>>>
HWY_INLINE VI test_along(D d, const Constants& c, const glm::vec2& origin_px, const RayLanes<V>& r, V lambda,
                         bool full_resolution, VI& qx, VI& qy) {
  const V clip_x = hn::Add(r.clip_x, hn::Mul(lambda, r.dir_x));
  const V clip_y = hn::Add(r.clip_y, hn::Mul(lambda, r.dir_y));
  const V clip_w = hn::Add(r.clip_w, hn::Mul(lambda, r.dir_w));
  const V depth_s = hn::Neg(hn::Add(r.p_z, hn::Mul(lambda, r.dir_z)));
  return test_lanes(d, c, origin_px, clip_x, clip_y, clip_w, depth_s, full_resolution, qx, qy);
}

// Bisection of the brackets [lo, hi] of the lanes `which` along their rays (lo in front of
// the depth buffer, hi behind it; both on screen, so every point between is: projection
// keeps segments convex), on full-resolution texels: sample_refinements halvings; each
// occluded midpoint becomes the lane's occluder and sender (qx, qy).
template <class D, class V = hn::Vec<D>, class M = hn::Mask<D>, class VI = hn::Vec<hn::RebindToSigned<D>>>
HWY_INLINE void bisect_lanes(D d, const Constants& c, const RayLanes<V>& ray, M which, V lo, V hi, M& occluded,
                             VI& qx, VI& qy) {
  const hn::RebindToSigned<D> di;
  const glm::vec2 unused_origin(0.0f);  // full-resolution texels: no level by distance
  for (int h = 0; h < c.s.sample_refinements; ++h) {
    const V mid = hn::Mul(hn::Set(d, 0.5f), hn::Add(lo, hi));
    VI mx = hn::Zero(di), my = hn::Zero(di);
    const VI tap = test_along(d, c, unused_origin, ray, mid, true, mx, my);
    const M visible = hn::And(which, tap_is(d, tap, Tap::visible));
    const M hit = hn::And(which, tap_is(d, tap, Tap::occluded));
    lo = hn::IfThenElse(visible, mid, lo);
    hi = hn::IfThenElse(visible, hi, mid);
    occluded = hn::Or(occluded, hit);
    qx = hn::IfThenElse(hn::RebindMask(di, hit), mx, qx);
    qy = hn::IfThenElse(hn::RebindMask(di, hit), my, qy);
  }
}

// The sender pass's bisections that locate a sender (march_batch), queued across pixels
// and run a full vector of brackets at a time: their result goes only to the pixel's
// record (its sample's sender), which nothing reads before the pass has ended, and a
// pixel's own bisection has a vector to itself of which a few lanes (the occluded
// directions) are used. The same halvings on the same lanes' values: the same bits.
struct LocateQueue {
  static constexpr int kCapacity = 64;
  static_assert(kCapacity % hn::MaxLanes(hn::ScalableTag<float>()) == 0, "whole vectors");
  int count = 0;
  alignas(64) float clip_x[kCapacity], clip_y[kCapacity], clip_w[kCapacity], p_z[kCapacity];
  alignas(64) float dir_x[kCapacity], dir_y[kCapacity], dir_w[kCapacity], dir_z[kCapacity];
  alignas(64) float lo[kCapacity], hi[kCapacity];
  int32_t* slot[kCapacity];  // the record entry that receives the sender's pixel y W + x

  // The queued brackets' fields, in RayLanes' order then lo and hi.
  static constexpr size_t kFields = 10;
  std::array<float*, kFields> fields() { return {clip_x, clip_y, clip_w, p_z, dir_x, dir_y, dir_w, dir_z, lo, hi}; }

  // Room for n more brackets: runs the queued ones first when there is not.
  void reserve(const Constants& c, int n) {
    if (count + n > kCapacity) run(c);
  }

  // Bisects every queued bracket and writes the senders found to their records.
  void run(const Constants& c) {
    const hn::ScalableTag<float> d;
    const hn::RebindToSigned<decltype(d)> di;
    using V = hn::Vec<decltype(d)>;
    const size_t lanes = hn::Lanes(d);
    const int width = int(c.width_px);
    // The last vector's lanes past `count` bisect [0, 0] along a ray at the eye (clip w 0:
    // off screen), for nobody.
    const size_t padded = hwy::RoundUpTo(size_t(count), lanes);
    for (float* a : fields()) std::fill(a + count, a + padded, 0.0f);
    for (size_t k = 0; k < size_t(count); k += lanes) {
      const RayLanes<V> ray{hn::Load(d, clip_x + k), hn::Load(d, clip_y + k), hn::Load(d, clip_w + k),
                            hn::Load(d, p_z + k),    hn::Load(d, dir_x + k),  hn::Load(d, dir_y + k),
                            hn::Load(d, dir_w + k),  hn::Load(d, dir_z + k)};
      const auto queued = hn::FirstN(d, size_t(count) - k);
      auto found = hn::FirstN(d, 0);
      auto qx = hn::Zero(di), qy = hn::Zero(di);
      bisect_lanes(d, c, ray, queued, hn::Load(d, lo + k), hn::Load(d, hi + k), found, qx, qy);
      alignas(64) int32_t found_lanes[hn::MaxLanes(di)], x_lanes[hn::MaxLanes(di)], y_lanes[hn::MaxLanes(di)];
      hn::Store(hn::VecFromMask(di, hn::RebindMask(di, found)), di, found_lanes);
      hn::Store(qx, di, x_lanes);
      hn::Store(qy, di, y_lanes);
      for (size_t l = 0; l < lanes && k + l < size_t(count); ++l)
        if (found_lanes[l]) *slot[k + l] = y_lanes[l] * width + x_lanes[l];
    }
    count = 0;
  }
};

// Queues the brackets [lo, hi] of the lanes `locate` along their rays (batch_rays of the
// directions s0 + l), their record entries record_batch + s0 + l. Lane by lane from the
// stored vectors: a batch locates a few lanes, and a compressing store per field costs more
// on several targets (AVX2 has no such instruction: Highway's emulation copies a 1 KiB
// table per call and stores through vmaskmovps, microcode on AMD's cores).
template <class D, class V = hn::Vec<D>, class M = hn::Mask<D>>
HWY_INLINE void queue_locate(D d, const Receiver& rcv, const RayFrame& f, const SampleBatch& b, size_t s0, M locate,
                             V lo, V hi, int32_t* record_batch, LocateQueue& q) {
  const hn::RebindToSigned<D> di;
  const RayLanes<V> ray = batch_rays(d, rcv, f, b, s0);
  constexpr size_t kFields = LocateQueue::kFields;
  const V field[kFields] = {ray.clip_x, ray.clip_y, ray.clip_w, ray.p_z, ray.dir_x, ray.dir_y, ray.dir_w, ray.dir_z,
                            lo,         hi};
  const std::array<float*, kFields> queued = q.fields();
  alignas(64) float field_lanes[kFields][hn::MaxLanes(d)];
  for (size_t i = 0; i < kFields; ++i) hn::Store(field[i], d, field_lanes[i]);
  alignas(64) int32_t locate_lanes[hn::MaxLanes(di)];
  hn::Store(hn::VecFromMask(di, hn::RebindMask(di, locate)), di, locate_lanes);
  int slot = q.count;
  for (size_t l = 0; l < hn::Lanes(d); ++l) {
    if (!locate_lanes[l]) continue;
    for (size_t i = 0; i < kFields; ++i) queued[i][slot] = field_lanes[i][l];
    q.slot[slot++] = record_batch + s0 + l;
  }
  q.count = slot;
}

// The march of each direction s of the batch, one direction per lane: the first point
// behind the depth buffer within the thickness decides; occluded[s] says whether it was
// found, and (qx, qy)[s] is then the sender. Between two steps, bisection (bisect_lanes):
// - after an occluded step, for the entry point (when locate_sender): the sender is the
//   surface where w enters the occluder, not wherever a coarse step overshot to (an
//   overshot point projects onto a face of the occluder that often faces away from P, which
//   the back-face test then drops: a dark bias of the bounce). Only the bounce needs it.
//   The march ends there whatever the bisection finds, so these run together at the end,
//   or, given a queue, are queued there (LocateQueue) with record_batch + s as their
//   record entries, which receive the step's pixel meanwhile.
// - after a step farther behind the surface than the thickness right after one in front:
//   the ray crossed the stored surface in between, and the part within the thickness lies
//   between the steps (large occluders seen face-on: deep inside, a point is farther than
//   the thickness behind the front face the screen shows). The march goes on when the
//   bisection finds nothing, so these run at their step.
// The lanes step together: a direction's steps and halvings depend on each other, and
// branches on what a tap found, or texel reads one after the other (each a cache miss
// when it lands far from the last), cost more than the lanes' wasted work.
void march_batch(const Constants& c, const Receiver& rcv, const RayFrame& f, const SampleBatch& b,
                 bool locate_sender, LocateQueue* queue, int32_t* record_batch, bool* occluded_out, int* qx_out,
                 int* qy_out) {
  const hn::CappedTag<float, kSampleBatch> d;
  const hn::RebindToSigned<decltype(d)> di;
  using V = hn::Vec<decltype(d)>;
  using VI = hn::Vec<decltype(di)>;
  using M = hn::Mask<decltype(d)>;
  static_assert(sizeof(Tap) == sizeof(int32_t));
  const V zero = hn::Zero(d);
  const int32_t* taps = reinterpret_cast<const int32_t*>(b.tap_at);
  for (size_t s0 = 0; s0 < size_t(kSampleBatch); s0 += hn::Lanes(d)) {
    // Lanes past the batch's count never start.
    M active = hn::FirstN(d, size_t(std::max(b.count - int(s0), 0)));
    const M none = hn::FirstN(d, 0);
    const M locate_sender_m = locate_sender ? active : none;
    M after_front = active, occluded = none, locate = none;
    V lambda_front = zero, locate_lo = zero, locate_hi = zero;  // the last point in front: P itself
    VI qx = hn::Zero(di), qy = hn::Zero(di);
    for (int j = 0; j < c.s.sample_steps && !hn::AllFalse(d, active); ++j) {
      const size_t k = size_t(j * b.count) + s0;
      const VI tap = hn::LoadU(di, taps + k);
      const V lambda = hn::LoadU(d, b.lambda + k);
      active = hn::AndNot(tap_is(d, tap, Tap::off_screen), active);
      const M visible = hn::And(active, tap_is(d, tap, Tap::visible));
      lambda_front = hn::IfThenElse(visible, lambda, lambda_front);
      const M hit = hn::AndNot(tap_is(d, tap, Tap::visible), active);  // occluded or behind: tap = tj
      const M hit_occluded = hn::And(hit, tap_is(d, tap, Tap::occluded));
      occluded = hn::Or(hit_occluded, hn::AndNot(hit, occluded));
      qx = hn::IfThenElse(hn::RebindMask(di, hit), hn::LoadU(di, b.qx_at + k), qx);
      qy = hn::IfThenElse(hn::RebindMask(di, hit), hn::LoadU(di, b.qy_at + k), qy);
      // An occluded step ends the march, its bisection left for the end.
      const M locate_now = hn::And(hit_occluded, locate_sender_m);
      locate_lo = hn::IfThenElse(locate_now, lambda_front, locate_lo);
      locate_hi = hn::IfThenElse(locate_now, lambda, locate_hi);
      locate = hn::Or(locate, locate_now);
      active = hn::AndNot(hit_occluded, active);
      const M crossed = hn::AndNot(hit_occluded, hn::And(hit, after_front));
      after_front = hn::Or(hn::AndNot(hit, after_front), visible);
      if (!hn::AllFalse(d, crossed)) {
        M found = none;
        bisect_lanes(d, c, batch_rays(d, rcv, f, b, s0), crossed, lambda_front, lambda, found, qx, qy);
        occluded = hn::Or(occluded, found);
        active = hn::AndNot(found, active);
      }
    }
    if (!hn::AllFalse(d, locate)) {
      if (queue)
        queue_locate(d, rcv, f, b, s0, locate, locate_lo, locate_hi, record_batch, *queue);
      else
        bisect_lanes(d, c, batch_rays(d, rcv, f, b, s0), locate, locate_lo, locate_hi, occluded, qx, qy);
    }
    alignas(64) int32_t occluded_lanes[hn::MaxLanes(di)];
    hn::Store(hn::VecFromMask(di, hn::RebindMask(di, occluded)), di, occluded_lanes);
    const size_t n = std::min(hn::Lanes(d), size_t(std::max(0, b.count - int(s0))));
    for (size_t l = 0; l < n; ++l) occluded_out[s0 + l] = occluded_lanes[l] != 0;
    alignas(64) int32_t lanes_x[hn::MaxLanes(di)], lanes_y[hn::MaxLanes(di)];
    hn::Store(qx, di, lanes_x);
    hn::Store(qy, di, lanes_y);
    std::copy_n(lanes_x, n, qx_out + s0);
    std::copy_n(lanes_y, n, qy_out + s0);
  }
}

// A pixel's sums over its samples.
struct SampleSums {
  glm::vec3 direct{0.0f};    // per_sample: sum over visible w_i of L_env,filtered(w_i)
  glm::vec3 bent{0.0f};      // bent_normal: sum of the visible w_i
  glm::vec3 occluded{0.0f};  // open_minus_occluded: sum over occluded w_i of L_env,filtered(w_i)
  glm::vec3 indirect{0.0f};  // sum over occluded w_i of the sender's light (add_sender)
  int visible = 0;
};

// bilinear_at(map, equirect_from_direction_fast(m * w, map.size())) (kernels/environment.cpp)
// of view-space directions w, one per lane, into (red, green, blue): m * w in glm's order,
// fast_atan2 twice and the bilinear lookup with its wrap in azimuth and clamp in elevation,
// the same operations in the same order as the scalar code, so the same bits. map: an
// environment's equirect table (CV_32FC3).
template <class D>
HWY_INLINE void equirect_lanes(D d, const cv::Mat& map, const glm::mat3& m, hn::Vec<D> wx, hn::Vec<D> wy,
                               hn::Vec<D> wz, hn::Vec<D>& red, hn::Vec<D>& green, hn::Vec<D>& blue) {
  const hn::RebindToSigned<D> di;
  using V = hn::Vec<D>;
  const int width = map.cols, height = map.rows;
  const int32_t row_floats = int32_t(map.step1());
  const float* texels = map.ptr<float>(0);
  constexpr float pi = std::numbers::pi_v<float>;
  const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
  // fast_atan2 (kernels/environment.cpp) in lanes.
  auto atan2_lanes = [&](V y, V x) {
    const V ax = hn::Abs(x), ay = hn::Abs(y);
    const V hi = hn::Max(ax, ay), lo = hn::Min(ax, ay);
    const V t = hn::IfThenElse(hn::Gt(hi, zero), hn::Div(lo, hi), zero);
    const V t2 = hn::Mul(t, t);
    const float* coefficient = Environment::kAtanPolynomial;
    V poly = hn::Set(d, coefficient[0]);
    for (int i = 1; i < 6; ++i) poly = hn::Add(hn::Mul(poly, t2), hn::Set(d, coefficient[i]));
    V a = hn::Mul(poly, t);
    a = hn::IfThenElse(hn::Gt(ay, ax), hn::Sub(hn::Set(d, float(0.5 * std::numbers::pi)), a), a);
    a = hn::IfThenElse(hn::Lt(x, zero), hn::Sub(hn::Set(d, pi), a), a);
    return hn::IfThenElse(hn::Lt(y, zero), hn::Neg(a), a);
  };
  auto row = [&](int r) {  // glm's mat3 * vec3: m[0][r] x + m[1][r] y + m[2][r] z
    return hn::Add(hn::Add(hn::Mul(hn::Set(d, m[0][r]), wx), hn::Mul(hn::Set(d, m[1][r]), wy)),
                   hn::Mul(hn::Set(d, m[2][r]), wz));
  };
  const V dx = row(0), dy = row(1), dz = row(2);
  const V theta = atan2_lanes(dz, hn::Sqrt(hn::Add(hn::Mul(dx, dx), hn::Mul(dy, dy))));
  const V phi = atan2_lanes(hn::Neg(dx), dy);
  const V px = hn::Mul(hn::Set(d, 0.5f * float(width)), hn::Sub(one, hn::Div(phi, hn::Set(d, pi))));
  const V py = hn::Mul(hn::Set(d, float(height)), hn::Sub(half, hn::Div(theta, hn::Set(d, pi))));
  // bilinear_at: texel centres at + 0.5.
  const V x = hn::Sub(px, half), y = hn::Sub(py, half);
  const V x0f = hn::Floor(x), y0f = hn::Floor(y);
  const V fx = hn::Sub(x, x0f), fy = hn::Sub(y, y0f);
  // A direction gives x in [-0.5, W - 0.5] (atan2 is bounded), so one add or subtract
  // wraps x0 and x0 + 1; the clamp only keeps a NaN direction's texels in the map.
  const auto width_v = hn::Set(di, width);
  auto wrap = [&](hn::Vec<decltype(di)> xi) {
    xi = hn::Min(hn::Max(xi, hn::Neg(width_v)), hn::Set(di, 2 * width - 1));
    xi = hn::IfThenElse(hn::Lt(xi, hn::Zero(di)), hn::Add(xi, width_v), xi);
    return hn::IfThenElse(hn::Gt(xi, hn::Set(di, width - 1)), hn::Sub(xi, width_v), xi);
  };
  auto clamp_row = [&](hn::Vec<decltype(di)> yi) {
    return hn::Min(hn::Max(yi, hn::Zero(di)), hn::Set(di, height - 1));
  };
  const auto x0 = hn::ConvertTo(di, x0f), y0 = hn::ConvertTo(di, y0f);
  const auto one_i = hn::Set(di, 1);
  const auto three = hn::Set(di, 3), row_step = hn::Set(di, row_floats);
  const auto xa = hn::Mul(wrap(x0), three), xb = hn::Mul(wrap(hn::Add(x0, one_i)), three);
  const auto ya = hn::Mul(clamp_row(y0), row_step), yb = hn::Mul(clamp_row(hn::Add(y0, one_i)), row_step);
  const V wx0 = hn::Sub(one, fx), wy0 = hn::Sub(one, fy);
  V* out[3] = {&red, &green, &blue};
  for (int ch = 0; ch < 3; ++ch) {
    const auto c_i = hn::Set(di, ch);
    auto texel = [&](hn::Vec<decltype(di)> yo, hn::Vec<decltype(di)> xo) {
      return hn::GatherIndex(d, texels, hn::Add(hn::Add(yo, xo), c_i));
    };
    const V top = hn::Add(hn::Mul(texel(ya, xa), wx0), hn::Mul(texel(ya, xb), fx));
    const V bottom = hn::Add(hn::Mul(texel(yb, xa), wx0), hn::Mul(texel(yb, xb), fx));
    *out[ch] = hn::Add(hn::Mul(top, wy0), hn::Mul(bottom, fy));
  }
}

// Environment::radiance_filtered_env of the batch's kSampleBatch directions w (view space)
// at once, into (red, green, blue). A filtered map or a sky (not a constant). Lanes of
// visible samples are computed too (for nobody when the estimator reads only the occluded
// ones): a vector of lanes costs about what one scalar lookup does.
void filtered_radiance_lanes(const Constants& c, const SampleBatch& b, float* red, float* green, float* blue) {
  const hn::CappedTag<float, kSampleBatch> d;
  for (size_t s0 = 0; s0 < size_t(kSampleBatch); s0 += hn::Lanes(d)) {
    hn::Vec<decltype(d)> r, g, bl;
    equirect_lanes(d, c.env->filtered_map(), c.env_from_view, hn::LoadU(d, b.wx + s0), hn::LoadU(d, b.wy + s0),
                   hn::LoadU(d, b.wz + s0), r, g, bl);
    hn::StoreU(r, d, red + s0);
    hn::StoreU(g, d, green + s0);
    hn::StoreU(bl, d, blue + s0);
  }
}

// The environment's share of the batch's samples (paper eq. 1): the filtered radiance
// through each visible w_i (per_sample), or through each occluded w_i (the control
// variate), added in the samples' order; nothing for bent_normal.
inline void add_environment(const Constants& c, const SampleBatch& b, const bool* occluded, SampleSums& sums) {
  if (c.bent_normal) return;
  glm::vec3* sum = c.control_variate ? &sums.occluded : &sums.direct;
  bool any = false;
  for (int s = 0; s < b.count; ++s) any |= occluded[s] == c.control_variate;
  if (!any) return;
  if (c.env->kind() == EnvironmentKind::constant) {  // the same radiance every way
    const glm::vec3 radiance = c.env->radiance_filtered_env(glm::vec3(0.0f, 0.0f, 1.0f));
    for (int s = 0; s < b.count; ++s)
      if (occluded[s] == c.control_variate) *sum += radiance;
    return;
  }
  alignas(64) float red[kSampleBatch], green[kSampleBatch], blue[kSampleBatch];
  filtered_radiance_lanes(c, b, red, green, blue);
  for (int s = 0; s < b.count; ++s)
    if (occluded[s] == c.control_variate) *sum += glm::vec3(red[s], green[s], blue[s]);
}

// One sample's share besides the environment's (add_environment): the visible w_i for the
// bent normal and the count; indirect light from the sender of an occluded w_i (eq. 2).
inline void add_sample(const Constants& c, const Receiver& rcv, const cv::Mat& sender_direct, bool want_direct,
                       bool want_indirect, const glm::vec3& w, bool occluded, int qx, int qy, SampleSums& sums) {
  if (!occluded) {
    if (want_direct && c.bent_normal) sums.bent += w;
    ++sums.visible;
    return;
  }
  if (want_indirect) add_sender(c, rcv, sender_direct, qx, qy, sums.indirect);
}

// direct = E / pi by the selected estimator (see ssdo.h) from a pixel's sums over N samples.
inline glm::vec3 direct_estimate(const Constants& c, const Receiver& rcv, int x, int y, const SampleSums& sums,
                                 float inv_n) {
  if (c.bent_normal) {
    const float len = glm::length(sums.bent);
    return len > 0.0f ? c.env->irradiance_over_pi_env(c.env_from_view * (sums.bent / len)) *
                            (float(sums.visible) * inv_n)
                      : glm::vec3(0.0f);
  }
  if (c.control_variate) {
    // E_tab(n) / pi - (1/N) sum_{occluded} L_f(w_i): exact when nothing is occluded; the
    // clamp removes negative values that noise can give where almost all is occluded.
    const glm::vec3 open = c.irradiance_at_normal ? to_glm(c.irradiance_at_normal->at<cv::Vec3f>(y, x))
                                                  : c.env->irradiance_over_pi_env(c.env_from_view * rcv.n);
    return glm::max(open - sums.occluded * inv_n, glm::vec3(0.0f));
  }
  return sums.direct * inv_n;
}

// One pixel of the SSDO estimator (method ssdo). want_direct / want_indirect select the
// terms; sender_direct is the sender pass (used only without `lighting`).
// record (may be null): receives, per sample, the sender's pixel index y W + x, or -1 when
// the sample is visible. recorded (may be null): such a record from an earlier pass with
// the same inputs and settings; the samples are then not marched again. locate_queue (may
// be null): where a pixel that records and wants no indirect light queues the bisections
// that locate its senders; the record is complete once the queue has run.
void ssdo_pixel(const Constants& c, int x, int y, bool want_direct, bool want_indirect,
                const cv::Mat& sender_direct, int32_t* record, const int32_t* recorded, LocateQueue* locate_queue,
                glm::vec3& direct, glm::vec3& indirect) {
  const Receiver rcv = receiver_at(c, x, y);
  const int n_samples = c.s.samples;
  const int width = int(c.width_px);
  SampleSums sums;
  if (recorded) {
    for (int i = 0; i < n_samples; ++i)
      if (recorded[i] >= 0 && want_indirect)
        add_sender(c, rcv, sender_direct, recorded[i] % width, recorded[i] / width, sums.indirect);
  } else {
    const RayFrame f = ray_frame(c, rcv, x, y);
    const SampleShift shift = sample_shift(c, x, y);
    const bool locate_sender = want_indirect || record != nullptr;
    // Only the record needs the senders' entry points: their bisections can wait.
    LocateQueue* queue = record != nullptr && !want_indirect ? locate_queue : nullptr;
    SampleBatch b;
    for (int i0 = 0; i0 < n_samples; i0 += kSampleBatch) {
      b.first = i0;
      b.count = std::min(kSampleBatch, n_samples - i0);
      sample_directions(c, rcv, f, shift, x, y, b);
      test_points(c, rcv, f, b);
      bool occluded[kSampleBatch];
      int qx[kSampleBatch], qy[kSampleBatch];
      if (queue) queue->reserve(c, b.count);
      march_batch(c, rcv, f, b, locate_sender, queue, queue ? record + i0 : nullptr, occluded, qx, qy);
      for (int s = 0; s < b.count; ++s) {
        if (record) record[i0 + s] = occluded[s] ? qy[s] * width + qx[s] : -1;
        add_sample(c, rcv, sender_direct, want_direct, want_indirect, b.w(s), occluded[s], qx[s], qy[s], sums);
      }
      if (want_direct) add_environment(c, b, occluded, sums);
    }
  }
  const float inv_n = 1.0f / float(n_samples);
  if (want_direct) direct = direct_estimate(c, rcv, x, y, sums, inv_n);
  if (want_indirect) {
    // form factor: (A_s / pi) sum = (r^2 / N) sum; solid angle: (1 / N) sum.
    const float scale = c.form_factor ? rcv.r * rcv.r * inv_n : inv_n;
    indirect = sums.indirect * (scale * c.s.indirect_strength);
  }
}

// The oracle's march along view-space direction w: oracle_steps evenly spaced points up to
// r (jittered by step_jitter), tested kOracleLanes at a time (test_lanes at full
// resolution: the oracle's pyramid has one level). The first point that is occluded (true;
// its pixel (qx, qy) is the sender) or off screen (false) ends it; a straight ray whose
// point has left the frame does not come back.
// Four points a time in vector lanes (1.7x faster than one at a time on AVX-512, the
// points past the first that ends the march tested for nobody); one on the emulated
// targets, whose lanes are loops (under AddressSanitizer, 5x faster than four).
constexpr size_t kOracleLanes = HWY_TARGET == HWY_EMU128 || HWY_TARGET == HWY_SCALAR ? 1 : 4;

bool oracle_march(const Constants& c, const Receiver& rcv, const RayFrame& f, const glm::vec3& w, float step_jitter,
                  int& qx, int& qy) {
  const hn::CappedTag<float, kOracleLanes> d;
  const hn::RebindToSigned<decltype(d)> di;
  const int steps = c.s.oracle_steps;
  const float step = rcv.r / float(steps);
  const glm::vec4 cw = c.clip_from_view * glm::vec4(w, 0.0f);
  for (int k0 = 0; k0 < steps; k0 += int(hn::Lanes(d))) {
    // lambda = (k + step_jitter) step + 1e-7 r: > 0 always.
    const auto k = hn::ConvertTo(d, iota_lanes(di, k0));
    const auto lambda =
        hn::Add(hn::Mul(hn::Add(k, hn::Set(d, step_jitter)), hn::Set(d, step)), hn::Set(d, 1e-7f * rcv.r));
    auto lane_x = hn::Zero(di), lane_y = hn::Zero(di);
    const auto ray = receiver_rays(d, rcv, f, hn::Set(d, cw.x), hn::Set(d, cw.y), hn::Set(d, cw.w), hn::Set(d, w.z));
    const auto tap = test_along(d, c, f.origin_px, ray, lambda, true, lane_x, lane_y);
    const auto in_range = hn::FirstN(d, size_t(steps - k0));
    const auto ends = hn::And(in_range, hn::Or(tap_is(d, tap, Tap::occluded), tap_is(d, tap, Tap::off_screen)));
    const intptr_t first = hn::FindFirstTrue(d, ends);
    if (first < 0) continue;
    alignas(16) int32_t taps[hn::MaxLanes(di)], xs[hn::MaxLanes(di)], ys[hn::MaxLanes(di)];
    hn::Store(tap, di, taps);
    hn::Store(lane_x, di, xs);
    hn::Store(lane_y, di, ys);
    qx = xs[first];
    qy = ys[first];
    return taps[first] == int32_t(Tap::occluded);
  }
  return false;
}

// One pixel of the oracle (method oracle).
void oracle_pixel(const Constants& c, int x, int y, bool want_direct, bool want_indirect,
                  const cv::Mat& sender_direct, glm::vec3& direct, glm::vec3& indirect) {
  const Receiver rcv = receiver_at(c, x, y);
  const glm::vec3& p = rcv.p;
  const RayFrame f = ray_frame(c, rcv, x, y);
  // Cranley-Patterson rotation of the stratified grid and of the step positions, per pixel.
  const int nx = x - c.frame_origin_px.x, ny = y - c.frame_origin_px.y;  // the frame's pixel
  const float shift_u = noise01(nx, ny, 0, c.s.seed), shift_v = noise01(nx, ny, 1, c.s.seed);
  const float step_jitter = noise01(nx, ny, 2, c.s.seed);
  const int g = c.s.oracle_grid;

  glm::vec3 direct_sum(0.0f), indirect_sum(0.0f);
  for (int a = 0; a < g; ++a) {
    for (int bb = 0; bb < g; ++bb) {
      float u = (float(a) + 0.5f) / float(g) + shift_u;
      float v = (float(bb) + 0.5f) / float(g) + shift_v;
      u -= std::floor(u);
      v -= std::floor(v);
      const glm::vec3 w = cosine_direction(u, v, f.t, f.b, rcv.n);
      int qx = 0, qy = 0;
      const bool hit = oracle_march(c, rcv, f, w, step_jitter, qx, qy);
      if (!hit) {
        if (want_direct) direct_sum += c.env->radiance_env(c.env_from_view * w);
        continue;
      }
      if (!want_indirect) continue;
      const SenderTexel& sender = c.senders[size_t(qy) * size_t(c.width_px) + size_t(qx)];
      if (glm::dot(sender.normal_view, p - sender.position_view) > 0.0f)
        indirect_sum += sender_radiance(c, sender_direct, qx, qy);
    }
  }
  const float inv_k = 1.0f / float(g * g);
  if (want_direct) direct = direct_sum * inv_k;
  if (want_indirect) indirect = indirect_sum * (inv_k * c.s.indirect_strength);
}

void light_pixel(const Constants& c, int x, int y, bool want_direct, bool want_indirect,
                 const cv::Mat& sender_direct, int32_t* record, const int32_t* recorded, LocateQueue* locate_queue,
                 glm::vec3& direct, glm::vec3& indirect) {
  if (c.s.method == SsdoMethod::oracle)
    oracle_pixel(c, x, y, want_direct, want_indirect, sender_direct, direct, indirect);
  else
    ssdo_pixel(c, x, y, want_direct, want_indirect, sender_direct, record, recorded, locate_queue, direct, indirect);
}

// The pyramid's levels (method ssdo only; the oracle is the full-resolution best case):
// levels until one covers the largest tap distance (~2 max_radius_px: a sample point nearer
// the camera than P projects farther out) or the image is one texel wide; the arrays
// allocated, not written.
TapPyramid allocate_tap_pyramid(cv::Size size, const SsdoSettings& settings) {
  TapPyramid p;
  p.width = size.width;
  p.level_width[0] = size.width;
  p.level_height[0] = size.height;
  const float max_rho_px = 2.0f * settings.max_radius_px;
  while (settings.method == SsdoMethod::ssdo && p.n_levels < kMaxLevels &&
         kMipStartPx * float(1 << (p.n_levels - 1)) < max_rho_px &&
         (p.level_width[p.n_levels - 1] > 1 || p.level_height[p.n_levels - 1] > 1)) {
    const int l = p.n_levels++;
    p.level_width[l] = (p.level_width[l - 1] + 1) / 2;
    p.level_height[l] = (p.level_height[l - 1] + 1) / 2;
  }
  const int64_t top_level_rows = (int64_t(size.height) + (1 << (p.n_levels - 1)) - 1) >> (p.n_levels - 1);
  p.rows_2h = top_level_rows << p.n_levels;
  const int64_t pyramid_rows = p.rows_2h - (p.rows_2h >> p.n_levels);
  CV_Assert(pyramid_rows * size.width <= std::numeric_limits<int>::max());  // texel indices are int
  // Not initialised: only the texels of each level are written, and only they are read.
  p.taps.resize(size_t(pyramid_rows) * size_t(size.width));
  p.senders.resize(size_t(size.area()));  // every element written by write_full_resolution
  return p;
}

// The eye rays' steps per pixel, for the tangent planes' screen gradients (pixel_plane).
struct PlaneRays {
  bool perspective;
  glm::vec3 du, dv;  // ray(u + 1, v) - ray(u, v) and ray(u, v + 1) - ray(u, v)
};

PlaneRays plane_rays(const Camera& camera) {
  const glm::vec3 ray_00 = camera.view_from_pixel_depth({0.0f, 0.0f}, 1.0f);
  return {camera.is_perspective(), camera.view_from_pixel_depth({1.0f, 0.0f}, 1.0f) - ray_00,
          camera.view_from_pixel_depth({0.0f, 1.0f}, 1.0f) - ray_00};
}

// A pixel's tangent plane as the taps read it: its depth (+inf where nothing is) and the
// screen gradients of 1 / depth ((0, 0): not used). Tangent plane n . X = n . P of pixel q
// met by the eye ray through pixel (u, v), X = depth ray(u, v) with ray(u, v) the view
// point at depth 1 (affine in u, v for a perspective camera): 1 / depth = n . ray(u, v) /
// (n . P), so its gradients are n . ray_du / (n . P) and n . ray_dv / (n . P).
struct PixelPlane {
  float depth_view;
  glm::vec2 inv_depth_gradient;
};

PixelPlane pixel_plane(const SsdoInputs& in, const PlaneRays& rays, const SenderTexel& q, int x, int y) {
  const float d = in.depth_view.ptr<float>(y)[x];
  const bool foreground = in.mask.ptr<uint8_t>(y)[x] != 0 && d > 0.0f && d < std::numeric_limits<float>::infinity();
  PixelPlane plane{foreground ? d : std::numeric_limits<float>::infinity(), glm::vec2(0.0f)};
  const float n_dot_p = glm::dot(q.normal_view, q.position_view);
  // A plane through the eye (n . P ~ 0) is seen edge-on: no usable gradient. The threshold
  // is relative to the depth (|n . P| = depth x |cos| of the view angle), i.e. views within
  // ~0.06 deg of grazing keep the centre depth.
  if (foreground && rays.perspective && std::abs(n_dot_p) > 1e-3f * d)
    plane.inv_depth_gradient = {glm::dot(q.normal_view, rays.du) / n_dot_p, glm::dot(q.normal_view, rays.dv) / n_dot_p};
  return plane;
}

// The texel centred at `centre` (pixels) that keeps the plane of the pixel whose centre is
// at `source`: the plane's depth there, clamped as test_lanes clamps a tap's, and its
// relative gradients; where the clamp holds or the plane has passed the eye, the clamped
// or the source's depth without gradients (what a tap there would find).
TapTexel plane_texel(const PixelPlane& q, glm::vec2 source, glm::vec2 centre) {
  if (!(q.depth_view < std::numeric_limits<float>::infinity())) return {q.depth_view, 0u};
  // depth_q / depth at the centre (as test_lanes' depth_ratio).
  const float depth_ratio = 1.0f + q.depth_view * glm::dot(q.inv_depth_gradient, centre - source);
  const float limit = kPlaneCorrectionMaxRelative * q.depth_view;
  if (!(depth_ratio > 0.0f)) return {q.depth_view, 0u};
  const float depth = q.depth_view / depth_ratio;
  if (!(std::abs(depth - q.depth_view) <= limit))
    return {std::clamp(depth, q.depth_view - limit, q.depth_view + limit), 0u};
  const glm::vec2 g = depth * q.inv_depth_gradient;
  return {depth, bfloat16_bits(g.x) | (bfloat16_bits(g.y) << 16)};
}

// Level 0 and the senders: each pixel's position and normal, and its tangent plane at its
// centre.
void write_full_resolution(const SsdoInputs& in, const PlaneRays& rays, TapPyramid& p, int nthreads) {
  const int width = p.width;
  parallel_rows(cv::Range(0, in.depth_view.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const cv::Vec3f* nrm = in.normal_view.ptr<cv::Vec3f>(y);
      const cv::Vec3f* pos = in.position_view.ptr<cv::Vec3f>(y);
      TapTexel* t = &p.taps[p.level_row(0, y)];
      SenderTexel* snd = &p.senders[size_t(y) * size_t(width)];
      for (int x = 0; x < width; ++x) {
        snd[x].position_view = glm::vec3(pos[x][0], pos[x][1], pos[x][2]);
        snd[x].normal_view = glm::vec3(nrm[x][0], nrm[x][1], nrm[x][2]);
        const glm::vec2 centre(float(x) + 0.5f, float(y) + 0.5f);
        t[x] = plane_texel(pixel_plane(in, rays, snd[x], x, y), centre, centre);
      }
    }
  });
}

// The full-resolution pixel whose tangent plane texel (x, y) of level l keeps: from each
// level, SAO's rotated grid, child (2x + (y & 1 ^ 1), 2y + (x & 1 ^ 1)), clamped to the
// image.
cv::Point source_pixel(const TapPyramid& p, int l, int x, int y) {
  for (; l > 0; --l) {
    const int cx = std::min(2 * x + ((y & 1) ^ 1), p.level_width[l - 1] - 1);
    const int cy = std::min(2 * y + ((x & 1) ^ 1), p.level_height[l - 1] - 1);
    x = cx, y = cy;
  }
  return {x, y};
}

// Levels l > 0: each texel the plane of its source pixel at the texel's centre.
void write_coarse_levels(const SsdoInputs& in, const PlaneRays& rays, TapPyramid& p, int nthreads) {
  for (int l = 1; l < p.n_levels; ++l)
    parallel_rows(cv::Range(0, p.level_height[l]), nthreads, [&](const cv::Range& rows) {
      const float texel_px = float(1 << l);
      for (int y = rows.start; y < rows.end; ++y) {
        TapTexel* lt = &p.taps[p.level_row(l, y)];
        for (int x = 0; x < p.level_width[l]; ++x) {
          const cv::Point s = source_pixel(p, l, x, y);
          const SenderTexel& q = p.senders[size_t(s.y) * size_t(p.width) + size_t(s.x)];
          lt[x] = plane_texel(pixel_plane(in, rays, q, s.x, s.y), glm::vec2(float(s.x) + 0.5f, float(s.y) + 0.5f),
                              glm::vec2((float(x) + 0.5f) * texel_px, (float(y) + 0.5f) * texel_px));
        }
      }
    });
}

// Each texel's occluder thickness from the second depth layer: back - front of its source
// pixel, as a planar depth difference (test_lanes compares planar depths); 0 where the
// back layer is not behind the front one (only the bias' allowance then).
void write_thickness(const SsdoInputs& in, TapPyramid& p) {
  p.thickness.assign(p.taps.size(), 0.0f);
  for (int l = 0; l < p.n_levels; ++l)
    for (int y = 0; y < p.level_height[l]; ++y)
      for (int x = 0; x < p.level_width[l]; ++x) {
        const cv::Point s = source_pixel(p, l, x, y);
        const float front = in.depth_view.ptr<float>(s.y)[s.x], back = in.depth_back_view->ptr<float>(s.y)[s.x];
        p.thickness[p.level_row(l, y) + size_t(x)] = back > front ? back - front : 0.0f;
      }
}

// The tap pyramid of a frame (McGuire et al. 2012): level 0 from the G-buffer, then the
// coarser levels, and the texels' thickness when there is a second depth layer.
TapPyramid build_tap_pyramid(const SsdoInputs& in, const SsdoSettings& settings, int nthreads) {
  TapPyramid p = allocate_tap_pyramid(in.depth_view.size(), settings);
  const PlaneRays rays = plane_rays(in.camera);
  write_full_resolution(in, rays, p, nthreads);
  write_coarse_levels(in, rays, p, nthreads);
  if (in.depth_back_view != nullptr && !in.depth_back_view->empty()) write_thickness(in, p);
  return p;
}

// (cos, sin) of the R2 sequence's azimuths (Constants::azimuth_cos, azimuth_sin).
struct SampleAzimuths {
  std::vector<float> cos, sin;
};

SampleAzimuths sample_azimuths(int samples) {
  SampleAzimuths a{std::vector<float>(size_t(samples)), std::vector<float>(size_t(samples))};
  for (int i = 0; i < samples; ++i) {
    const double angle = 2.0 * std::numbers::pi * (kR2Second * double(i) - std::floor(kR2Second * double(i)));
    a.cos[size_t(i)] = float(std::cos(angle));
    a.sin[size_t(i)] = float(std::sin(angle));
  }
  return a;
}

Constants frame_constants(const SsdoInputs& in, const SsdoSettings& settings, const TapPyramid& p,
                          const SampleAzimuths& azimuths) {
  Constants c{};
  c.pyramid = p.taps.data();
  c.frame_origin_px = in.frame_origin_px;
  c.pyramid_thickness = p.thickness.empty() ? nullptr : p.thickness.data();
  c.pyramid_rows_2h = int(p.rows_2h);
  c.n_levels = p.n_levels;
  c.senders = p.senders.data();
  c.depth = &in.depth_view;
  c.normal = &in.normal_view;
  c.position = &in.position_view;
  c.mask = &in.mask;
  c.albedo = in.albedo && !in.albedo->empty() ? in.albedo : nullptr;
  c.lighting = in.lighting && !in.lighting->empty() ? in.lighting : nullptr;
  c.camera = &in.camera;
  c.env = &in.environment;
  c.clip_from_view = in.camera.view_to_clip;
  c.env_from_view = in.environment.env_from_world_matrix() * glm::mat3(in.camera.view_to_world);
  c.width_px = float(in.depth_view.cols);
  c.height_px = float(in.depth_view.rows);
  c.s = settings;
  c.bent_normal = settings.direct_estimator == SsdoDirectEstimator::bent_normal;
  c.control_variate = settings.direct_estimator == SsdoDirectEstimator::open_minus_occluded;
  c.form_factor = settings.indirect_estimator == SsdoIndirectEstimator::form_factor;
  c.sender_distance_min2_world = settings.sender_distance_min_world * settings.sender_distance_min_world;
  c.azimuth_cos = azimuths.cos.data();
  c.azimuth_sin = azimuths.sin.data();
  c.noise = StratifiedNoise(settings.seed);
  return c;
}

// Each sample's sender from the sender pass (method ssdo, indirect wanted, no `lighting`),
// so that the receiver pass need not march again: per pixel, per sample, the sender's
// pixel index or -1 (ssdo_pixel). Empty when not wanted or over kRecordBudgetBytes. Not
// zeroed: the sender pass writes every foreground pixel's record, the only ones read.
struct SenderRecord {
  UninitializedVector<int32_t> senders;
  size_t width = 0, samples = 0;

  int32_t* at(int x, int y) { return senders.empty() ? nullptr : &senders[offset(x, y)]; }
  const int32_t* at(int x, int y) const { return senders.empty() ? nullptr : &senders[offset(x, y)]; }
  size_t offset(int x, int y) const { return (size_t(y) * width + size_t(x)) * samples; }
};

SenderRecord sender_record(const Constants& c, cv::Size size, bool want_indirect) {
  SenderRecord record;
  record.width = size_t(size.width);
  record.samples = size_t(c.s.samples);
  const size_t record_size = size_t(size.area()) * size_t(c.s.samples);
  if (want_indirect && !c.lighting && c.s.method == SsdoMethod::ssdo &&
      record_size * sizeof(int32_t) <= kRecordBudgetBytes)
    record.senders.resize(record_size);
  return record;
}

// Sender pass (no `lighting`): direct light at every pixel, the senders' light
// L_q = albedo_q x direct_q; method ssdo also records each sample's sender.
void sender_pass(const Constants& c, SenderRecord& record, int nthreads, cv::Mat& sender_direct) {
  const cv::Mat& mask = *c.mask;
  const int width = mask.cols;
  sender_direct.create(mask.size(), CV_32FC3);
  parallel_rows(cv::Range(0, mask.rows), nthreads, [&](const cv::Range& rows) {
    glm::vec3 direct(0.0f), unused(0.0f);
    LocateQueue locate_queue;
    for (int x0 = 0; x0 < width; x0 += kTileWidthPx)
      for (int y = rows.start; y < rows.end; ++y) {
        const uint8_t* m = mask.ptr<uint8_t>(y);
        cv::Vec3f* d = sender_direct.ptr<cv::Vec3f>(y);
        for (int x = x0; x < std::min(x0 + kTileWidthPx, width); ++x) {
          if (!m[x]) {
            d[x] = cv::Vec3f(0.0f, 0.0f, 0.0f);
            continue;
          }
          light_pixel(c, x, y, true, false, sender_direct, record.at(x, y), nullptr, &locate_queue, direct, unused);
          d[x] = cv::Vec3f(direct.x, direct.y, direct.z);
        }
      }
    locate_queue.run(c);
  }, kStripRows);
}

// Receiver pass over roi: direct (the sender pass's where there is one) and indirect at
// every foreground pixel, 0 on background.
void receiver_pass(const Constants& c, const cv::Mat& sender_direct, const SenderRecord& record, bool want_indirect,
                   const cv::Rect& r, int nthreads, SsdoOutput& out) {
  const cv::Mat& mask = *c.mask;
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int x0 = r.x; x0 < r.x + r.width; x0 += kTileWidthPx)
      for (int y = rows.start; y < rows.end; ++y) {
        const uint8_t* m = mask.ptr<uint8_t>(y);
        cv::Vec3f* od = out.direct.ptr<cv::Vec3f>(y);
        cv::Vec3f* oi = out.indirect.ptr<cv::Vec3f>(y);
        for (int x = x0; x < std::min(x0 + kTileWidthPx, r.x + r.width); ++x) {
          if (!m[x]) {
            od[x] = oi[x] = cv::Vec3f(0.0f, 0.0f, 0.0f);
            continue;
          }
          glm::vec3 direct(0.0f), indirect(0.0f);
          if (!sender_direct.empty()) {
            const cv::Vec3f& d = sender_direct.at<cv::Vec3f>(y, x);
            direct = glm::vec3(d[0], d[1], d[2]);
            light_pixel(c, x, y, false, true, sender_direct, nullptr, record.at(x, y), nullptr, direct, indirect);
          } else {
            light_pixel(c, x, y, true, want_indirect, sender_direct, nullptr, nullptr, nullptr, direct, indirect);
          }
          od[x] = cv::Vec3f(direct.x, direct.y, direct.z);
          oi[x] = cv::Vec3f(indirect.x, indirect.y, indirect.z);
        }
      }
  }, kStripRows);
}

// E_tab(n) / pi (Environment::irradiance_over_pi_env) at the view-space normal n of every
// pixel of rows r, a vector of pixels at a time (equirect_lanes on the irradiance table:
// the bits of the scalar lookup), into a CV_32FC3 image of the frame's size. Background
// pixels get the value of their normal too (0: a direction the lookup tolerates), read by
// nobody.
cv::Mat irradiance_at_normals(const Constants& c, const cv::Rect& r, int nthreads) {
  cv::Mat out(c.normal->size(), CV_32FC3);
  const cv::Mat& table = c.env->irradiance_map();
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    const hn::ScalableTag<float> d;
    const int lanes = int(hn::Lanes(d));
    HWY_ALIGN float tail[3 * hn::MaxLanes(d)];
    for (int y = rows.start; y < rows.end; ++y) {
      const float* normal = c.normal->ptr<float>(y);
      float* row = out.ptr<float>(y);
      for (int x = r.x; x < r.x + r.width; x += lanes) {
        const int count = std::min(lanes, r.x + r.width - x);
        const float* in = normal + 3 * x;
        if (count < lanes) {  // the row's last pixels; the lanes past them normal 0
          std::fill(std::copy_n(in, 3 * count, tail), tail + 3 * lanes, 0.0f);
          in = tail;
        }
        hn::Vec<decltype(d)> nx, ny, nz, red, green, blue;
        hn::LoadInterleaved3(d, in, nx, ny, nz);
        equirect_lanes(d, table, c.env_from_view, nx, ny, nz, red, green, blue);
        if (count == lanes) {
          hn::StoreInterleaved3(red, green, blue, d, row + 3 * x);
        } else {
          hn::StoreInterleaved3(red, green, blue, d, tail);
          std::copy_n(tail, 3 * count, row + 3 * x);
        }
      }
    }
  }, kStripRows);
  return out;
}

}  // namespace

// compute_ssdo() for this instruction set; the inputs are checked.
void compute_ssdo_checked(const SsdoInputs& in, const SsdoSettings& settings, SsdoOutput& out, cv::Rect roi,
                          int nthreads) {
  const cv::Size size = in.depth_view.size();
  if (out.direct.size() != size || out.direct.type() != CV_32FC3) out.direct.create(size, CV_32FC3);
  if (out.indirect.size() != size || out.indirect.type() != CV_32FC3) out.indirect.create(size, CV_32FC3);
  // Constants from the settings once, then the passes (Ritschel et al. 2009, sec. 3): the
  // tap pyramid, the senders' direct light (when the frame has no `lighting`), the
  // receivers' direct and indirect light.
  const TapPyramid pyramid = build_tap_pyramid(in, settings, nthreads);
  const SampleAzimuths azimuths = sample_azimuths(settings.samples);
  Constants c = frame_constants(in, settings, pyramid, azimuths);
  const bool want_indirect = settings.indirect_strength > 0.0f;
  const bool sender_pass_runs = want_indirect && !c.lighting;
  const cv::Rect r = resolve_roi(roi, size);
  // The control variate's E_tab(n) / pi of every pixel the passes light, in vector lanes
  // (a constant light has one value: looked up as is).
  cv::Mat irradiance;
  if (c.control_variate && settings.method == SsdoMethod::ssdo && in.environment.kind() != EnvironmentKind::constant) {
    irradiance = irradiance_at_normals(c, sender_pass_runs ? cv::Rect({0, 0}, size) : r, nthreads);
    c.irradiance_at_normal = &irradiance;
  }
  SenderRecord record = sender_record(c, size, want_indirect);
  cv::Mat sender_direct;
  if (sender_pass_runs) sender_pass(c, record, nthreads, sender_direct);
  receiver_pass(c, sender_direct, record, want_indirect, r, nthreads, out);
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo {

HWY_EXPORT(compute_ssdo_checked);

namespace {

constexpr std::pair<SsdoMethod, std::string_view> kSsdoMethodNames[] = {
    {SsdoMethod::ssdo, "ssdo"}, {SsdoMethod::oracle, "oracle"}};

}  // namespace

std::string_view to_string(SsdoMethod m) { return enum_name<SsdoMethod>(kSsdoMethodNames, m); }
std::optional<SsdoMethod> parse_ssdo_method(std::string_view s) {
  return parse_enum<SsdoMethod>(kSsdoMethodNames, s);
}

SsdoSettings ssdo_preset(SsdoMethod method, Preset preset) {
  SsdoSettings s;
  s.method = method;
  const int level = int(preset);  // 0 low .. 3 ultra
  // Measured against the oracle at high on the shared frames (tests/accuracy), denoised
  // as the pipeline does (footprint scaled to the grid, kernels/denoise.h): the bounce of
  // medium is within 13-18% relative MAE (16 samples x 6 points on every pixel: 10-15%);
  // low and medium run on the half-resolution grid (a quarter of the pixels). Directions
  // cost more than the denoise's wider footprint on that grid: medium's 8 with it are
  // within 0.01 of 16 with the footprint of full resolution (docs/performance.md,
  // "Directions against the denoise's footprint").
  constexpr int kSamples[] = {8, 8, 16, 32};
  constexpr int kSampleSteps[] = {4, 6, 8, 8};
  constexpr int kRefinements[] = {2, 3, 3, 4};
  constexpr int kDivisor[] = {2, 2, 1, 1};
  constexpr int kOracleGrid[] = {8, 12, 16, 32};
  constexpr int kOracleSteps[] = {32, 48, 64, 128};
  s.samples = kSamples[level];
  s.sample_steps = kSampleSteps[level];
  s.sample_refinements = kRefinements[level];
  s.resolution_divisor = kDivisor[level];
  s.oracle_grid = kOracleGrid[level];
  s.oracle_steps = kOracleSteps[level];
  return s;
}

bool runs_on_half_grid(const SsdoSettings& s) {
  return s.resolution_divisor == 2 && s.method == SsdoMethod::ssdo;
}

using HWY_NAMESPACE::kMaxSampleSteps;

std::string validate(const SsdoSettings& s) {
  if (std::string e = detail::check_radius(s.radius_world, s.max_radius_px); !e.empty()) return e;
  if (s.samples < 1 || s.samples > 1024) return detail::out_of_range("samples", s.samples, "[1, 1024]");
  if (s.sample_steps < 1 || s.sample_steps > kMaxSampleSteps)
    return detail::out_of_range("sample_steps", s.sample_steps,
                                ("[1, " + std::to_string(kMaxSampleSteps) + "]").c_str());
  if (s.sample_refinements < 0 || s.sample_refinements > 16)
    return detail::out_of_range("sample_refinements", s.sample_refinements, "[0, 16]");
  if (!(s.thickness_world > 0.0f)) return detail::out_of_range("thickness_world", s.thickness_world, "(0, inf]");
  if (!(s.depth_bias_relative >= 0.0f && s.depth_bias_relative <= 0.1f))
    return detail::out_of_range("depth_bias_relative", s.depth_bias_relative, "[0, 0.1]");
  if (!(s.indirect_strength >= 0.0f && s.indirect_strength <= 16.0f))
    return detail::out_of_range("indirect_strength", s.indirect_strength, "[0, 16]");
  if (!(s.sender_distance_min_world >= 0.0f) || !std::isfinite(s.sender_distance_min_world))
    return detail::out_of_range("sender_distance_min_world", s.sender_distance_min_world, "[0, inf)");
  if (s.resolution_divisor < 1 || s.resolution_divisor > 2)
    return detail::out_of_range("resolution_divisor", s.resolution_divisor, "[1, 2]");
  if (s.oracle_grid < 1 || s.oracle_grid > 256) return detail::out_of_range("oracle_grid", s.oracle_grid, "[1, 256]");
  if (s.oracle_steps < 1 || s.oracle_steps > 4096)
    return detail::out_of_range("oracle_steps", s.oracle_steps, "[1, 4096]");
  return {};
}

void compute_ssdo(const SsdoInputs& in, const SsdoSettings& settings, SsdoOutput& out, cv::Rect roi,
                  int nthreads) {
  const cv::Size size = in.depth_view.size();
  CV_Assert(in.depth_view.type() == CV_32FC1);
  CV_Assert(in.mask.type() == CV_8UC1 && in.mask.size() == size);
  CV_Assert(in.normal_view.type() == CV_32FC3 && in.normal_view.size() == size);
  CV_Assert(in.position_view.type() == CV_32FC3 && in.position_view.size() == size);
  CV_Assert(!in.albedo || (in.albedo->type() == CV_32FC3 && in.albedo->size() == size));
  CV_Assert(!in.lighting || (in.lighting->type() == CV_32FC3 && in.lighting->size() == size));
  CV_Assert(!in.depth_back_view || in.depth_back_view->empty() ||
            (in.depth_back_view->type() == CV_32FC1 && in.depth_back_view->size() == size));
  CV_Assert(in.camera.width_px == size.width && in.camera.height_px == size.height);
  CV_Assert(validate(settings).empty());
  HWY_DYNAMIC_DISPATCH(compute_ssdo_checked)(in, settings, out, roi, nthreads);
}

}  // namespace ssdo
#endif  // HWY_ONCE
