// The closed-form scenes shared by the AO method tests, measured once per method and
// preset: the floor-wall corner line (AO = 0.5), the floor under a sphere (AO = 1 - R^2/h^2)
// and open planes at several orientations, grazing included (AO = 1).
#pragma once

#include <cstdio>

#include "tests/unit/kernels/ao_test_scenes.h"

namespace ssdo::ao_test {

inline constexpr float kSphereRadius = 0.5f, kSphereHeight = 1.5f;
inline constexpr double kSphereExact = 1.0 - (0.5 * 0.5) / (1.5 * 1.5);  // 0.8889

// Mean AO on the corner line (unlimited radius: the taps span the 160 px frame).
inline double corner_ao(const AoSettings& base) {
  const Frame f = render(raycast::corner_scene(), raycast::corner_camera(160, 90));
  AoSettings s = base;
  s.radius_world = 1000.0f;
  s.max_radius_px = 160.0f;
  return mean_at(run(f, s).ao, corner_line_pixels(f));
}

// Mean AO at the floor pixels within 0.1 of the foot point (the closed form is stationary
// there: its gradient vanishes by symmetry; the ray-traced reference over the same pixels
// is 0.8892 vs 0.8889 at the foot). Radius 2 covers the whole sphere (its farthest point
// is 2.0 from the foot): "unlimited" for this scene, with the taps kept dense.
inline double sphere_ao(const AoSettings& base, float thickness_world) {
  static const Frame f = render(raycast::sphere_over_plane(kSphereRadius, kSphereHeight),
                                raycast::sphere_over_plane_camera(kSphereRadius, kSphereHeight, 320, 180));
  AoSettings s = base;
  s.radius_world = 2.0f;
  s.max_radius_px = 320.0f;
  s.falloff_fraction = 0.0f;  // binary within the radius, as the reference
  s.thickness_world = thickness_world;
  return mean_at(run(f, s).ao, foot_pixels(f, 0.1f));
}

// Largest |AO - 1| over every pixel of open planes of three orientations seen at
// elevations from head-on to 1 deg (89 deg from the normal).
inline double open_plane_worst(const AoSettings& base) {
  AoSettings s = base;
  s.radius_world = 1000.0f;
  s.max_radius_px = 160.0f;
  double worst = 0.0;
  for (glm::vec3 n : {glm::vec3(0, 0, 1), glm::vec3(0.3f, -0.2f, 1.0f), glm::vec3(1, 1, 0.2f)})
    for (float e : {90.0f, 60.0f, 30.0f, 10.0f, 5.0f, 2.0f, 1.0f}) {
      const Frame f = render(raycast::open_plane(n), raycast::open_plane_camera(n, e));
      worst = std::max(worst, max_abs_dev(run(f, s).ao, all_pixels(f), 1.0));
    }
  return worst;
}

// The same through parallel rays (an orthographic camera 4 units wide): one oblique plane
// head-on, at 30 and at 5 degrees, the radius 0.5 (settings' own otherwise).
inline double open_plane_worst_parallel_rays(const AoSettings& base) {
  const glm::vec3 n = glm::normalize(glm::vec3(1, 2, 3));
  AoSettings s = base;
  s.radius_world = 0.5f;
  double worst = 0.0;
  for (float e : {90.0f, 30.0f, 5.0f}) {
    const Camera camera = raycast::with_parallel_rays(raycast::open_plane_camera(n, e, 96, 54), 2.0f);
    const Frame f = render(raycast::open_plane(n), camera);
    worst = std::max(worst, max_abs_dev(run(f, s).ao, all_pixels(f), 1.0));
  }
  return worst;
}

}  // namespace ssdo::ao_test
