// The raymarch AO oracle: slow on purpose, the best a screen-space method can do with the
// frame's information. Per pixel, `directions` cosine-weighted rays around the normal
// (the same R2 + concentric-map directions as the reference ray caster, raycast.cpp), each
// marched in `steps` view-space steps up to radius_world. A step is projected to the
// screen and tested against the surface stored at the pixel it lands in:
//
//   blocked  <=>  depth(q) > d_ref + bias   and   depth(q) - d_ref <= thickness_world
//
// where depth(q) is the step's planar depth and d_ref the stored surface's depth on the
// view ray through q (see below). With a second depth layer (AoInputs::depth_back_view,
// a back-face pass) the tap's own thickness replaces thickness_world: the step is inside
// the object between the two layers (depth peeling, Ritschel et al. 2009, sec. 3.3),
//
//   blocked  <=>  depth(q) > d_ref + bias   and   depth(q) - d_ref <= back(q) - depth(q_px) + bias
//
// (the thickness measured at the tap pixel centre, carried onto the tangent plane; a back
// depth of +inf, e.g. a floor or a wall, is solid behind the surface). Visibility is binary
// with no falloff (Cycles' AO pass: settings.falloff_fraction is not used), so AO = fraction
// of unblocked rays; with cosine-weighted directions that is the cosine-weighted open
// fraction of the hemisphere.
// Steps landing off-screen, behind the eye or on masked pixels never occlude (nothing is
// known there); they are counted into the confidence output (ao_raymarch.h).
//
// d_ref: the stored depth is a sample at the pixel centre, while q projects anywhere inside
// the pixel. On a surface seen at angle theta to the view ray the depth changes by up to
// (0.5 px footprint) * tan(theta) within half a pixel, far above any sensible bias at
// grazing angles, so a plain nearest read makes even an open plane occlude itself. The tap
// pixel's stored position and normal define its tangent plane; d_ref is where the view
// ray through q meets that plane (first order in the sub-pixel offset: exact on planes,
// error O(offset^2 / curvature radius) on curved surfaces). When that ray is within
// kMinTangentCos of parallel to the plane (silhouette taps) the extrapolation is
// ill-conditioned and the plain stored depth is used.
//
// max_radius_px is not applied: the oracle's cost is set by directions x steps, and
// clamping the radius would change the answer it exists to give.
#include "kernels/ao_raymarch.h"

#include <cmath>
#include <vector>

#include "kernels/ao_common.h"
#include "kernels/ao_methods.h"
#include "kernels/hemisphere_sampling.h"
#include "kernels/noise.h"
#include "core/parallel.h"

namespace ssdo {
namespace {

// Below this |cos| between the view ray through a step and the tap's normal, the tangent
// plane is not used for d_ref (the plain stored depth is). On a plane the extrapolation is
// exact at any angle; its error comes from the stored normal's rounding (~1e-7) amplified
// by 1 / cos, i.e. ~1e-4 of the sub-pixel offset at this threshold: negligible. Below it
// the tap is a silhouette (the tangent plane nearly contains the view ray), where the
// extrapolated depth runs off to 0 or infinity. 1e-3 = 89.94 degrees keeps the plane exact
// down to the horizon rows of a plane viewed at a few degrees of elevation.
constexpr float kMinTangentCos = 1e-3f;

struct Constants {
  int directions;
  int steps;
  float radius_world;
  float thickness_world;
  float bias_relative;
  uint32_t seed;
  bool perspective;
  bool multibounce;
  bool has_back;  // AoInputs::depth_back_view given: per-tap thickness
  float width_px, height_px;
};

// What a step needs from the pixel it lands in, packed so one 32-byte read serves it:
// the tangent plane dot(n_view, x) = plane_c of the stored surface, and the stored depth
// (negative = masked: unknown, never occludes).
struct Tap {
  float nx, ny, nz, plane_c;
  float depth_view;
  float thickness_world;  // behind the stored surface that is solid: thickness_world of
                          // the settings, or depth_back_view - depth_view when given
  float pad[2];
};

void build_taps(const AoInputs& in, float thickness_world, std::vector<Tap>& taps,
                int nthreads) {
  const cv::Mat* back = in.depth_back_view != nullptr && !in.depth_back_view->empty()
                            ? in.depth_back_view
                            : nullptr;
  const int width = in.depth_view.cols;
  taps.resize(size_t(width) * size_t(in.depth_view.rows));  // before the parallel loop
  parallel_rows(cv::Range(0, in.depth_view.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      const float* depth_row = in.depth_view.ptr<float>(y);
      for (int x = 0; x < width; ++x) {
        Tap& t = taps[size_t(y) * size_t(width) + size_t(x)];
        if (mask_row[x] == 0) {
          t = Tap{0.0f, 0.0f, 0.0f, 0.0f, -1.0f, 0.0f, {0.0f, 0.0f}};
          continue;
        }
        const glm::vec3 n = detail::load3(in.normal_view, x, y);
        const glm::vec3 p = detail::load3(in.position_view, x, y);
        float thickness = thickness_world;
        if (back) {
          // Back layer in front of the front one (rounding, or a peeled layer of another
          // object): no measured thickness, only the bias' allowance.
          const float b = back->ptr<float>(y)[x];
          thickness = b > depth_row[x] ? b - depth_row[x] : 0.0f;
        }
        t = Tap{n.x, n.y, n.z, glm::dot(n, p), depth_row[x], thickness, {0.0f, 0.0f}};
      }
    }
  });
}

// A pixel's ray origin: biased along the normal, and its clip-space image.
struct RayOrigin {
  glm::vec3 view;
  glm::vec4 clip;
};

// A ray's verdict: blocked by a stored surface, or seen through a step that is unknown
// (off screen, behind the eye or masked).
struct RayVerdict {
  bool blocked = false;
  bool unknown = false;
};

// Steps tested per batch: a batch's reference depths are computed together (below), so a
// ray blocked early wastes at most a batch's worth of them.
constexpr int kBatchSteps = 16;

// A ray's steps where they land, before any of them is tested: the steps do not depend on
// each other, so the loops that fill this run in vector lanes, and with them the three
// divisions of a step (the march's cost). Per step j: its distance s, its clip-space w and
// its pixel coordinates (garbage where w <= 0: the march stops there before reading them);
// per step of the batch being tested: its planar depth and d_ref.
struct RaySteps {
  std::vector<float> s, clip_w, px, py;
  float depth_q[kBatchSteps], depth_ref[kBatchSteps];
  float tap_n[3][kBatchSteps], tap_plane_c[kBatchSteps], tap_depth[kBatchSteps];
  const Tap* tap[kBatchSteps];  // null: off screen (or behind the eye)
  void resize(int steps) {
    for (std::vector<float>* v : {&s, &clip_w, &px, &py}) v->resize(size_t(steps));
  }
};

// Step s_j = radius (j + 1 - jitter) / steps, jitter in [0, 1): one sample in each of the
// `steps` equal segments of (0, radius], the last at most radius; clip(origin + s w) =
// clip(origin) + s P [w, 0], the projection being linear in s.
inline void place_steps(const Constants& k, const glm::vec4& origin_clip, const glm::vec4& dir_clip, float jitter,
                        RaySteps& out) {
  float* __restrict s_out = out.s.data();
  float* __restrict w_out = out.clip_w.data();
  float* __restrict px_out = out.px.data();
  float* __restrict py_out = out.py.data();
  for (int j = 0; j < k.steps; ++j) {
    const float s = k.radius_world * (float(j) + 1.0f - jitter) / float(k.steps);
    const float clip_x = origin_clip.x + s * dir_clip.x;
    const float clip_y = origin_clip.y + s * dir_clip.y;
    const float clip_w = origin_clip.w + s * dir_clip.w;
    const float inv_w = 1.0f / clip_w;
    s_out[j] = s;
    w_out[j] = clip_w;
    px_out[j] = 0.5f * (clip_x * inv_w + 1.0f) * k.width_px;
    py_out[j] = 0.5f * (1.0f - clip_y * inv_w) * k.height_px;
  }
}

// d_ref (top of this file) of the steps j0 .. j0 + n - 1: the depth where the view ray
// through step q meets the tap pixel's tangent plane dot(n, x) = c, or the stored depth
// where that is ill-conditioned. Perspective: x = a q, a = c / dot(n, q). Orthographic:
// x = (q.x, q.y, -d), d = (n.x q.x + n.y q.y - c) / n.z. The taps the steps land on are
// gathered first; a step off screen reads the first tap, and its d_ref is never used.
inline void reference_depths(const Constants& k, const std::vector<Tap>& taps, int width, int height,
                             const glm::vec3& origin, const glm::vec3& w, int j0, int n, RaySteps& st) {
  for (int i = 0; i < n; ++i) {
    const int j = j0 + i;
    const float px = st.px[size_t(j)], py = st.py[size_t(j)];
    const bool on_screen = st.clip_w[size_t(j)] > 0.0f && px >= 0.0f && px < k.width_px && py >= 0.0f &&
                           py < k.height_px;
    const Tap& tap = on_screen ? taps[size_t(std::min(int(py), height - 1)) * size_t(width) +
                                      size_t(std::min(int(px), width - 1))]
                               : taps[0];
    st.tap[i] = on_screen ? &tap : nullptr;
    st.tap_n[0][i] = tap.nx;
    st.tap_n[1][i] = tap.ny;
    st.tap_n[2][i] = tap.nz;
    st.tap_plane_c[i] = tap.plane_c;
    st.tap_depth[i] = tap.depth_view;
  }
  constexpr float kMinTangentCos2 = kMinTangentCos * kMinTangentCos;
  for (int i = 0; i < n; ++i) {
    const float s = st.s[size_t(j0 + i)];
    const float qx = origin.x + s * w.x, qy = origin.y + s * w.y, qz = origin.z + s * w.z;
    const float depth_q = -qz;
    const float nx = st.tap_n[0][i], ny = st.tap_n[1][i], nz = st.tap_n[2][i];
    float d;
    bool usable;
    if (k.perspective) {
      const float denom = nx * qx + ny * qy + nz * qz;
      usable = denom * denom >= kMinTangentCos2 * (qx * qx + qy * qy + qz * qz);
      d = st.tap_plane_c[i] / denom * depth_q;
    } else {
      usable = std::abs(nz) >= kMinTangentCos;
      d = (nx * qx + ny * qy - st.tap_plane_c[i]) / nz;
    }
    st.depth_q[i] = depth_q;
    st.depth_ref[i] = usable && d > 0.0f ? d : st.tap_depth[i];
  }
}

// Marches direction w from the origin in `steps` jittered steps up to radius_world and tests
// each step against the surface stored where it lands (the blocked rule at the top of this
// file).
inline RayVerdict march_ray(const Constants& k, const AoInputs& in, const std::vector<Tap>& taps,
                            const RayOrigin& o, const glm::vec3& w, float jitter, RaySteps& st) {
  const int width = in.depth_view.cols, height = in.depth_view.rows;
  place_steps(k, o.clip, in.camera.view_to_clip * glm::vec4(w, 0.0f), jitter, st);
  RayVerdict r;
  bool entered = false;
  for (int j0 = 0; j0 < k.steps; j0 += kBatchSteps) {
    const int n = std::min(kBatchSteps, k.steps - j0);
    reference_depths(k, taps, width, height, o.view, w, j0, n, st);
    for (int i = 0; i < n; ++i) {
      // Off-screen and behind-the-eye steps are unknown. Both are final once the ray has
      // been on screen: clip.w is linear in s (once <= 0, it stays so), and the screen path
      // of a segment in front of the eye is a segment, which leaves the convex screen
      // rectangle at most once.
      if (!(st.clip_w[size_t(j0 + i)] > 0.0f)) {
        r.unknown = true;
        return r;
      }
      const Tap* tap = st.tap[i];
      if (tap == nullptr) {
        r.unknown = true;
        if (entered) return r;
        continue;
      }
      entered = true;
      if (tap->depth_view < 0.0f) {  // masked
        r.unknown = true;
        continue;
      }
      const float depth_q = st.depth_q[i], depth_ref = st.depth_ref[i];
      // Bias relative to the stored depth: its rounding error is relative (float: 6e-8,
      // half: 4.9e-4 of the value), so a fixed bias would be too large near the camera and
      // too small far away. The default 1e-3 covers half-float depth.
      const float bias = k.bias_relative * tap->depth_view;
      // With a back layer the bias also widens the slab: a thin object's two layers carry
      // the same relative rounding.
      r.blocked = depth_q > depth_ref + bias &&
                  depth_q - depth_ref <= tap->thickness_world + (k.has_back ? bias : 0.0f);
      if (r.blocked) return r;
    }
  }
  return r;
}

// A pixel's outputs.
struct PixelResult {
  float ao;
  glm::vec3 bent_normal;
  float confidence;
};

// Foreground pixel (x, y): the open fraction of its cosine-weighted rays, their mean
// direction, and the fraction of rays whose verdict rests on known samples only.
inline PixelResult shade_pixel(const Constants& k, const AoInputs& in, const std::vector<Tap>& taps, int x, int y,
                               RaySteps& steps) {
  const float depth = in.depth_view.ptr<float>(y)[x];
  const glm::vec3 p = detail::load3(in.position_view, x, y);
  const glm::vec3 n = detail::load3(in.normal_view, x, y);
  // Start offset along the normal, relative to depth like the bias: the first steps land in
  // the pixel's own footprint, and its reconstructed position carries the depth's relative
  // rounding error.
  const glm::vec3 origin = detail::biased_origin(p, n, depth, k.bias_relative);
  const RayOrigin o{origin, in.camera.view_to_clip * glm::vec4(origin, 1.0f)};
  glm::vec3 t, b;
  sampling::orthonormal_basis(n, t, b);
  const int nx = x - in.frame_origin_px.x, ny = y - in.frame_origin_px.y;  // the frame's pixel
  const float shift_u = noise01(nx, ny, 0, k.seed), shift_v = noise01(nx, ny, 1, k.seed);
  const uint32_t jitter_key = hash_pixel(nx, ny, 2, k.seed);
  int open = 0, resolved = 0;
  glm::vec3 bent(0.0f);
  for (int i = 0; i < k.directions; ++i) {
    float u, v;
    r2_point(uint32_t(i), shift_u, shift_v, u, v);
    const glm::vec3 w = sampling::cosine_hemisphere(n, t, b, u, v);
    const RayVerdict r = march_ray(k, in, taps, o, w, unit_float(hash_u32(jitter_key + uint32_t(i))), steps);
    if (!r.blocked) {
      ++open;
      bent += w;
    }
    if (r.blocked || !r.unknown) ++resolved;
  }
  float ao = float(open) / float(k.directions);
  if (k.multibounce) ao = detail::multibounce(ao, detail::albedo_luminance(in.albedo->ptr<cv::Vec3f>(y)[x]));
  const float len = glm::length(bent);
  return {ao, len > 0.0f ? bent / len : n, float(resolved) / float(k.directions)};
}

void raymarch_rows(const AoInputs& in, const Constants& k, AoOutput& out, cv::Mat* confidence,
                   const cv::Rect& roi, int nthreads) {
  std::vector<Tap> taps;
  build_taps(in, k.thickness_world, taps, nthreads);
  parallel_rows(cv::Range(roi.y, roi.y + roi.height), nthreads, [&](const cv::Range& rows) {
    RaySteps steps;
    steps.resize(k.steps);
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      float* ao_row = out.ao.ptr<float>(y);
      cv::Vec3f* bent_row = out.bent_normal_view.ptr<cv::Vec3f>(y);
      float* conf_row = confidence ? confidence->ptr<float>(y) : nullptr;
      for (int x = roi.x; x < roi.x + roi.width; ++x) {
        // Background: AO 1, no bent normal, confidence 1.
        const PixelResult r =
            mask_row[x] ? shade_pixel(k, in, taps, x, y, steps) : PixelResult{1.0f, glm::vec3(0.0f), 1.0f};
        ao_row[x] = r.ao;
        bent_row[x] = cv::Vec3f(r.bent_normal.x, r.bent_normal.y, r.bent_normal.z);
        if (conf_row) conf_row[x] = r.confidence;
      }
    }
  });
}

Constants make_constants(const AoInputs& in, const AoSettings& s) {
  return {s.directions,
          s.steps,
          s.radius_world,
          effective_thickness_world(s),
          s.depth_bias_relative,
          s.seed,
          in.camera.is_perspective(),
          s.multibounce && in.albedo != nullptr && !in.albedo->empty(),
          in.depth_back_view != nullptr && !in.depth_back_view->empty(),
          float(in.camera.width_px),
          float(in.camera.height_px)};
}

}  // namespace

void compute_ao_raymarch(const AoInputs& in, const AoSettings& s, AoOutput& out,
                         cv::Mat& confidence, cv::Rect roi, int nthreads) {
  CV_Assert(s.method == AoMethod::raymarch && validate(s).empty());
  CV_Assert(in.depth_view.type() == CV_32FC1);
  const cv::Size size = in.depth_view.size();
  CV_Assert(in.mask.type() == CV_8UC1 && in.mask.size() == size);
  CV_Assert(in.normal_view.type() == CV_32FC3 && in.normal_view.size() == size);
  CV_Assert(in.position_view.type() == CV_32FC3 && in.position_view.size() == size);
  CV_Assert(in.camera.width_px == size.width && in.camera.height_px == size.height);
  CV_Assert(in.depth_back_view == nullptr || in.depth_back_view->empty() ||
            (in.depth_back_view->type() == CV_32FC1 && in.depth_back_view->size() == size));
  if (out.ao.size() != size || out.ao.type() != CV_32FC1) out.ao.create(size, CV_32FC1);
  if (out.bent_normal_view.size() != size || out.bent_normal_view.type() != CV_32FC3)
    out.bent_normal_view.create(size, CV_32FC3);
  if (confidence.size() != size || confidence.type() != CV_32FC1) confidence.create(size, CV_32FC1);
  raymarch_rows(in, make_constants(in, s), out, &confidence, resolve_roi(roi, size), nthreads);
}

namespace detail {

void ao_raymarch(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi,
                 int nthreads) {
  CV_Assert(in.camera.width_px == in.depth_view.cols && in.camera.height_px == in.depth_view.rows);
  raymarch_rows(in, make_constants(in, s), out, nullptr, roi, nthreads);
}

}  // namespace detail
}  // namespace ssdo
