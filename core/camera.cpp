#include "core/camera.h"

#include <cmath>
#include <limits>

namespace ssdo {

Camera Camera::from_fov_x(int width_px, int height_px, float fov_x_deg, float near_view,
                          float far_view, float pixel_aspect) {
  Camera c;
  c.width_px = width_px;
  c.height_px = height_px;
  c.near_view = near_view;
  c.far_view = far_view;
  const float sx = 1.0f / std::tan(0.5f * glm::radians(fov_x_deg));
  // The image's width over its height, in the scene: width x pixel_aspect / height.
  const float sy = sx * float(width_px) * pixel_aspect / float(height_px);
  glm::mat4 p(0.0f);
  p[0][0] = sx;
  p[1][1] = sy;
  p[2][2] = -(far_view + near_view) / (far_view - near_view);
  p[2][3] = -1.0f;
  p[3][2] = -2.0f * far_view * near_view / (far_view - near_view);
  c.view_to_clip = p;
  return c;
}

float Camera::fov_x_deg() const { return glm::degrees(2.0f * std::atan(1.0f / view_to_clip[0][0])); }
float Camera::fov_y_deg() const { return glm::degrees(2.0f * std::atan(1.0f / view_to_clip[1][1])); }

glm::vec2 Camera::ndc_from_pixel(glm::vec2 pixel) const {
  glm::vec2 ndc;
  NdcFromPixel<ScalarOps>(pixel.x, pixel.y, float(width_px), float(height_px), ndc.x, ndc.y);
  return ndc;
}

glm::vec2 Camera::pixel_from_ndc(glm::vec2 ndc) const {
  return {0.5f * (ndc.x + 1.0f) * float(width_px), 0.5f * (1.0f - ndc.y) * float(height_px)};
}

glm::vec2 Camera::pixel_from_view(const glm::vec3& p_view) const {
  const glm::vec4 clip = view_to_clip * glm::vec4(p_view, 1.0f);
  if (!(clip.w > 0.0f)) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    return {nan, nan};
  }
  return pixel_from_ndc(glm::vec2(clip.x, clip.y) / clip.w);
}

glm::vec3 Camera::view_from_pixel_depth(glm::vec2 pixel, float depth_view) const {
  glm::vec3 p;
  PixelDepthSolve<ScalarOps>(*this)(pixel.x, pixel.y, depth_view, p.x, p.y, p.z);
  return p;
}

glm::vec3 Camera::view_ray_direction(glm::vec2 pixel) const {
  if (!is_perspective()) return {0.0f, 0.0f, -1.0f};
  return glm::normalize(view_from_pixel_depth(pixel, 1.0f));
}

PixelRays pixel_rays(const Camera& camera) {
  PixelRays m;
  auto point = [&](float px, float py, float depth) { return camera.view_from_pixel_depth({px, py}, depth); };
  if (camera.is_perspective()) {
    m.o0 = m.ox = m.oy = glm::vec3(0.0f);
    m.u0 = point(0.0f, 0.0f, 1.0f);
    m.ux = point(1.0f, 0.0f, 1.0f) - m.u0;
    m.uy = point(0.0f, 1.0f, 1.0f) - m.u0;
  } else {
    m.o0 = point(0.0f, 0.0f, 0.0f);
    m.ox = point(1.0f, 0.0f, 0.0f) - m.o0;
    m.oy = point(0.0f, 1.0f, 0.0f) - m.o0;
    m.u0 = glm::vec3(0.0f, 0.0f, -1.0f);
    m.ux = m.uy = glm::vec3(0.0f);
  }
  return m;
}

}  // namespace ssdo
