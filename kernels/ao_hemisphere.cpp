// Classic normal-oriented hemisphere SSAO, the baseline of the seed projects: Mittring
// 2007 ("Finding Next Gen: CryEngine 2") with the normal-oriented hemisphere of Chapman
// 2011 / LearnOpenGL "SSAO" (kernel scaled towards the centre, 4x4 tiled rotation noise,
// range check, depth bias).
//
// Per pixel, `samples` points P + r_i k_i in the hemisphere around the normal:
// - k_i: cosine-distributed unit directions (R2 sequence point i mapped with Malley's
//   method, so the occluded fraction of directions is cosine-weighted like Cycles' AO),
//   all pixels share the kernel;
// - r_i = radius * lerp(0.1, 1, t^2), t = i / samples (more samples near the centre, where
//   occluders shade most);
// - the kernel is rotated about the normal by an angle from a 4x4 tile of noise (the tile
//   repeats, so box_blur_4x4 in denoise.h removes its pattern exactly).
// A sample is occluded when the surface stored at its pixel is in front of it by more than
// the depth bias and by at most thickness_world; the occluder's weight fades with its 3D
// distance from the pixel over the last falloff_fraction of the radius (the range check:
// a far foreground object does not darken the background around its silhouette).
//
// This estimates the fraction of sample *points* inside geometry (volumetric obscurance),
// not of rays: it matches ray-traced AO where occluders are large (walls, corners) and
// differs where they are small (a sphere above a floor shadows more rays than it fills
// volume). No bent normal.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/ao_hemisphere.cpp"
#include <hwy/foreach_target.h>  // this file once per instruction set (core/simd.h)
#include <hwy/highway.h>

#include <array>
#include <numbers>
#include <vector>

#include "kernels/ao_common.h"
#include "kernels/ao_methods.h"
#include "kernels/noise.h"
#include "core/parallel.h"

HWY_BEFORE_NAMESPACE();
namespace ssdo::detail::HWY_NAMESPACE {
namespace {

constexpr float kTwoPi = 2.0f * std::numbers::pi_v<float>;

// The settings turned into what the pixel loop reads, once per call: the shared kernel and
// the 4x4 tile's rotations.
struct Constants {
  int samples;
  float inv_samples;
  float radius_world, max_radius_px, falloff_fraction, depth_bias_relative, thickness_world;
  bool multibounce;
  int width, height;
  float half_width, half_height;
  // Tangent-space offsets in the unit hemisphere (z = normal), shared by all pixels.
  std::vector<glm::vec3> kernel;
  // The 4x4 tile's rotation directions (16 angles, no trig per pixel).
  std::array<glm::vec3, 16> tile_dir;

  Constants(const AoInputs& in, const AoSettings& s)
      : samples(s.samples),
        inv_samples(1.0f / float(s.samples)),
        radius_world(s.radius_world),
        max_radius_px(s.max_radius_px),
        falloff_fraction(s.falloff_fraction),
        depth_bias_relative(s.depth_bias_relative),
        thickness_world(s.thickness_world),
        multibounce(s.multibounce && in.albedo != nullptr && !in.albedo->empty()),
        width(in.depth_view.cols),
        height(in.depth_view.rows),
        half_width(0.5f * float(width)),
        half_height(0.5f * float(height)),
        kernel(size_t(s.samples)) {
    for (int i = 0; i < samples; ++i) {
      float u, v;
      r2_point(uint32_t(i), 0.5f, 0.5f, u, v);
      const float r = std::sqrt(u), a = kTwoPi * v;
      const glm::vec3 dir(r * std::cos(a), r * std::sin(a), std::sqrt(std::max(0.0f, 1.0f - u)));
      const float t = float(i) / float(samples);
      const float scale = 0.1f + 0.9f * t * t;  // lerp(0.1, 1, t^2)
      kernel[size_t(i)] = dir * scale;
    }
    for (int j = 0; j < 16; ++j) {
      const float angle = kTwoPi * noise01(j & 3, j >> 2, 0, s.seed);
      tile_dir[size_t(j)] = glm::vec3(std::cos(angle), std::sin(angle), 0.0f);
    }
  }
};

// The kernel's frame at picture pixel (x, y) (AoInputs::frame_origin_px): the normal and a
// tangent rotated by the 4x4 tile's angle (tile position, not pixel, picks it), and the
// bitangent completing them.
struct KernelFrame {
  glm::vec3 tangent, bitangent;
};

inline KernelFrame kernel_frame(const Constants& k, int x, int y, const glm::vec3& normal) {
  const glm::vec3 random_dir = k.tile_dir[size_t((y & 3) * 4 + (x & 3))];
  glm::vec3 tangent = random_dir - normal * glm::dot(random_dir, normal);
  float tangent_len = glm::length(tangent);
  if (tangent_len < 1e-4f) {  // random_dir along the normal: any other axis will do
    tangent = glm::vec3(0, 0, 1) - normal * normal.z;
    tangent_len = glm::length(tangent);
  }
  tangent /= tangent_len;
  return {tangent, glm::cross(normal, tangent)};
}

// The kernel placed at a pixel, as the sample loop needs it. The projection is linear in
// homogeneous coordinates: a sample's clip position is the pixel's plus the kernel's
// offsets times the frame axes' clip images (four products per pixel instead of a matrix
// per sample); likewise its planar depth -z.
struct PlacedKernel {
  glm::vec4 clip_p, clip_t, clip_b, clip_n;
  float depth_t, depth_b, depth_n;
};

inline PlacedKernel place_kernel(const glm::mat4& view_to_clip, const glm::vec3& p, const KernelFrame& f,
                                 const glm::vec3& normal, float radius) {
  return {view_to_clip * glm::vec4(p, 1.0f),
          view_to_clip * glm::vec4(radius * f.tangent, 0.0f),
          view_to_clip * glm::vec4(radius * f.bitangent, 0.0f),
          view_to_clip * glm::vec4(radius * normal, 0.0f),
          -radius * f.tangent.z,
          -radius * f.bitangent.z,
          -radius * normal.z};
}

// The occlusion of the pixel at p: the kernel's samples inside the stored surface (in front
// of them by more than the bias, by at most thickness_world), each weighted by the falloff
// of the occluder's distance (the range check).
inline float sample_occlusion(const Constants& k, const AoInputs& in, const glm::vec3& p, const PlacedKernel& pk,
                              const Falloff& falloff, float bias) {
  float occlusion = 0.0f;
  for (int i = 0; i < k.samples; ++i) {
    const glm::vec3& o = k.kernel[size_t(i)];
    const glm::vec4 clip = pk.clip_p + o.x * pk.clip_t + o.y * pk.clip_b + o.z * pk.clip_n;
    if (!(clip.w > 0.0f)) continue;  // behind the eye: no information, not occluded
    const float inv_w = 1.0f / clip.w;
    // Camera::pixel_from_ndc: x = (ndc_x + 1) W / 2, y = (1 - ndc_y) H / 2.
    const float px = (clip.x * inv_w + 1.0f) * k.half_width;
    const float py = (1.0f - clip.y * inv_w) * k.half_height;
    if (!(px >= 0.0f && py >= 0.0f && px < float(k.width) && py < float(k.height)))
      continue;  // off screen: no information, not occluded
    const int sx = int(px), sy = int(py);
    if (!in.mask.ptr<uint8_t>(sy)[sx]) continue;
    const float stored = in.depth_view.ptr<float>(sy)[sx];
    const float sample_depth = -p.z + (o.x * pk.depth_t + o.y * pk.depth_b + o.z * pk.depth_n);
    const float in_front = sample_depth - stored;  // > 0: stored surface is closer
    if (!(in_front > bias) || in_front > k.thickness_world) continue;
    const float dist = glm::length(load3(in.position_view, sx, sy) - p);
    occlusion += falloff(dist);
  }
  return occlusion;
}

// AO of foreground pixel (x, y).
inline float shade_pixel(const Constants& k, const AoInputs& in, int x, int y) {
  const float depth = in.depth_view.ptr<float>(y)[x];
  const glm::vec3 p = load3(in.position_view, x, y);
  const glm::vec3 normal = load3(in.normal_view, x, y);
  // World radius shrunk so that its projection stays within max_radius_px.
  const glm::vec2 ppu = in.camera.pixels_per_unit(depth);
  const float full_px = k.radius_world * std::sqrt(ppu.x * ppu.y);
  const float radius = full_px > k.max_radius_px ? k.radius_world * (k.max_radius_px / full_px) : k.radius_world;
  const Falloff falloff(radius, k.falloff_fraction);
  const float bias = k.depth_bias_relative * depth;
  const KernelFrame frame = kernel_frame(k, x - in.frame_origin_px.x, y - in.frame_origin_px.y, normal);
  const PlacedKernel pk = place_kernel(in.camera.view_to_clip, p, frame, normal, radius);
  const float occlusion = sample_occlusion(k, in, p, pk, falloff, bias);
  float ao = std::clamp(1.0f - occlusion * k.inv_samples, 0.0f, 1.0f);
  if (k.multibounce) ao = multibounce(ao, albedo_luminance(in.albedo->ptr<cv::Vec3f>(y)[x]));
  return std::min(ao, 1.0f);
}

}  // namespace

void ao_hemisphere(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi,
                   int nthreads) {
  const Constants k(in, s);
  parallel_rows(cv::Range(roi.y, roi.y + roi.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      float* ao_row = out.ao.ptr<float>(y);
      for (int x = roi.x; x < roi.x + roi.width; ++x) ao_row[x] = mask_row[x] ? shade_pixel(k, in, x, y) : 1.0f;
    }
  });
}

}  // namespace ssdo::detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace ssdo::detail {

SSDO_AO_METHOD_DISPATCH(ao_hemisphere)

}  // namespace ssdo::detail
#endif  // HWY_ONCE
