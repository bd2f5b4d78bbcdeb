// The project's own exact references: a small deterministic ray caster over a handful of
// analytic primitives that renders synthetic G-buffers and Monte-Carlo ray-traced AO and
// light references in the conventions of the Cycles passes (docs/architecture.md, "Conventions").
//
// Conventions:
// - World space: right-handed, Z up, scene units (as Blender); any orientation works, the
//   scene builders below use Z up.
// - Cameras: ssdo::Camera (view space looks down -Z, +Y up; planar depth = -z_view).
// - Every primitive is opaque and two-sided for visibility; each surface point carries a
//   constant linear RGB albedo in [0, 1].
// - Brute force over all primitives: meant for test scenes of a few dozen primitives.
// - Output is a pure function of (scene, G-buffer, arguments, seed): identical bytes for any
//   thread count (per-pixel noise from kernels/noise.h only).
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include <glm/glm.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/gbuffer.h"

namespace ssdo::raycast {

// Infinite plane { x : dot(normal_world, x - point_world) = 0 }.
struct Plane {
  glm::vec3 point_world{0.0f};
  glm::vec3 normal_world{0.0f, 0.0f, 1.0f};  // unit
  glm::vec3 albedo{0.8f};
};

struct Sphere {
  glm::vec3 centre_world{0.0f};
  float radius_world = 1.0f;  // > 0
  glm::vec3 albedo{0.8f};
};

// Oriented box: the points centre_world + rotation * l with |l_k| <= half_extents_world[k].
// rotation is orthonormal (box-local axes as columns in world space); identity = axis-aligned.
struct Box {
  glm::vec3 centre_world{0.0f};
  glm::vec3 half_extents_world{0.5f};  // > 0 each
  glm::mat3 rotation{1.0f};
  glm::vec3 albedo{0.8f};
};

struct Scene {
  std::vector<Plane> planes;
  std::vector<Sphere> spheres;
  std::vector<Box> boxes;
};

// The nearest intersection of a ray with the scene.
struct Hit {
  float t = std::numeric_limits<float>::infinity();  // ray parameter (unit direction: distance)
  glm::vec3 normal_world{0.0f};  // unit geometric normal, outward (planes: as given)
  glm::vec3 albedo{0.0f};
  bool valid() const { return t < std::numeric_limits<float>::infinity(); }
};

// Nearest hit with t in (0, t_max) of the ray origin + t * direction (direction unit).
Hit intersect(const Scene& scene, const glm::vec3& origin_world, const glm::vec3& direction_world,
              float t_max = std::numeric_limits<float>::infinity());

// True when any primitive is hit with t in (0, t_max).
bool occluded(const Scene& scene, const glm::vec3& origin_world, const glm::vec3& direction_world,
              float t_max = std::numeric_limits<float>::infinity());

// A perspective camera at eye_world looking at target_world (up_world: any vector not
// parallel to the view direction), square pixels, full horizontal field of view fov_x_deg
// in (0, 180). world_to_view and view_to_world are set (rigid, mutual inverses).
Camera look_at(glm::vec3 eye_world, glm::vec3 target_world, glm::vec3 up_world, int width_px,
               int height_px, float fov_x_deg);

// One ray through each pixel centre (i + 0.5, j + 0.5). Fills depth_view (planar, +inf on
// background), mask (255 foreground, 0 background), normal_view (unit geometric normal in
// view space, flipped to face the camera; 0 on background), position_view
// (= camera.view_from_pixel_depth(centre, depth), exactly as positions.h reconstructs it;
// 0 on background) and albedo (0 on background).
GBuffer render_gbuffer(const Scene& scene, const Camera& camera, int nthreads = 0);

// A back-face depth pass (the second depth layer of depth peeling, Ritschel et al. 2009,
// "Approximating Dynamic Global Illumination in Image Space", sec. 3.3): per pixel, the
// planar depth of the nearest surface the pixel's ray leaves a solid through (the nearest
// back face: the far side of a sphere, the exit face of a box). Planes bound half-spaces
// with no far side, so a ray that hits a plane first never exits: +inf, as a pass with
// front-face culling sees nothing behind a floor or a wall. +inf on background too; compare
// with the G-buffer's mask. CV_32FC1 of the camera's size.
cv::Mat render_depth_back(const Scene& scene, const Camera& camera, int nthreads = 0);

// Every surface crossing of each pixel's ray, as a deep render without culling writes them
// (one sample per surface, opaque): the planar depths of the entry and exit of each sphere
// and box in front of the eye, nearest first, up to the first plane hit (included): a plane
// bounds a half-space with no far side (render_depth_back). Row-major, one vector per pixel
// (empty on background). Where solids overlap, the crossings inside another are listed too.
std::vector<std::vector<float>> render_depth_samples(const Scene& scene, const Camera& camera,
                                                    int nthreads = 0);

// Offset of a secondary ray's origin along the surface normal, scene units:
// kRayOffsetRelative * max(1, |p_world|, depth_view). Why: hit points are computed in float
// (relative error ~1e-7 of the coordinates and of the camera distance, amplified a few
// times by the intersection arithmetic); without an offset a ray can re-hit its own surface
// at t ~ 0 ("shadow acne"). 1e-4 is ~1000x that error and 1e-4 of a unit-sized scene,
// so the occluders it can skip (those closer than the offset) change AO by O(1e-4).
inline constexpr float kRayOffsetRelative = 1e-4f;

// Ambient occlusion at one surface point, exactly the Cycles AO convention: the fraction
// of cosine-weighted hemisphere directions around n_world whose ray travels radius_world
// (inf = unlimited) without hitting anything; binary visibility, no falloff, 1 = open.
// Estimator: `samples` directions from the R2 low-discrepancy sequence, Cranley-Patterson
// rotated by (shift_u, shift_v) in [0,1)^2, mapped through Shirley-Chiu's concentric disk
// and Malley's method (pdf = cos / pi, so the estimate is the plain mean of visibilities).
float ao_at_point(const Scene& scene, const glm::vec3& p_world, const glm::vec3& n_world,
                  float radius_world, int samples, float shift_u = 0.5f, float shift_v = 0.5f);

// reference_ao: ao_at_point for every foreground pixel of `gbuffer` (the point from
// position_view or, when absent, depth; the normal from normal_view), with a per-pixel
// Cranley-Patterson shift from noise01(x, y, {0, 1}, seed). radius_world in (0, inf],
// samples >= 1. CV_32FC1, 1 on background.
cv::Mat reference_ao(const Scene& scene, const GBuffer& gbuffer, float radius_world, int samples,
                     uint32_t seed, int nthreads = 0);

// Environment radiance (linear RGB) arriving from world direction dir_world (unit; the
// direction light travels *from*, i.e. pointing away from the shaded point).
using EnvironmentRadiance = std::function<glm::vec3(const glm::vec3& dir_world)>;

// Uniform environment of radiance `rgb` in every direction.
EnvironmentRadiance uniform_environment(glm::vec3 rgb = glm::vec3(1.0f));

// The procedural sky of the shared Cycles dumps (world Z up):
// t = clamp((d.z + 0.4) / 0.8, 0, 1), L = (1 - t) (1.0, 0.35, 0.08) + t (0.25, 0.5, 1.0).
EnvironmentRadiance gradient_sky_environment();

struct LightSample {
  glm::vec3 direct{0.0f};
  glm::vec3 indirect{0.0f};
};

// Light at one surface point, in the Cycles DiffDir / DiffInd conventions ("divided by
// albedo"), with the environment as the only light (no lamps):
//   direct   = (1/pi) \int_H L_env(w) V(w) cos(theta) dw
//   indirect = (1/pi) \int_H L_1(w) cos(theta) dw,  L_1 = albedo(hit) * direct(hit)
// where V(w) = 1 when the ray leaves radius_world without a hit (inf = unlimited, the
// physical value), and L_1 is the outgoing radiance of the first hit within radius_world
// (only its direct light: one bounce, as Cycles with max bounces 1). Beyond radius_world a
// ray counts as open for direct and contributes no indirect: the same ray limit as AO.
// Primary directions as in ao_at_point; direct(hit) is a one-ray estimate (path tracing,
// unbiased) whose direction comes from hash noise with `secondary_seed`.
// A white unoccluded surface under uniform radiance 1 gets direct = 1, indirect = 0.
LightSample light_at_point(const Scene& scene, const glm::vec3& p_world, const glm::vec3& n_world,
                           const EnvironmentRadiance& environment_radiance, float radius_world,
                           int samples, float shift_u = 0.5f, float shift_v = 0.5f,
                           uint32_t secondary_seed = 0);

struct LightReference {
  cv::Mat direct;    // CV_32FC3 RGB, 0 on background
  cv::Mat indirect;  // CV_32FC3 RGB, 0 on background
};

// light_at_point for every foreground pixel of `gbuffer` (per-pixel shifts as
// reference_ao). environment_radiance must be thread-safe (it is called concurrently).
LightReference reference_light(const Scene& scene, const GBuffer& gbuffer,
                               const EnvironmentRadiance& environment_radiance,
                               float radius_world, int samples, uint32_t seed, int nthreads = 0);

// ---------------------------------------------------------------------------------------
// Scene builders (world Z up, scene units) and a camera for each. Camera helpers take the
// frame size; the defaults are the test size.

// Floor z = 0 (normal +Z) meeting a wall x = 0 (normal +X), both infinite, albedo 0.8.
// Closed forms (unlimited radius): AO = 0.5 and, under uniform radiance 1, direct = 0.5 at
// every visible point. With radius R, a floor point at distance d from the wall has
// AO = 1 - (acos(a) - a sqrt(1 - a^2)) / pi with a = min(d / R, 1) (the disk segment cut by
// the wall in the projected-disk picture of cosine-weighted directions).
Scene corner_scene();
// Looks at the corner line from the front (x > 0), floor and wall both in view.
Camera corner_camera(int width_px = 160, int height_px = 90);

// Floor z = 0 and a sphere of radius R centred at (0, 0, h), h > R. Closed form: a floor
// point directly below the centre has AO = 1 - (R / h)^2 for any radius >= h (the sphere
// subtends a cone of half-angle asin(R / h); its cosine-weighted fraction is sin^2).
Scene sphere_over_plane(float radius_world, float height_world);
// Looks at the foot point (0, 0, 0) from the side and slightly above, sphere in view.
Camera sphere_over_plane_camera(float radius_world, float height_world, int width_px = 160,
                                int height_px = 90);

// A single infinite plane through the origin with the given unit normal. AO = 1 and, under
// uniform radiance 1, direct = 1 everywhere.
Scene open_plane(glm::vec3 normal_world);
// Looks at the origin from distance 4 along a direction elevation_deg above the plane
// (90 = head-on, a few degrees = grazing).
Camera open_plane_camera(glm::vec3 normal_world, float elevation_deg, int width_px = 160,
                         int height_px = 90);
// The same camera through parallel rays: an orthographic view half_width_world to each
// side of its axis (the height from the frame's aspect), depths 0.1 to 100.
Camera with_parallel_rays(Camera camera, float half_width_world);

// Cornell-like room as the shared "cornell" dump: x in [-2, 2], y in [0, 4], z in [0, 3];
// red left wall (x = -2), green right wall, grey floor, back wall and ceiling with a 2x2
// skylight; a tall (1.1 x 1.1 x 2.4) and a short (1.1 x 1.1 x 1.2) block; open at y = 0.
// Walls are boxes 0.1 thick outside the room.
Scene cornell_scene();
// At (0, -3, 1.5) looking along +Y, fov_x 65 (as the shared dump).
Camera cornell_camera(int width_px = 160, int height_px = 90);

// White infinite floor z = 0 beside a finite red wall (albedo (0.8, 0.05, 0.05)) occupying
// x in [-0.2, 0], y in [-3, 3], z in [0, 1.5]: colour bleeding onto the floor near x = 0,
// none far away (the wall subtends ~0 solid angle at x >> 1.5).
Scene red_wall_scene();
Camera red_wall_camera(int width_px = 160, int height_px = 90);

// Thin poles (0.04 x 0.04 x 2 boxes) 0.3-1.2 units in front of a wall y = 3 (normal -Y)
// standing on a floor z = 0: thin occluders that a depth buffer sees as tall walls.
Scene poles_scene();
Camera poles_camera(int width_px = 160, int height_px = 90);

// Objects floating far in front of a back plane y = 7 (normal -Y): a sphere, a rotated box
// and a tall thin box, 4-6 units in front of it, no floor. Depth discontinuities: a height
// field (infinite thickness) wrongly darkens the back plane around their silhouettes.
Scene floating_scene();
Camera floating_camera(int width_px = 160, int height_px = 90);

// A shot: the camera trucks sideways along +X over a floor z = 0 towards a wall y = 3.5
// (facing -Y), kTruckShotStepWorld per frame, 55 degrees wide, centred on x = 0 at frame
// kTruckShotFrames / 2. From the camera's side back: low boxes (0.5 cubes, 2.4 apart) that
// pass the left and right screen edges during the shot and darken the floor beside them
// while off screen; box pairs, a 0.6 cube hiding a taller box (0.4 x 0.4 x 1.2) 0.2 behind
// it; thin slabs (0.8 wide, 0.04 deep, 1 tall) 0.6 in front of the wall, and thin poles
// (0.06 square, 1.8 tall) 0.3-1.0 in front of it, which a depth buffer takes for solids.
inline constexpr int kTruckShotFrames = 7;
inline constexpr float kTruckShotStepWorld = 0.5f;
inline constexpr float kTruckShotFovXDeg = 55.0f;
Scene truck_shot_scene();
// Frame t of the shot at width_px x height_px; with guard_px > 0, the same camera with
// guard_px more pixels on each side (the same projection per pixel: overscan).
Camera truck_shot_camera(int t, int width_px, int height_px, int guard_px = 0);

}  // namespace ssdo::raycast
