// An environment light as a value: constant radiance, a two-colour sky, or an
// equirectangular radiance image, with the two prefiltered lookups the light kernels use.
//
// Units: radiance in the renderer's linear RGB units (a constant environment of 1 lights a
// white unoccluded Lambertian surface to outgoing radiance 1, the Cycles convention).
//
// Frames. Lookups take world-space unit directions. Internally every direction is first
// rotated into the "environment frame", which is Z-up like Blender: for UpAxis::z the
// environment frame is the world frame; for UpAxis::y (glTF, OpenGL, Maya worlds) the
// rotation (x, y, z)_world -> (x, -z, y)_env maps +Y world to +Z env and keeps the frame
// right-handed. Kernels holding view-space directions rotate them to world with the camera
// (Camera::world_from_view_direction) first.
//
// Equirectangular layout (exactly that of env_equirect.exr in the shared G-buffers, which
// Cycles renders with an equirectangular camera looking at +Y, +Z up), image W x H:
//   row j (0 = top) has elevation  theta = pi (0.5 - (j + 0.5) / H)   (top row = +Z),
//   column i has azimuth           phi   = pi (1 - 2 (i + 0.5) / W),
//   direction d_env = (-cos(theta) sin(phi), cos(theta) cos(phi), sin(theta))
// so from left to right the columns at W/4 steps look at -Y, -X, +Y (centre), +X. Pixel
// (i, j) covers the solid angle (2 pi / W) (sin(theta_top) - sin(theta_bottom)).
//
// The three lookups and which term uses which:
//  - radiance(d): the unfiltered radiance (analytic for constant and sky, bilinear in the
//    image for equirect). Used by the oracle, which takes hundreds of directions per pixel
//    and wants the exact integrand.
//  - radiance_filtered(d): the radiance averaged over a cone of half-angle
//    EnvironmentSettings::filter_cone_half_angle_deg around d (a small pre-blurred lat-long,
//    bilinear). Used per sample by the SSDO direct term (the visible samples of its
//    per_sample estimator, the occluded ones of its default open_minus_occluded estimator,
//    see kernels/ssdo.h): one sample stands for a solid angle of about 2 pi / N (N samples
//    in the hemisphere), so looking up the radiance averaged over that footprint removes
//    the variance of sampling a high-frequency map at a point, at the price of a bias where
//    the cone straddles a sharp change (measured in ssdo_test.cpp).
//  - irradiance_over_pi(n): the cosine-convolved environment E(n) / pi, tabulated once on a
//    lat-long of normals (2.8 deg texels) by quadrature over the radiance box-averaged to
//    2.8 deg texels, read bilinearly. E / pi is "direct" of an unoccluded surface in the
//    Cycles DiffDir convention. Used by the SSDO direct estimators open_minus_occluded (the
//    unoccluded integral) and bent_normal; exact for constant environments, within 0.2% for
//    smooth skies (0.15% for the Cycles sky), and within 2% of a sun's irradiance at any
//    angle from it (1.5% measured), 0 facing away; built in ~10 ms of CPU per environment.
//    The order-2 spherical-harmonics form (Ramamoorthi and Hanrahan 2001) is exact to 1% for
//    smooth skies only: under a small bright source it leaks ~10% of its light onto
//    surfaces facing away (environment_test.cpp). The SH projection still gives
//    mean_radiance.
#pragma once

#include <array>
#include <string>

#include <glm/glm.hpp>
#include <opencv2/core.hpp>

namespace ssdo {

enum class UpAxis { z, y };

enum class EnvironmentKind { constant, sky, equirect };

// A two-colour sky: `top` for directions with up-component >= up_end, `bottom` for
// up-component <= up_begin, linearly blended in between (up-component = sin(elevation)).
// The defaults are the Cycles world of the shared G-buffers (docs/usage.md, "Environment light"):
//   t = clamp((d.z + 0.4) / 0.8, 0, 1),  L = (1 - t) bottom + t top.
struct SkyGradient {
  glm::vec3 top{0.25f, 0.5f, 1.0f};     // radiance straight up (RGB)
  glm::vec3 bottom{1.0f, 0.35f, 0.08f};  // radiance straight down (RGB)
  float up_begin = -0.4f;  // up-component where the blend starts, [-1, up_end)
  float up_end = 0.4f;     // up-component where the blend ends, (up_begin, 1]
};

struct EnvironmentSettings {
  UpAxis up = UpAxis::z;
  // Half-angle of the cone the filtered lookup averages over, degrees, [0, 90]. 0 = no
  // blur. The default 15 deg is the footprint of one of ~30 hemisphere samples
  // (2 pi (1 - cos 15 deg) ~ 2 pi / 30); filter_cone_half_angle_for_samples() gives it for N.
  float filter_cone_half_angle_deg = 15.0f;
  // Size of the pre-blurred lat-long, pixels (width = 2 x height), [8, 512]. A 15 deg cone
  // spans ~5 rows at 64 rows, enough for bilinear lookups to be smooth.
  int filtered_height_px = 64;
};

// The cone half-angle (degrees) whose solid angle is that of one of `samples`
// cosine-distributed hemisphere samples, 2 pi / samples, clamped to [0, 90].
float filter_cone_half_angle_for_samples(int samples);

// Returns an empty string when the settings are valid, else what is wrong.
std::string validate(const EnvironmentSettings& s);

class Environment {
 public:
  // A constant environment of radiance 1 (white).
  Environment();

  static Environment constant(const glm::vec3& radiance_rgb, const EnvironmentSettings& s = {});
  static Environment sky(const SkyGradient& sky, const EnvironmentSettings& s = {});
  // radiance_rgb: CV_32FC3 (R, G, B), W x H with W = 2 H (other aspect ratios are accepted
  // and mapped the same way), finite and >= 0. The image is shared, not copied.
  static Environment equirect(const cv::Mat& radiance_rgb, const EnvironmentSettings& s = {});

  EnvironmentKind kind() const { return kind_; }
  const EnvironmentSettings& settings() const { return settings_; }

  // World -> environment frame (a rotation, see the header comment).
  glm::vec3 env_from_world(const glm::vec3& d_world) const;
  // The same rotation as a matrix (column-major glm), to fold into per-frame matrices.
  glm::mat3 env_from_world_matrix() const;

  // Lookups by unit world direction (see the header comment for which term uses which).
  glm::vec3 radiance(const glm::vec3& d_world) const { return radiance_env(env_from_world(d_world)); }
  glm::vec3 radiance_filtered(const glm::vec3& d_world) const {
    return radiance_filtered_env(env_from_world(d_world));
  }
  glm::vec3 irradiance_over_pi(const glm::vec3& n_world) const {
    return irradiance_over_pi_env(env_from_world(n_world));
  }

  // The same lookups by unit direction already in the environment frame.
  glm::vec3 radiance_env(const glm::vec3& d_env) const;
  glm::vec3 radiance_filtered_env(const glm::vec3& d_env) const;
  glm::vec3 irradiance_over_pi_env(const glm::vec3& n_env) const;

  // The mean radiance over the sphere: the uniform light of the same power (a constant's
  // own radiance, exactly; else Y_00 L_00 of the SH projection below).
  glm::vec3 mean_radiance() const;

  // Order-2 SH projection of the radiance in the environment frame, L_lm = integral of
  // L(d) Y_lm(d) over the sphere, index k = l (l + 1) + m (0..8), real SH basis.
  const std::array<glm::vec3, 9>& sh_radiance() const { return sh_; }

  // The pre-blurred lat-long (CV_32FC3, same layout as the equirect input): what
  // radiance_filtered_env reads (for a sky too; a constant has none).
  const cv::Mat& filtered_map() const { return filtered_; }
  // The table irradiance_over_pi_env looks up (CV_32FC3 equirect of normals; not for a
  // constant).
  const cv::Mat& irradiance_map() const { return irradiance_; }

  // The odd polynomial of radiance_filtered_env's arctangent, a(t) = t (c0 + t^2 (c1 + ...)),
  // highest power first (the Cg reference atan2's coefficients, within 4e-6 rad on
  // [0, 1]): one table for the scalar lookup and the SSDO kernel's lanes, which must give
  // the same bits.
  static constexpr float kAtanPolynomial[6] = {-0.013480470f, 0.057477314f, -0.121239071f,
                                               0.195635925f,  -0.332994597f, 0.999995630f};

  // Real SH basis functions Y_lm(d), d unit, index k = l (l + 1) + m.
  static std::array<float, 9> sh_basis(const glm::vec3& d);

  // Equirect layout helpers (see the header comment). Continuous pixel coordinates
  // (centre of pixel (i, j) at (i + 0.5, j + 0.5)) <-> unit direction in the env frame.
  static glm::vec3 direction_from_equirect(glm::vec2 pixel, cv::Size size);
  static glm::vec2 equirect_from_direction(const glm::vec3& d_env, cv::Size size);

 private:
  // The kind and its asserted-valid settings; a factory then sets the kind's radiance and builds.
  Environment(EnvironmentKind kind, const EnvironmentSettings& s);
  void build();  // SH projection and filtered map from the kind's radiance
  glm::vec3 sh_irradiance_over_pi(const glm::vec3& n_env) const;  // the SH evaluation

  EnvironmentKind kind_ = EnvironmentKind::constant;
  EnvironmentSettings settings_;
  glm::vec3 constant_{1.0f};
  SkyGradient sky_;
  cv::Mat image_;     // equirect radiance, CV_32FC3
  cv::Mat filtered_;  // cone-filtered lat-long, CV_32FC3
  cv::Mat irradiance_;  // E(n) / pi on a lat-long of normals, CV_32FC3 (not for a constant)
  std::array<glm::vec3, 9> sh_{};
  glm::vec3 constant_irradiance_over_pi_{0.0f};  // a constant's irradiance_over_pi_env, any normal
};

}  // namespace ssdo
