#include "tests/support/raycast.h"

#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

#include "kernels/hemisphere_sampling.h"
#include "kernels/noise.h"
#include "core/parallel.h"

namespace ssdo::raycast {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// Ray-plane: t = dot(p0 - o, n) / dot(d, n). Rays parallel to the plane (|dot| below
// 1e-12, far below any float direction's rounding) miss.
inline float intersect_plane(const Plane& p, const glm::vec3& o, const glm::vec3& d) {
  const float denom = glm::dot(d, p.normal_world);
  if (std::abs(denom) < 1e-12f) return kInf;
  return glm::dot(p.point_world - o, p.normal_world) / denom;
}

// Ray-sphere in the numerically robust form of Haines et al. 2019 ("Precision Improvements
// for Ray/Sphere Intersection", Ray Tracing Gems ch. 7, eq. 7.5-7.8): the discriminant
// r^2 - |f - b d|^2 avoids the cancellation of b^2 - c for distant spheres, and the near
// root comes from q / a with q = -b - sign(b) sqrt(disc). d is unit. Returns the two roots.
inline bool intersect_sphere(const Sphere& s, const glm::vec3& o, const glm::vec3& d, float& t0,
                             float& t1) {
  const glm::vec3 f = o - s.centre_world;
  const float b = -glm::dot(f, d);  // distance along d to the point closest to the centre
  const glm::vec3 l = f + b * d;
  const float disc = s.radius_world * s.radius_world - glm::dot(l, l);
  if (disc < 0.0f) return false;
  const float c = glm::dot(f, f) - s.radius_world * s.radius_world;
  const float q = b + std::copysign(std::sqrt(disc), b);
  if (q == 0.0f) {  // ray origin at the centre's closest point with zero radius: degenerate
    t0 = t1 = 0.0f;
    return true;
  }
  const float ta = c / q, tb = q;
  t0 = std::min(ta, tb);
  t1 = std::max(ta, tb);
  return true;
}

// Ray-box slab test (Kay & Kajiya 1986) in the box's local frame. Returns the entry and
// exit parameters and the local axis (0..2) and side (+-1) of the entry and exit faces.
inline bool intersect_box(const Box& bx, const glm::vec3& o, const glm::vec3& d, float& t_near,
                          float& t_far, int& axis_near, float& sign_near, int& axis_far,
                          float& sign_far) {
  const glm::mat3 to_local = glm::transpose(bx.rotation);
  const glm::vec3 ol = to_local * (o - bx.centre_world);
  const glm::vec3 dl = to_local * d;
  t_near = -kInf;
  t_far = kInf;
  axis_near = axis_far = 0;
  sign_near = sign_far = 1.0f;
  for (int k = 0; k < 3; ++k) {
    const float h = bx.half_extents_world[k];
    if (dl[k] == 0.0f) {  // parallel to this slab: inside it or a miss
      if (std::abs(ol[k]) > h) return false;
      continue;
    }
    const float inv = 1.0f / dl[k];
    float ta = (-h - ol[k]) * inv, tb = (h - ol[k]) * inv;
    // The face entered first is on the side the ray comes from: -h when dl > 0.
    float sa = -1.0f, sb = 1.0f;
    if (ta > tb) {
      std::swap(ta, tb);
      std::swap(sa, sb);
    }
    if (ta > t_near) {
      t_near = ta;
      axis_near = k;
      sign_near = sa;
    }
    if (tb < t_far) {
      t_far = tb;
      axis_far = k;
      sign_far = sb;
    }
    if (t_near > t_far) return false;
  }
  return true;
}

using sampling::cosine_hemisphere;
using sampling::orthonormal_basis;

inline float ray_offset(const glm::vec3& p_world, float depth_view) {
  const float scale = std::max({1.0f, std::abs(p_world.x), std::abs(p_world.y),
                                std::abs(p_world.z), depth_view});
  return kRayOffsetRelative * scale;
}

// The shading point of a G-buffer pixel in world space, or false on background.
inline bool pixel_point(const GBuffer& g, int x, int y, glm::vec3& p_world, glm::vec3& n_world,
                        float& depth_view) {
  if (g.mask.at<uint8_t>(y, x) == 0) return false;
  depth_view = g.depth_view.at<float>(y, x);
  glm::vec3 p_view;
  if (!g.position_view.empty()) {
    const cv::Vec3f& pv = g.position_view.at<cv::Vec3f>(y, x);
    p_view = {pv[0], pv[1], pv[2]};
  } else {
    p_view = g.camera.view_from_pixel_depth({float(x) + 0.5f, float(y) + 0.5f}, depth_view);
  }
  const cv::Vec3f& nv = g.normal_view.at<cv::Vec3f>(y, x);
  p_world = glm::vec3(g.camera.view_to_world * glm::vec4(p_view, 1.0f));
  n_world = glm::normalize(g.camera.world_from_view_direction({nv[0], nv[1], nv[2]}));
  return true;
}

// The world-space ray through the centre of pixel (x, y): from the eye (perspective) or from
// the pixel on the near plane (orthographic), unit direction.
struct PixelRay {
  glm::vec3 origin_world, dir_world;
};

PixelRay pixel_ray(const Camera& camera, int x, int y) {
  const glm::vec2 pixel(float(x) + 0.5f, float(y) + 0.5f);
  const glm::vec3 origin_view = camera.is_perspective() ? glm::vec3(0.0f) : camera.view_from_pixel_depth(pixel, 0.0f);
  return {glm::vec3(camera.view_to_world * glm::vec4(origin_view, 1.0f)),
          glm::normalize(camera.world_from_view_direction(camera.view_ray_direction(pixel)))};
}

}  // namespace

Hit intersect(const Scene& scene, const glm::vec3& o, const glm::vec3& d, float t_max) {
  Hit hit;
  float best = t_max;
  for (const Plane& p : scene.planes) {
    const float t = intersect_plane(p, o, d);
    if (t > 0.0f && t < best) {
      best = t;
      hit.t = t;
      hit.normal_world = p.normal_world;
      hit.albedo = p.albedo;
    }
  }
  for (const Sphere& s : scene.spheres) {
    float t0, t1;
    if (!intersect_sphere(s, o, d, t0, t1)) continue;
    const float t = t0 > 0.0f ? t0 : t1;
    if (t > 0.0f && t < best) {
      best = t;
      hit.t = t;
      hit.normal_world = glm::normalize(o + t * d - s.centre_world);
      hit.albedo = s.albedo;
    }
  }
  for (const Box& bx : scene.boxes) {
    float tn, tf, sn, sf;
    int an, af;
    if (!intersect_box(bx, o, d, tn, tf, an, sn, af, sf)) continue;
    const bool entering = tn > 0.0f;
    const float t = entering ? tn : tf;
    if (t > 0.0f && t < best) {
      best = t;
      hit.t = t;
      hit.normal_world = bx.rotation[entering ? an : af] * (entering ? sn : sf);
      hit.albedo = bx.albedo;
    }
  }
  return hit;
}

bool occluded(const Scene& scene, const glm::vec3& o, const glm::vec3& d, float t_max) {
  for (const Plane& p : scene.planes) {
    const float t = intersect_plane(p, o, d);
    if (t > 0.0f && t < t_max) return true;
  }
  for (const Sphere& s : scene.spheres) {
    float t0, t1;
    if (!intersect_sphere(s, o, d, t0, t1)) continue;
    if ((t0 > 0.0f && t0 < t_max) || (t1 > 0.0f && t1 < t_max)) return true;
  }
  for (const Box& bx : scene.boxes) {
    float tn, tf, sn, sf;
    int an, af;
    if (!intersect_box(bx, o, d, tn, tf, an, sn, af, sf)) continue;
    if ((tn > 0.0f && tn < t_max) || (tf > 0.0f && tf < t_max)) return true;
  }
  return false;
}

Camera look_at(glm::vec3 eye_world, glm::vec3 target_world, glm::vec3 up_world, int width_px,
               int height_px, float fov_x_deg) {
  Camera c = Camera::from_fov_x(width_px, height_px, fov_x_deg);
  const glm::vec3 back = glm::normalize(eye_world - target_world);  // view +Z
  const glm::vec3 right = glm::normalize(glm::cross(up_world, back));
  const glm::vec3 up = glm::cross(back, right);
  glm::mat4 v2w(1.0f);
  v2w[0] = glm::vec4(right, 0.0f);
  v2w[1] = glm::vec4(up, 0.0f);
  v2w[2] = glm::vec4(back, 0.0f);
  v2w[3] = glm::vec4(eye_world, 1.0f);
  // Rigid inverse: R^T and -R^T eye.
  const glm::mat3 rt = glm::transpose(glm::mat3(v2w));
  glm::mat4 w2v(rt);
  w2v[3] = glm::vec4(-(rt * eye_world), 1.0f);
  c.view_to_world = v2w;
  c.world_to_view = w2v;
  return c;
}

GBuffer render_gbuffer(const Scene& scene, const Camera& camera, int nthreads) {
  CV_Assert(camera.width_px > 0 && camera.height_px > 0);
  GBuffer g;
  g.camera = camera;
  const cv::Size size(camera.width_px, camera.height_px);
  g.depth_view.create(size, CV_32FC1);
  g.mask.create(size, CV_8UC1);
  g.normal_view.create(size, CV_32FC3);
  g.position_view.create(size, CV_32FC3);
  g.albedo.create(size, CV_32FC3);
  parallel_rows(cv::Range(0, size.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* depth = g.depth_view.ptr<float>(y);
      uint8_t* mask = g.mask.ptr<uint8_t>(y);
      cv::Vec3f* normal = g.normal_view.ptr<cv::Vec3f>(y);
      cv::Vec3f* position = g.position_view.ptr<cv::Vec3f>(y);
      cv::Vec3f* albedo = g.albedo.ptr<cv::Vec3f>(y);
      for (int x = 0; x < size.width; ++x) {
        const PixelRay ray = pixel_ray(camera, x, y);
        const glm::vec3 origin_world = ray.origin_world, dir_world = ray.dir_world;
        const Hit hit = intersect(scene, origin_world, dir_world);
        const float depth_view = hit.valid() ? -camera.view_from_world_point(origin_world + hit.t * dir_world).z
                                             : kInf;
        if (!(depth_view > 0.0f) || !std::isfinite(depth_view)) {
          depth[x] = kInf;
          mask[x] = 0;
          normal[x] = position[x] = albedo[x] = cv::Vec3f(0.0f, 0.0f, 0.0f);
          continue;
        }
        glm::vec3 n_world = hit.normal_world;
        if (glm::dot(n_world, dir_world) > 0.0f) n_world = -n_world;  // face the camera
        const glm::vec3 n_view = glm::normalize(camera.view_from_world_direction(n_world));
        const glm::vec3 p_view = camera.view_from_pixel_depth(glm::vec2(float(x) + 0.5f, float(y) + 0.5f), depth_view);
        depth[x] = depth_view;
        mask[x] = 255;
        normal[x] = cv::Vec3f(n_view.x, n_view.y, n_view.z);
        position[x] = cv::Vec3f(p_view.x, p_view.y, p_view.z);
        albedo[x] = cv::Vec3f(hit.albedo.x, hit.albedo.y, hit.albedo.z);
      }
    }
  });
  return g;
}

cv::Mat render_depth_back(const Scene& scene, const Camera& camera, int nthreads) {
  CV_Assert(camera.width_px > 0 && camera.height_px > 0);
  cv::Mat depth_back(camera.height_px, camera.width_px, CV_32FC1);
  parallel_rows(cv::Range(0, depth_back.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* out = depth_back.ptr<float>(y);
      for (int x = 0; x < depth_back.cols; ++x) {
        const PixelRay ray = pixel_ray(camera, x, y);
        const glm::vec3 o = ray.origin_world, d = ray.dir_world;
        // The nearest front face decides whether a plane is hit first (then: no exit).
        const Hit front = intersect(scene, o, d);
        float best = kInf;
        if (front.valid()) {
          bool plane_first = false;
          for (const Plane& p : scene.planes) {
            const float t = intersect_plane(p, o, d);
            if (t > 0.0f && t <= front.t) plane_first = true;
          }
          if (!plane_first) {
            for (const Sphere& s : scene.spheres) {
              float t0, t1;
              if (intersect_sphere(s, o, d, t0, t1) && t1 > 0.0f) best = std::min(best, t1);
            }
            for (const Box& bx : scene.boxes) {
              float tn, tf, sn, sf;
              int an, af;
              if (intersect_box(bx, o, d, tn, tf, an, sn, af, sf) && tf > 0.0f)
                best = std::min(best, tf);
            }
          }
        }
        // A back face before the front one only when the eye is inside a solid: clamp.
        if (best < kInf) best = std::max(best, front.t);
        out[x] = best < kInf ? -camera.view_from_world_point(o + best * d).z : kInf;
      }
    }
  });
  return depth_back;
}

std::vector<std::vector<float>> render_depth_samples(const Scene& scene, const Camera& camera,
                                                    int nthreads) {
  CV_Assert(camera.width_px > 0 && camera.height_px > 0);
  std::vector<std::vector<float>> samples(size_t(camera.width_px) * size_t(camera.height_px));
  parallel_rows(cv::Range(0, camera.height_px), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 0; x < camera.width_px; ++x) {
        const PixelRay ray = pixel_ray(camera, x, y);
        const glm::vec3 o = ray.origin_world, d = ray.dir_world;
        std::vector<float> ts;
        for (const Plane& p : scene.planes) ts.push_back(intersect_plane(p, o, d));
        for (const Sphere& sp : scene.spheres) {
          float t0, t1;
          if (intersect_sphere(sp, o, d, t0, t1)) ts.insert(ts.end(), {t0, t1});
        }
        for (const Box& bx : scene.boxes) {
          float tn, tf, sn, sf;
          int an, af;
          if (intersect_box(bx, o, d, tn, tf, an, sn, af, sf)) ts.insert(ts.end(), {tn, tf});
        }
        // A plane bounds a half-space solid (as in render_depth_back): nothing behind its
        // hit is seen.
        float t_end = kInf;
        for (const Plane& p : scene.planes)
          if (const float t = intersect_plane(p, o, d); t > 0.0f) t_end = std::min(t_end, t);
        std::sort(ts.begin(), ts.end());
        std::vector<float>& out = samples[size_t(y) * size_t(camera.width_px) + size_t(x)];
        for (float t : ts)
          if (t > 0.0f && t <= t_end && t < kInf) out.push_back(-camera.view_from_world_point(o + t * d).z);
      }
  });
  return samples;
}

namespace {

// Estimators shared by the point and image entry points; `offset_world` is the origin
// offset along the normal (see kRayOffsetRelative).
float ao_estimate(const Scene& scene, const glm::vec3& p_world, const glm::vec3& n_world,
                  float radius_world, int samples, float shift_u, float shift_v,
                  float offset_world) {
  glm::vec3 t, b;
  orthonormal_basis(n_world, t, b);
  const glm::vec3 origin = p_world + offset_world * n_world;
  int open = 0;
  for (int k = 0; k < samples; ++k) {
    float u, v;
    r2_point(uint32_t(k), shift_u, shift_v, u, v);
    if (!occluded(scene, origin, cosine_hemisphere(n_world, t, b, u, v), radius_world)) ++open;
  }
  return float(open) / float(samples);
}

LightSample light_estimate(const Scene& scene, const glm::vec3& p_world, const glm::vec3& n_world,
                           const EnvironmentRadiance& env, float radius_world, int samples,
                           float shift_u, float shift_v, uint32_t secondary_seed,
                           float offset_world) {
  glm::vec3 t, b;
  orthonormal_basis(n_world, t, b);
  const glm::vec3 origin = p_world + offset_world * n_world;
  glm::dvec3 direct(0.0), indirect(0.0);  // double sums: no float drift over thousands of samples
  for (int k = 0; k < samples; ++k) {
    float u, v;
    r2_point(uint32_t(k), shift_u, shift_v, u, v);
    const glm::vec3 w = cosine_hemisphere(n_world, t, b, u, v);
    const Hit hit = intersect(scene, origin, w, radius_world);
    if (!hit.valid()) {
      direct += glm::dvec3(env(w));
      continue;
    }
    // One bounce: the hit's outgoing radiance albedo * direct(hit), direct(hit) estimated
    // with one cosine-weighted ray around the side of the hit surface the ray arrived from.
    const glm::vec3 x_world = origin + hit.t * w;
    glm::vec3 n_hit = hit.normal_world;
    if (glm::dot(n_hit, w) > 0.0f) n_hit = -n_hit;
    glm::vec3 t_hit, b_hit;
    orthonormal_basis(n_hit, t_hit, b_hit);
    const float u2 = unit_float(hash_u32(secondary_seed + 2u * uint32_t(k)));
    const float v2 = unit_float(hash_u32(secondary_seed + 2u * uint32_t(k) + 1u));
    const glm::vec3 w2 = cosine_hemisphere(n_hit, t_hit, b_hit, u2, v2);
    const glm::vec3 origin2 = x_world + ray_offset(x_world, 0.0f) * n_hit;
    if (!occluded(scene, origin2, w2, radius_world))
      indirect += glm::dvec3(hit.albedo * env(w2));
  }
  const double inv = 1.0 / double(samples);
  return {glm::vec3(direct * inv), glm::vec3(indirect * inv)};
}

}  // namespace

float ao_at_point(const Scene& scene, const glm::vec3& p_world, const glm::vec3& n_world,
                  float radius_world, int samples, float shift_u, float shift_v) {
  CV_Assert(samples >= 1 && radius_world > 0.0f);
  return ao_estimate(scene, p_world, n_world, radius_world, samples, shift_u, shift_v,
                     ray_offset(p_world, 0.0f));
}

LightSample light_at_point(const Scene& scene, const glm::vec3& p_world, const glm::vec3& n_world,
                           const EnvironmentRadiance& environment_radiance, float radius_world,
                           int samples, float shift_u, float shift_v, uint32_t secondary_seed) {
  CV_Assert(samples >= 1 && radius_world > 0.0f);
  return light_estimate(scene, p_world, n_world, environment_radiance, radius_world, samples,
                        shift_u, shift_v, secondary_seed, ray_offset(p_world, 0.0f));
}

cv::Mat reference_ao(const Scene& scene, const GBuffer& g, float radius_world, int samples,
                     uint32_t seed, int nthreads) {
  CV_Assert(samples >= 1 && radius_world > 0.0f);
  CV_Assert(g.depth_view.type() == CV_32FC1 && g.mask.type() == CV_8UC1);
  CV_Assert(g.normal_view.type() == CV_32FC3 && g.normal_view.size() == g.depth_view.size());
  cv::Mat ao(g.depth_view.size(), CV_32FC1);
  parallel_rows(cv::Range(0, ao.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* out = ao.ptr<float>(y);
      for (int x = 0; x < ao.cols; ++x) {
        glm::vec3 p, n;
        float depth;
        if (!pixel_point(g, x, y, p, n, depth)) {
          out[x] = 1.0f;
          continue;
        }
        out[x] = ao_estimate(scene, p, n, radius_world, samples, noise01(x, y, 0, seed),
                             noise01(x, y, 1, seed), ray_offset(p, depth));
      }
    }
  });
  return ao;
}

EnvironmentRadiance uniform_environment(glm::vec3 rgb) {
  return [rgb](const glm::vec3&) { return rgb; };
}

EnvironmentRadiance gradient_sky_environment() {
  return [](const glm::vec3& d) {
    const float t = std::clamp((d.z + 0.4f) / 0.8f, 0.0f, 1.0f);
    return (1.0f - t) * glm::vec3(1.0f, 0.35f, 0.08f) + t * glm::vec3(0.25f, 0.5f, 1.0f);
  };
}

LightReference reference_light(const Scene& scene, const GBuffer& g,
                               const EnvironmentRadiance& environment_radiance,
                               float radius_world, int samples, uint32_t seed, int nthreads) {
  CV_Assert(samples >= 1 && radius_world > 0.0f);
  CV_Assert(g.depth_view.type() == CV_32FC1 && g.mask.type() == CV_8UC1);
  CV_Assert(g.normal_view.type() == CV_32FC3 && g.normal_view.size() == g.depth_view.size());
  LightReference ref;
  ref.direct.create(g.depth_view.size(), CV_32FC3);
  ref.indirect.create(g.depth_view.size(), CV_32FC3);
  parallel_rows(cv::Range(0, g.depth_view.rows), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      cv::Vec3f* direct = ref.direct.ptr<cv::Vec3f>(y);
      cv::Vec3f* indirect = ref.indirect.ptr<cv::Vec3f>(y);
      for (int x = 0; x < g.depth_view.cols; ++x) {
        glm::vec3 p, n;
        float depth;
        if (!pixel_point(g, x, y, p, n, depth)) {
          direct[x] = indirect[x] = cv::Vec3f(0.0f, 0.0f, 0.0f);
          continue;
        }
        const LightSample s = light_estimate(
            scene, p, n, environment_radiance, radius_world, samples, noise01(x, y, 0, seed),
            noise01(x, y, 1, seed), hash_pixel(x, y, 2, seed), ray_offset(p, depth));
        direct[x] = cv::Vec3f(s.direct.x, s.direct.y, s.direct.z);
        indirect[x] = cv::Vec3f(s.indirect.x, s.indirect.y, s.indirect.z);
      }
    }
  });
  return ref;
}

// ---------------------------------------------------------------------------------------
// Scenes and cameras.

namespace {

constexpr glm::vec3 kZ(0.0f, 0.0f, 1.0f);
constexpr glm::vec3 kGrey(0.8f);

// Axis-aligned box from its min and max corners.
Box aabb(glm::vec3 lo, glm::vec3 hi, glm::vec3 albedo) {
  Box b;
  b.centre_world = 0.5f * (lo + hi);
  b.half_extents_world = 0.5f * (hi - lo);
  b.albedo = albedo;
  return b;
}

// Rotation by angle_deg about the world Z axis (counter-clockwise seen from above).
glm::mat3 rotation_z(float angle_deg) {
  const float a = glm::radians(angle_deg), c = std::cos(a), s = std::sin(a);
  return glm::mat3(glm::vec3(c, s, 0.0f), glm::vec3(-s, c, 0.0f), kZ);
}

glm::mat3 rotation_x(float angle_deg) {
  const float a = glm::radians(angle_deg), c = std::cos(a), s = std::sin(a);
  return glm::mat3(glm::vec3(1.0f, 0.0f, 0.0f), glm::vec3(0.0f, c, s), glm::vec3(0.0f, -s, c));
}

}  // namespace

Scene corner_scene() {
  Scene s;
  s.planes.push_back({glm::vec3(0.0f), kZ, kGrey});
  s.planes.push_back({glm::vec3(0.0f), glm::vec3(1.0f, 0.0f, 0.0f), kGrey});
  return s;
}

Camera corner_camera(int width_px, int height_px) {
  return look_at({2.5f, 0.0f, 1.0f}, {0.0f, 0.0f, 0.3f}, kZ, width_px, height_px, 60.0f);
}

Scene sphere_over_plane(float radius_world, float height_world) {
  CV_Assert(radius_world > 0.0f && height_world > radius_world);
  Scene s;
  s.planes.push_back({glm::vec3(0.0f), kZ, kGrey});
  s.spheres.push_back({glm::vec3(0.0f, 0.0f, height_world), radius_world, kGrey});
  return s;
}

Camera sphere_over_plane_camera(float radius_world, float height_world, int width_px,
                                int height_px) {
  // Low enough that the line of sight to the foot point passes under the sphere.
  const float distance = 3.0f * (height_world + radius_world);
  const float eye_z = 0.5f * (height_world - radius_world) * distance / radius_world;
  return look_at({0.0f, -distance, std::min(eye_z, height_world)},
                 {0.0f, 0.0f, 0.5f * height_world}, kZ, width_px, height_px, 50.0f);
}

Scene open_plane(glm::vec3 normal_world) {
  Scene s;
  s.planes.push_back({glm::vec3(0.0f), glm::normalize(normal_world), kGrey});
  return s;
}

Camera open_plane_camera(glm::vec3 normal_world, float elevation_deg, int width_px,
                         int height_px) {
  const glm::vec3 n = glm::normalize(normal_world);
  glm::vec3 t, b;
  orthonormal_basis(n, t, b);
  const float e = glm::radians(elevation_deg);
  const glm::vec3 eye = 4.0f * (std::sin(e) * n - std::cos(e) * t);
  // Head-on views need an up vector that is not the normal.
  const glm::vec3 up = elevation_deg > 80.0f ? b : n;
  return look_at(eye, glm::vec3(0.0f), up, width_px, height_px, 60.0f);
}

Camera with_parallel_rays(Camera camera, float half_width_world) {
  const float half_height_world = half_width_world * float(camera.height_px) / float(camera.width_px);
  camera.view_to_clip =
      glm::ortho(-half_width_world, half_width_world, -half_height_world, half_height_world, 0.1f, 100.0f);
  return camera;
}

Scene cornell_scene() {
  const glm::vec3 red(0.63f, 0.065f, 0.05f), green(0.14f, 0.45f, 0.091f);
  constexpr float kT = 0.1f;  // wall thickness, outside the room
  Scene s;
  s.boxes.push_back(aabb({-2 - kT, 0, -kT}, {2 + kT, 4 + kT, 0}, kGrey));        // floor
  s.boxes.push_back(aabb({-2 - kT, 4, -kT}, {2 + kT, 4 + kT, 3 + kT}, kGrey));   // back
  s.boxes.push_back(aabb({-2 - kT, 0, -kT}, {-2, 4 + kT, 3 + kT}, red));         // left
  s.boxes.push_back(aabb({2, 0, -kT}, {2 + kT, 4 + kT, 3 + kT}, green));         // right
  // Ceiling z in [3, 3.1] with a 2x2 skylight over x in [-1, 1], y in [1, 3].
  s.boxes.push_back(aabb({-2 - kT, 0, 3}, {-1, 4 + kT, 3 + kT}, kGrey));
  s.boxes.push_back(aabb({1, 0, 3}, {2 + kT, 4 + kT, 3 + kT}, kGrey));
  s.boxes.push_back(aabb({-1, 0, 3}, {1, 1, 3 + kT}, kGrey));
  s.boxes.push_back(aabb({-1, 3, 3}, {1, 4 + kT, 3 + kT}, kGrey));
  Box tall;
  tall.centre_world = {-0.8f, 2.6f, 1.2f};
  tall.half_extents_world = {0.55f, 0.55f, 1.2f};
  tall.rotation = rotation_z(17.0f);
  tall.albedo = kGrey;
  s.boxes.push_back(tall);
  Box short_block;
  short_block.centre_world = {0.8f, 1.5f, 0.6f};
  short_block.half_extents_world = {0.55f, 0.55f, 0.6f};
  short_block.rotation = rotation_z(-17.0f);
  short_block.albedo = kGrey;
  s.boxes.push_back(short_block);
  return s;
}

Camera cornell_camera(int width_px, int height_px) {
  return look_at({0.0f, -3.0f, 1.5f}, {0.0f, 4.0f, 1.5f}, kZ, width_px, height_px, 65.0f);
}

Scene red_wall_scene() {
  Scene s;
  s.planes.push_back({glm::vec3(0.0f), kZ, glm::vec3(1.0f)});
  s.boxes.push_back(aabb({-0.2f, -3.0f, 0.0f}, {0.0f, 3.0f, 1.5f}, {0.8f, 0.05f, 0.05f}));
  return s;
}

Camera red_wall_camera(int width_px, int height_px) {
  return look_at({4.0f, -4.0f, 2.0f}, {0.8f, 0.0f, 0.3f}, kZ, width_px, height_px, 60.0f);
}

Scene poles_scene() {
  Scene s;
  s.planes.push_back({glm::vec3(0.0f), kZ, kGrey});
  s.planes.push_back({glm::vec3(0.0f, 3.0f, 0.0f), glm::vec3(0.0f, -1.0f, 0.0f), kGrey});
  constexpr float kX[] = {-1.2f, -0.6f, 0.0f, 0.6f, 1.2f};
  constexpr float kGap[] = {0.3f, 0.6f, 0.9f, 1.2f, 0.5f};  // distance in front of the wall
  for (int k = 0; k < 5; ++k)
    s.boxes.push_back(aabb({kX[k] - 0.02f, 3.0f - kGap[k] - 0.02f, 0.0f},
                           {kX[k] + 0.02f, 3.0f - kGap[k] + 0.02f, 2.0f}, kGrey));
  return s;
}

Camera poles_camera(int width_px, int height_px) {
  return look_at({0.0f, -2.0f, 1.0f}, {0.0f, 3.0f, 0.8f}, kZ, width_px, height_px, 60.0f);
}

Scene floating_scene() {
  Scene s;
  s.planes.push_back({glm::vec3(0.0f, 7.0f, 0.0f), glm::vec3(0.0f, -1.0f, 0.0f), kGrey});
  s.spheres.push_back({glm::vec3(0.3f, 2.0f, 1.0f), 0.8f, kGrey});
  Box tilted;
  tilted.centre_world = {-1.7f, 2.5f, 0.7f};
  tilted.half_extents_world = {0.4f, 0.4f, 0.4f};
  tilted.rotation = rotation_z(30.0f) * rotation_x(20.0f);
  tilted.albedo = kGrey;
  s.boxes.push_back(tilted);
  s.boxes.push_back(aabb({1.85f, 1.3f, -1.0f}, {2.15f, 1.6f, 3.0f}, kGrey));
  return s;
}

Camera floating_camera(int width_px, int height_px) {
  return look_at({0.0f, -3.0f, 1.0f}, {0.0f, 7.0f, 1.0f}, kZ, width_px, height_px, 60.0f);
}

Scene truck_shot_scene() {
  Scene s;
  s.planes.push_back({glm::vec3(0.0f), glm::vec3(0.0f, 0.0f, 1.0f), kGrey});
  s.planes.push_back({glm::vec3(0.0f, 3.5f, 0.0f), glm::vec3(0.0f, -1.0f, 0.0f), kGrey});
  for (float x : {-3.0f, -0.6f, 1.8f, 4.2f}) s.boxes.push_back(aabb({x - 0.25f, 0.05f, 0.0f}, {x + 0.25f, 0.55f, 0.5f}, kGrey));
  for (float x : {-2.0f, 0.8f, 3.4f}) {
    s.boxes.push_back(aabb({x - 0.3f, 1.0f, 0.0f}, {x + 0.3f, 1.6f, 0.6f}, kGrey));
    s.boxes.push_back(aabb({x - 0.1f, 1.8f, 0.0f}, {x + 0.3f, 2.2f, 1.2f}, kGrey));
  }
  for (float x : {-2.6f, 2.0f}) s.boxes.push_back(aabb({x - 0.4f, 2.88f, 0.0f}, {x + 0.4f, 2.92f, 1.0f}, kGrey));
  constexpr float kPoleX[] = {-3.6f, -1.3f, -0.2f, 0.5f, 1.3f, 2.8f, 3.9f};
  constexpr float kPoleGap[] = {0.5f, 0.8f, 0.3f, 1.0f, 0.6f, 0.4f, 0.9f};
  for (int k = 0; k < 7; ++k) {
    const float y = 3.5f - kPoleGap[k];
    s.boxes.push_back(aabb({kPoleX[k] - 0.03f, y - 0.03f, 0.0f}, {kPoleX[k] + 0.03f, y + 0.03f, 1.8f}, kGrey));
  }
  return s;
}

Camera truck_shot_camera(int t, int width_px, int height_px, int guard_px) {
  const float x = kTruckShotStepWorld * float(t - kTruckShotFrames / 2);
  const float tan_half =
      std::tan(glm::radians(0.5f * kTruckShotFovXDeg)) * float(width_px + 2 * guard_px) / float(width_px);
  return look_at({x, -3.0f, 2.0f}, {x, 2.0f, 0.3f}, kZ, width_px + 2 * guard_px, height_px + 2 * guard_px,
                 glm::degrees(2.0f * std::atan(tan_half)));
}

}  // namespace ssdo::raycast
