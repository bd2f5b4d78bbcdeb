#include "formats/foreground_pass.h"

#include "core/simd_targets.h"  // before Highway

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "formats/foreground_pass.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <algorithm>
#include <cstring>

// Vectors are kept in the structs below; on the baseline GCC notes that functions passing
// them by value would have another ABI than with AVX: they are all internal and inlined.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

HWY_BEFORE_NAMESPACE();
namespace ssdo::foreground::HWY_NAMESPACE {
namespace {

namespace hn = hwy::HWY_NAMESPACE;
using DF = hn::ScalableTag<float>;
using VF = hn::Vec<DF>;

// One pixel of foreground_row, every case (the vector groups' fallback and the row's tail:
// left to the compiler to inline or call).
void foreground_pixel(const ForegroundPass& pass, const glm::vec3& ray_row,
                      const ForegroundRow& row, int x, RowCounts& counts) {
  float* depth = row.depth;
  cv::Vec3f* normal = row.normal;
  bool nonfinite = !std::isfinite(depth[x]);
  glm::vec3 n(0.0f);
  if (normal) {
    n = glm::vec3(normal[x][0], normal[x][1], normal[x][2]);
    if (!std::isfinite(n.x) || !std::isfinite(n.y) || !std::isfinite(n.z)) nonfinite = true;
  }
  const glm::vec3 ray = eye_ray(pass, ray_row, x);
  const float d =
      nonfinite ? std::numeric_limits<float>::infinity() : planar_depth(pass, ray, depth[x]);
  if (d == std::numeric_limits<float>::infinity()) {
    counts.nonfinite += nonfinite ? 1 : 0;
    depth[x] = std::numeric_limits<float>::infinity();
    row.mask[x] = 0;
    if (normal) normal[x] = cv::Vec3f(0, 0, 0);
    return;
  }
  depth[x] = d;
  row.mask[x] = 255;
  ++counts.foreground;
  counts.depth_min = std::min(counts.depth_min, d);
  counts.depth_max = std::max(counts.depth_max, d);
  if (!normal) return;
  if (pass.normals_world) n = pass.normal_to_view * n;
  float len = glm::length(n);
  // A finite normal whose squared length overflows (components past ~1.8e19): its
  // direction, scaled down by its largest component first.
  if (len == std::numeric_limits<float>::infinity() && std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z)) {
    n /= std::max({std::abs(n.x), std::abs(n.y), std::abs(n.z)});
    len = glm::length(n);
  }
  if (!(len > kMinNormalLength) || !std::isfinite(len)) {
    row.repair[x] = 1;
    ++counts.repaired;
    normal[x] = cv::Vec3f(0, 0, 0);
    return;
  }
  n /= len;
  // Face the camera: a normal pointing away from the eye (back face, or a renderer that
  // does not flip shading normals) is turned around, since the kernels integrate over the
  // visible side's hemisphere.
  if (glm::dot(n, ray) > 0.0f) {
    n = -n;
    ++counts.facing_away;
  }
  normal[x] = cv::Vec3f(n.x, n.y, n.z);
}

// A vector of pixels' (x, y, z) vectors, one component per register.
struct Vec3s {
  VF x, y, z;
};

// ForegroundPass and the row's first eye ray, broadcast to every lane.
struct ForegroundLanes {
  VF zero, infinity, min_depth, background_depth, far_view, background, min_length;
  VF m00, m10, m20, m01, m11, m21, m02, m12, m22;  // normal_to_view
  VF ray_row_x, ray_row_y, ray_row_z, step_x, step_y, step_z, lanes;
};

// Built whole at its return, never default-constructed (structs of Highway vectors on Arm:
// docs/architecture.md).
HWY_INLINE ForegroundLanes broadcast(const ForegroundPass& pass, const glm::vec3& ray_row) {
  const DF df;
  const float inf = std::numeric_limits<float>::infinity();
  const glm::mat3& m = pass.normal_to_view;
  const auto set = [&](float v) { return hn::Set(df, v); };
  return {hn::Zero(df),
          set(inf),
          set(kMinForegroundDepth),
          set(kBackgroundDepth),
          // No far clip: +inf, which no depth exceeds; no background value: NaN, which no
          // depth equals.
          set(pass.far_view > 0.0f ? pass.far_view : inf),
          set(pass.has_background ? pass.background : std::numeric_limits<float>::quiet_NaN()),
          set(kMinNormalLength),
          set(m[0][0]), set(m[1][0]), set(m[2][0]),
          set(m[0][1]), set(m[1][1]), set(m[2][1]),
          set(m[0][2]), set(m[1][2]), set(m[2][2]),
          set(ray_row.x), set(ray_row.y), set(ray_row.z),
          set(pass.ray_step_x.x), set(pass.ray_step_x.y), set(pass.ray_step_x.z),
          hn::Iota(df, 0.0f)};
}

// Lanes whose depth and normal are finite: |v| < inf (false for NaN).
HWY_INLINE hn::Mask<DF> finite(const ForegroundLanes& c, VF depth, const Vec3s& n) {
  auto finite1 = [&](VF v) { return hn::Lt(hn::Abs(v), c.infinity); };
  return hn::And(hn::And(finite1(depth), finite1(n.x)), hn::And(finite1(n.y), finite1(n.z)));
}

// The eye rays through the pixel centres x, x + 1, .., as eye_ray steps them.
HWY_INLINE Vec3s eye_rays(const ForegroundLanes& c, bool perspective, int x) {
  const DF df;
  if (!perspective) return {c.zero, c.zero, hn::Set(df, -1.0f)};
  // float(x) + lane is float(x + lane): integers this small are exact.
  const VF at = hn::Add(hn::Set(df, float(x)), c.lanes);
  return {hn::Add(c.ray_row_x, hn::Mul(at, c.step_x)), hn::Add(c.ray_row_y, hn::Mul(at, c.step_y)),
          hn::Add(c.ray_row_z, hn::Mul(at, c.step_z))};
}

// glm::dot's sum, in its order.
HWY_INLINE VF dot(const Vec3s& a, const Vec3s& b) {
  return hn::Add(hn::Add(hn::Mul(a.x, b.x), hn::Mul(a.y, b.y)), hn::Mul(a.z, b.z));
}

// normal_to_view * v, as glm's mat3 * vec3 sums it.
HWY_INLINE Vec3s to_view(const ForegroundLanes& c, const Vec3s& v) {
  auto row = [&](VF a, VF b, VF d) {
    return hn::Add(hn::Add(hn::Mul(a, v.x), hn::Mul(b, v.y)), hn::Mul(d, v.z));
  };
  return {row(c.m00, c.m10, c.m20), row(c.m01, c.m11, c.m21), row(c.m02, c.m12, c.m22)};
}

// foreground_pixel on the pixels x .. x + lanes - 1 when all are foreground with a usable
// normal; false, with nothing written, otherwise. The operations are foreground_pixel's,
// in its order and without contraction (-ffp-contract=off; IEEE add, multiply, divide and
// square root round the same in every lane width), so the bits are its.
HWY_INLINE bool foreground_group(const ForegroundPass& pass, const ForegroundLanes& c,
                                 const ForegroundRow& row, int x, VF& depth_min, VF& depth_max,
                                 int64_t& facing_away) {
  const DF df;
  const VF stored = hn::LoadU(df, row.depth + x);
  float* n_at = &row.normal[x][0];
  VF nx, ny, nz;  // not into a Vec3s: see broadcast
  hn::LoadInterleaved3(df, n_at, nx, ny, nz);
  Vec3s n{nx, ny, nz};
  auto usable = finite(c, stored, n);
  const Vec3s ray = eye_rays(c, pass.perspective, x);
  VF d = stored;
  if (pass.radial && pass.perspective) d = hn::Div(d, hn::Sqrt(dot(ray, ray)));
  usable = hn::And(usable, hn::And(hn::Ge(d, c.min_depth), hn::Lt(d, c.background_depth)));
  usable = hn::AndNot(hn::Or(hn::Gt(d, c.far_view), hn::Eq(stored, c.background)), usable);
  if (pass.normals_world) n = to_view(c, n);
  const VF len = hn::Sqrt(dot(n, n));
  usable = hn::And(usable, hn::And(hn::Gt(len, c.min_length), hn::Lt(len, c.infinity)));
  if (!hn::AllTrue(df, usable)) return false;
  n = {hn::Div(n.x, len), hn::Div(n.y, len), hn::Div(n.z, len)};
  // Face the camera (foreground_pixel): -n is n with its sign bits flipped.
  const auto away = hn::Gt(dot(n, ray), c.zero);
  facing_away += int64_t(hn::CountTrue(df, away));
  n = {hn::IfThenElse(away, hn::Neg(n.x), n.x), hn::IfThenElse(away, hn::Neg(n.y), n.y),
       hn::IfThenElse(away, hn::Neg(n.z), n.z)};
  hn::StoreU(d, df, row.depth + x);
  std::memset(row.mask + x, 255, hn::Lanes(df));
  hn::StoreInterleaved3(n.x, n.y, n.z, df, n_at);
  depth_min = hn::Min(depth_min, d);
  depth_max = hn::Max(depth_max, d);
  return true;
}

// foreground_row's pixels a vector at a time while all are foreground with a usable normal
// (nearly every group of a rendered frame); any other group goes pixel by pixel. Returns
// the first pixel not done.
HWY_INLINE int foreground_groups(const ForegroundPass& pass, const glm::vec3& ray_row,
                                 const ForegroundRow& row, RowCounts& counts) {
  const DF df;
  const int lanes = int(hn::Lanes(df));
  const ForegroundLanes c = broadcast(pass, ray_row);
  VF depth_min = c.infinity, depth_max = hn::Neg(c.infinity);
  int x = 0;
  for (; x + lanes <= pass.width; x += lanes) {
    if (foreground_group(pass, c, row, x, depth_min, depth_max, counts.facing_away)) {
      counts.foreground += lanes;
    } else {
      for (int i = 0; i < lanes; ++i) foreground_pixel(pass, ray_row, row, x + i, counts);
    }
  }
  // Foreground depths are finite and positive: the extremes do not depend on the order.
  counts.depth_min = std::min(counts.depth_min, hn::GetLane(hn::MinOfLanes(df, depth_min)));
  counts.depth_max = std::max(counts.depth_max, hn::GetLane(hn::MaxOfLanes(df, depth_max)));
  return x;
}

}  // namespace

// foreground_row (foreground_pass.h) on this target.
RowCounts foreground_row_lanes(const ForegroundPass pass, const glm::vec3 ray_row,
                               const ForegroundRow row) {
  RowCounts counts;
  int x = 0;
  // A one-lane target (the scalar baseline) goes pixel by pixel: a group of one would be
  // the pixel's work and the test of the group besides.
  if (row.normal && hn::Lanes(DF()) > 1) x = foreground_groups(pass, ray_row, row, counts);
  for (; x < pass.width; ++x) foreground_pixel(pass, ray_row, row, x, counts);
  return counts;
}

}  // namespace ssdo::foreground::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo::foreground {

HWY_EXPORT(foreground_row_lanes);

RowCounts foreground_row(const ForegroundPass pass, const glm::vec3 ray_row,
                         const ForegroundRow row) {
  return HWY_DYNAMIC_DISPATCH(foreground_row_lanes)(pass, ray_row, row);
}

}  // namespace ssdo::foreground
#endif  // HWY_ONCE
