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
#include <array>
#include <vector>

#include "kernels/ao_common.h"
#include "kernels/ao_methods.h"
#include "kernels/noise.h"
#include "core/parallel.h"

namespace ssdo::detail {

void ao_hemisphere(const AoInputs& in, const AoSettings& s, AoOutput& out, const cv::Rect& roi,
                   int nthreads) {
  const Camera& camera = in.camera;
  const int n = s.samples;
  // The kernel, once per call: tangent-space offsets in the unit hemisphere (z = normal).
  std::vector<glm::vec3> kernel(n);
  for (int i = 0; i < n; ++i) {
    float u, v;
    r2_point(uint32_t(i), 0.5f, 0.5f, u, v);
    const float r = std::sqrt(u), a = 2.0f * kPi * v;
    const glm::vec3 dir(r * std::cos(a), r * std::sin(a), std::sqrt(std::max(0.0f, 1.0f - u)));
    const float t = float(i) / float(n);
    const float scale = 0.1f + 0.9f * t * t;  // lerp(0.1, 1, t^2)
    kernel[i] = dir * scale;
  }
  const float inv_n = 1.0f / float(n);
  const int width = in.depth_view.cols, height = in.depth_view.rows;
  const bool use_multibounce = s.multibounce && in.albedo != nullptr && !in.albedo->empty();
  const glm::mat4& view_to_clip = camera.view_to_clip;
  const float half_width = 0.5f * float(width), half_height = 0.5f * float(height);
  // The 4x4 tile's rotation directions, once per call (16 angles, no trig per pixel).
  std::array<glm::vec3, 16> tile_dir;
  for (int j = 0; j < 16; ++j) {
    const float angle = 2.0f * kPi * noise01(j & 3, j >> 2, 0, s.seed);
    tile_dir[size_t(j)] = glm::vec3(std::cos(angle), std::sin(angle), 0.0f);
  }

  parallel_rows(cv::Range(roi.y, roi.y + roi.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const uint8_t* mask_row = in.mask.ptr<uint8_t>(y);
      const float* depth_row = in.depth_view.ptr<float>(y);
      float* ao_row = out.ao.ptr<float>(y);
      for (int x = roi.x; x < roi.x + roi.width; ++x) {
        if (!mask_row[x]) {
          ao_row[x] = 1.0f;
          continue;
        }
        const float depth = depth_row[x];
        const glm::vec3 p = load3(in.position_view, x, y);
        const glm::vec3 normal = load3(in.normal_view, x, y);
        // World radius shrunk so that its projection stays within max_radius_px.
        const glm::vec2 ppu = camera.pixels_per_unit(depth);
        const float full_px = s.radius_world * std::sqrt(ppu.x * ppu.y);
        const float radius = full_px > s.max_radius_px ? s.radius_world * (s.max_radius_px / full_px)
                                                       : s.radius_world;
        const Falloff falloff(radius, s.falloff_fraction);
        const float bias = s.depth_bias_relative * depth;
        // 4x4 tiled rotation about the normal (tile position, not pixel, picks the angle).
        const glm::vec3 random_dir = tile_dir[size_t((y & 3) * 4 + (x & 3))];
        glm::vec3 tangent = random_dir - normal * glm::dot(random_dir, normal);
        float tangent_len = glm::length(tangent);
        if (tangent_len < 1e-4f) {  // random_dir along the normal: any other axis will do
          tangent = glm::vec3(0, 0, 1) - normal * normal.z;
          tangent_len = glm::length(tangent);
        }
        tangent /= tangent_len;
        const glm::vec3 bitangent = glm::cross(normal, tangent);

        // The projection is linear in homogeneous coordinates: a sample's clip position is
        // the pixel's plus the kernel's offsets times the frame axes' clip images (four
        // products per pixel instead of a matrix per sample).
        const glm::vec4 clip_p = view_to_clip * glm::vec4(p, 1.0f);
        const glm::vec4 clip_t = view_to_clip * glm::vec4(radius * tangent, 0.0f);
        const glm::vec4 clip_b = view_to_clip * glm::vec4(radius * bitangent, 0.0f);
        const glm::vec4 clip_n = view_to_clip * glm::vec4(radius * normal, 0.0f);
        // Planar depth -z of a sample: the pixel's plus the offsets times -z of the axes.
        const float depth_t = -radius * tangent.z, depth_b = -radius * bitangent.z,
                    depth_n = -radius * normal.z;
        float occlusion = 0.0f;
        for (int i = 0; i < n; ++i) {
          const glm::vec3& k = kernel[i];
          const glm::vec4 clip = clip_p + k.x * clip_t + k.y * clip_b + k.z * clip_n;
          if (!(clip.w > 0.0f)) continue;  // behind the eye: no information, not occluded
          const float inv_w = 1.0f / clip.w;
          // Camera::pixel_from_ndc: x = (ndc_x + 1) W / 2, y = (1 - ndc_y) H / 2.
          const float px = (clip.x * inv_w + 1.0f) * half_width;
          const float py = (1.0f - clip.y * inv_w) * half_height;
          if (!(px >= 0.0f && py >= 0.0f && px < float(width) && py < float(height)))
            continue;  // off screen: no information, not occluded
          const int sx = int(px), sy = int(py);
          if (!in.mask.ptr<uint8_t>(sy)[sx]) continue;
          const float stored = in.depth_view.ptr<float>(sy)[sx];
          const float sample_depth = -p.z + (k.x * depth_t + k.y * depth_b + k.z * depth_n);
          const float in_front = sample_depth - stored;  // > 0: stored surface is closer
          if (!(in_front > bias) || in_front > s.thickness_world) continue;
          const float dist = glm::length(load3(in.position_view, sx, sy) - p);
          occlusion += falloff(dist);
        }
        float ao = std::clamp(1.0f - occlusion * inv_n, 0.0f, 1.0f);
        if (use_multibounce) ao = multibounce(ao, albedo_luminance(in.albedo->ptr<cv::Vec3f>(y)[x]));
        ao_row[x] = std::min(ao, 1.0f);
      }
    }
  });
}

}  // namespace ssdo::detail
