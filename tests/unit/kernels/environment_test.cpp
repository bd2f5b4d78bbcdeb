// Environment light: SH projection, the irradiance table, equirect layout, up axis,
// cone-filtered lookups. Everything is built in memory (no file I/O in kernels tests).
#include "kernels/environment.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/skips.h"

namespace ssdo {
namespace {

constexpr double kPi = 3.14159265358979323846;

glm::vec3 dir_from_angles(double elevation, double azimuth) {
  return glm::vec3(float(std::cos(elevation) * std::cos(azimuth)),
                   float(std::cos(elevation) * std::sin(azimuth)), float(std::sin(elevation)));
}

// (1/pi) integral of L(w) max(0, n.w) dw, midpoint rule on a fine lat-long grid (double).
template <class F>
glm::dvec3 numeric_irradiance_over_pi(F radiance, const glm::vec3& n) {
  const int rows = 1024, cols = 2048;
  glm::dvec3 sum(0.0);
  for (int j = 0; j < rows; ++j) {
    const double el_top = kPi * (0.5 - double(j) / rows), el_bottom = kPi * (0.5 - double(j + 1) / rows);
    const double d_omega = (2.0 * kPi / cols) * (std::sin(el_top) - std::sin(el_bottom));
    const double el = 0.5 * (el_top + el_bottom);
    for (int i = 0; i < cols; ++i) {
      const glm::vec3 w = dir_from_angles(el, 2.0 * kPi * (i + 0.5) / cols);
      const double c = glm::dot(n, w);
      if (c > 0.0) sum += glm::dvec3(radiance(w)) * (c * d_omega);
    }
  }
  return sum / kPi;
}

TEST(Environment, ConstantProjectsExactly) {
  const glm::vec3 l(0.3f, 1.0f, 2.5f);
  const Environment env = Environment::constant(l);
  const auto& sh = env.sh_radiance();
  const float l00_per_unit = float(0.28209479177387814 * 4.0 * kPi);  // Y00 x 4 pi
  for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(sh[0][c], l[c] * l00_per_unit);
  for (int k = 1; k < 9; ++k) EXPECT_EQ(sh[k], glm::vec3(0.0f)) << k;
  for (const glm::vec3& n : {glm::vec3(0, 0, 1), glm::vec3(0, 0, -1), glm::normalize(glm::vec3(1, -2, 0.5f))}) {
    const glm::vec3 e = env.irradiance_over_pi(n);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(e[c], l[c], 1e-6f * l[c]);
    EXPECT_EQ(env.radiance(n), l);
    EXPECT_EQ(env.radiance_filtered(n), l);
  }
}

TEST(Environment, ConstantEquirectProjectsExactly) {
  // A constant image: the exact pixel solid angles sum to 4 pi, so L00 is exact to float.
  cv::Mat img(64, 128, CV_32FC3, cv::Scalar(2.0, 2.0, 2.0));
  const Environment env = Environment::equirect(img);
  EXPECT_NEAR(env.sh_radiance()[0].x, 2.0 * 0.28209479177387814 * 4.0 * kPi, 1e-5);
  for (int k = 1; k < 9; ++k) EXPECT_NEAR(env.sh_radiance()[k].x, 0.0f, 1e-5f) << k;
  EXPECT_NEAR(env.irradiance_over_pi(glm::vec3(0, 0, 1)).y, 2.0f, 1e-5f);
}

// The mean radiance over the sphere (the ambient terms' uniform light): a constant's own,
// exactly; the sky's is (top + bottom) / 2 (its blend is symmetric about the horizon and
// the sphere's area is uniform in the up-component); an image's, its solid-angle mean.
TEST(Environment, MeanRadianceIsTheUniformLightOfTheSamePower) {
  const glm::vec3 l(0.3f, 1.0f, 2.5f);
  EXPECT_EQ(Environment::constant(l).mean_radiance(), l);
  const SkyGradient sky;
  const glm::vec3 sky_mean = Environment::sky(sky).mean_radiance(), expected = 0.5f * (sky.top + sky.bottom);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(sky_mean[c], expected[c], 0.005f * expected[c]) << c;
  cv::Mat img(64, 128, CV_32FC3, cv::Scalar(2.0, 2.0, 2.0));
  img.rowRange(0, 32).setTo(cv::Scalar(6.0, 6.0, 6.0));  // the upper hemisphere 3x brighter
  EXPECT_NEAR(Environment::equirect(img).mean_radiance().x, 4.0f, 1e-4f);
}

TEST(Environment, CyclesSkyIrradianceMatchesIntegrationWithinOnePercent) {
  const SkyGradient sky;  // defaults = the Cycles world of the shared dumps
  const Environment env = Environment::sky(sky);
  auto formula = [](const glm::vec3& d) {  // docs/usage.md, "Environment light", verbatim
    const float t = std::clamp((d.z + 0.4f) / 0.8f, 0.0f, 1.0f);
    return (1.0f - t) * glm::vec3(1.0f, 0.35f, 0.08f) + t * glm::vec3(0.25f, 0.5f, 1.0f);
  };
  double worst = 0.0;
  for (double el_deg : {90.0, 60.0, 30.0, 10.0, 0.0, -20.0, -45.0, -90.0}) {
    const glm::vec3 n = dir_from_angles(el_deg * kPi / 180.0, 0.7);
    const glm::dvec3 ref = numeric_irradiance_over_pi(formula, n);
    const glm::vec3 sh = env.irradiance_over_pi(n);
    for (int c = 0; c < 3; ++c) {
      const double rel = std::abs(sh[c] - ref[c]) / ref[c];
      worst = std::max(worst, rel);
      EXPECT_LT(rel, 0.01) << "elevation " << el_deg << " channel " << c << " sh " << sh[c] << " ref " << ref[c];
    }
    EXPECT_EQ(env.radiance(n), formula(n));
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
  std::printf("[ info ] Cycles sky: irradiance worst relative error %.4f%%\n", 100.0 * worst);
}

// A sun: one bright texel of a black map, E / pi = max(0, n . s) for its direction s (its
// radiance times its solid angle is pi). The irradiance follows the cosine law to within
// 2% of the sun's irradiance at every angle, 0 facing away; the order-2 SH it replaced
// gave 1.06 facing the sun and +0.06 to +0.1 on surfaces at 90 degrees and beyond.
TEST(Environment, ASunLightsByTheCosineLawAndNotBehind) {
  const cv::Size size(256, 128);
  cv::Mat img(size, CV_32FC3, cv::Scalar::all(0.0));
  const int si = 100, sj = 40;  // 20 degrees above the horizon
  const double el_top = kPi * (0.5 - double(sj) / size.height), el_bottom = kPi * (0.5 - double(sj + 1) / size.height);
  const double omega = (2.0 * kPi / size.width) * (std::sin(el_top) - std::sin(el_bottom));
  img.at<cv::Vec3f>(sj, si) = cv::Vec3f::all(float(kPi / omega));
  const glm::vec3 sun = Environment::direction_from_equirect({si + 0.5f, sj + 0.5f}, size);
  const Environment env = Environment::equirect(img);
  // Normals at angles from the sun in the plane of the sun and the zenith, and around it.
  const glm::vec3 side = glm::normalize(glm::cross(sun, glm::vec3(0, 0, 1))), up = glm::cross(side, sun);
  double worst = 0.0;
  for (double deg = 0.0; deg <= 180.0; deg += 7.5)
    for (const glm::vec3& axis : {up, side, glm::normalize(up + side)}) {
      const double a = deg * kPi / 180.0;
      const glm::vec3 n = glm::normalize(float(std::cos(a)) * sun + float(std::sin(a)) * axis);
      const double expect = std::max(0.0, double(glm::dot(n, sun)));
      const glm::vec3 e = env.irradiance_over_pi(n);
      worst = std::max(worst, std::abs(double(e.x) - expect));
      EXPECT_NEAR(e.x, expect, 0.02) << deg << " deg from the sun";
      if (deg >= 97.5) {
        EXPECT_LT(e.x, 1e-6) << deg << " deg from the sun: facing away";
      }
    }
  std::printf("[ info ] sun: worst irradiance error %.4f of the sun's\n", worst);
}

TEST(Environment, EquirectLayoutMatchesCyclesConvention) {
  const cv::Size size(512, 256);
  auto dir = [&](float i, float j) { return Environment::direction_from_equirect({i, j}, size); };
  auto near = [](const glm::vec3& a, const glm::vec3& b) { return glm::length(a - b) < 1e-5f; };
  EXPECT_TRUE(near(dir(256.0f, 128.0f), glm::vec3(0, 1, 0)));   // centre column looks at +Y
  EXPECT_TRUE(near(dir(128.0f, 128.0f), glm::vec3(-1, 0, 0)));  // quarter: -X
  EXPECT_TRUE(near(dir(384.0f, 128.0f), glm::vec3(1, 0, 0)));   // three quarters: +X
  EXPECT_TRUE(near(dir(0.0f, 128.0f), glm::vec3(0, -1, 0)));    // left edge: -Y
  EXPECT_TRUE(near(dir(77.0f, 0.0f), glm::vec3(0, 0, 1)));      // top edge: straight up
  EXPECT_TRUE(near(dir(300.0f, 256.0f), glm::vec3(0, 0, -1)));  // bottom edge: straight down
  // Pixel centre elevations: theta = pi (0.5 - (j + 0.5) / H).
  EXPECT_NEAR(std::asin(dir(10.5f, 0.5f).z), kPi * (0.5 - 0.5 / 256), 1e-5);
  // Round trip.
  for (float i : {3.2f, 100.0f, 255.9f, 400.1f, 511.0f})
    for (float j : {1.0f, 64.3f, 128.0f, 200.7f, 255.0f}) {
      const glm::vec2 p = Environment::equirect_from_direction(dir(i, j), size);
      EXPECT_NEAR(p.x, i, 2e-3f);
      EXPECT_NEAR(p.y, j, 2e-3f);
    }
}

// f(d) = 0.5 + 0.5 d per channel (R <- x, G <- y, B <- z): linear, so its SH irradiance is
// exact, E/pi = 0.5 + (2/3) 0.5 n, and bilinear lookups are accurate to O(texel^2).
cv::Mat linear_equirect(cv::Size size) {
  cv::Mat img(size, CV_32FC3);
  for (int j = 0; j < size.height; ++j)
    for (int i = 0; i < size.width; ++i) {
      const glm::vec3 d = Environment::direction_from_equirect({i + 0.5f, j + 0.5f}, size);
      img.at<cv::Vec3f>(j, i) = cv::Vec3f(0.5f + 0.5f * d.x, 0.5f + 0.5f * d.y, 0.5f + 0.5f * d.z);
    }
  return img;
}

TEST(Environment, EquirectLookupsFollowTheDirection) {
  const Environment env = Environment::equirect(linear_equirect({512, 256}));
  float worst_radiance = 0.0f, worst_irradiance = 0.0f;
  for (int k = 0; k < 200; ++k) {
    // A spread of directions (golden-angle spiral).
    const double z = 1.0 - 2.0 * (k + 0.5) / 200.0, az = k * 2.399963229728653;
    const glm::vec3 d = dir_from_angles(std::asin(z), az);
    const glm::vec3 expect = glm::vec3(0.5f) + 0.5f * d;
    const glm::vec3 got = env.radiance(d);
    worst_radiance = std::max(worst_radiance, glm::length(got - expect));
    const glm::vec3 e_expect = glm::vec3(0.5f) + (2.0f / 3.0f) * 0.5f * d;
    worst_irradiance = std::max(worst_irradiance, glm::length(env.irradiance_over_pi(d) - e_expect));
  }
  EXPECT_LT(worst_radiance, 2e-3f);
  EXPECT_LT(worst_irradiance, 1e-3f);
}

TEST(Environment, UpAxisYRotatesWorldYToZenith) {
  EnvironmentSettings s;
  s.up = UpAxis::y;
  SkyGradient sky;
  const Environment env = Environment::sky(sky, s);
  EXPECT_EQ(env.radiance(glm::vec3(0, 1, 0)), sky.top);
  EXPECT_EQ(env.radiance(glm::vec3(0, -1, 0)), sky.bottom);
  EXPECT_EQ(env.radiance(glm::vec3(0, 0, 1)), 0.5f * (sky.top + sky.bottom));
  // The rotation is proper (det +1) and agrees with the matrix form.
  const glm::mat3 m = env.env_from_world_matrix();
  EXPECT_NEAR(glm::determinant(m), 1.0f, 1e-6f);
  const glm::vec3 d = glm::normalize(glm::vec3(0.3f, -0.8f, 0.5f));
  EXPECT_LT(glm::length(m * d - env.env_from_world(d)), 1e-6f);
  // Y-up equirect: world +Y is the image's top row.
  cv::Mat img(32, 64, CV_32FC3, cv::Scalar(0, 0, 0));
  img.row(0).setTo(cv::Scalar(1, 1, 1));
  const Environment eq = Environment::equirect(img, s);
  EXPECT_NEAR(eq.radiance(glm::vec3(0, 1, 0)).x, 1.0f, 1e-6f);
  EXPECT_NEAR(eq.radiance(glm::vec3(0, 0, 1)).x, 0.0f, 1e-6f);
}

TEST(Environment, FilteredLookupAveragesOverTheCone) {
  EnvironmentSettings s;
  s.filter_cone_half_angle_deg = 15.0f;
  const SkyGradient sky;
  const Environment env = Environment::sky(sky, s);
  // Straight up the cone (z >= cos 15 deg = 0.97) lies entirely in the top colour.
  const glm::vec3 up = env.radiance_filtered(glm::vec3(0, 0, 1));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(up[c], sky.top[c], 1e-4f);
  // At the horizon the ramp is symmetric about the cone's axis: the mean is the midpoint.
  const glm::vec3 h = env.radiance_filtered(glm::vec3(1, 0, 0));
  const glm::vec3 mid = 0.5f * (sky.top + sky.bottom);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(h[c], mid[c], 0.01f * mid[c] + 2e-3f);
  // A sharp feature is spread: a one-row bright band at the zenith of an equirect image.
  cv::Mat img(128, 256, CV_32FC3, cv::Scalar(0, 0, 0));
  img.rowRange(0, 2).setTo(cv::Scalar(1, 1, 1));
  const Environment eq = Environment::equirect(img, s);
  const float at_zenith = eq.radiance_filtered(glm::vec3(0, 0, 1)).x;
  EXPECT_GT(at_zenith, 0.0f);
  EXPECT_LT(at_zenith, 0.5f);
  EXPECT_NEAR(filter_cone_half_angle_for_samples(30), 14.8f, 0.1f);
}

// The cone filter as its comment states it, by brute force: the filter source (the image
// box-averaged, solid-angle weighted, down to 64 rows when taller), then for every target
// texel every source texel of every row in the cone's elevation band is tested.
cv::Mat reference_filtered_map(const cv::Mat& image, const EnvironmentSettings& s) {
  auto pixel_solid_angle = [](int j, cv::Size size) {
    const double top = kPi * (0.5 - double(j) / size.height), bottom = kPi * (0.5 - double(j + 1) / size.height);
    return (2.0 * kPi / size.width) * (std::sin(top) - std::sin(bottom));
  };
  cv::Mat source = image;
  if (image.rows > 64) {
    const cv::Size ssize(128, 64);
    std::vector<double> sum(size_t(ssize.area()) * 3, 0.0), weight(size_t(ssize.area()), 0.0);
    for (int j = 0; j < image.rows; ++j)
      for (int i = 0; i < image.cols; ++i) {
        const double d_omega = pixel_solid_angle(j, image.size());
        const size_t t = size_t(j * ssize.height / image.rows) * ssize.width + size_t(i * ssize.width / image.cols);
        for (int c = 0; c < 3; ++c) sum[3 * t + c] += image.at<cv::Vec3f>(j, i)[c] * d_omega;
        weight[t] += d_omega;
      }
    source.create(ssize, CV_32FC3);
    for (size_t t = 0; t < size_t(ssize.area()); ++t)
      for (int c = 0; c < 3; ++c) source.ptr<cv::Vec3f>()[t][c] = float(sum[3 * t + c] / weight[t]);
  }
  const cv::Size tsize(2 * s.filtered_height_px, s.filtered_height_px), ssize = source.size();
  const double cone = s.filter_cone_half_angle_deg * kPi / 180.0;
  const float cos_cone = float(std::cos(cone));
  const Environment point = Environment::equirect(source);  // the fallback's bilinear lookup
  std::vector<glm::vec3> source_dir;
  for (int j = 0; j < ssize.height; ++j)
    for (int i = 0; i < ssize.width; ++i)
      source_dir.push_back(Environment::direction_from_equirect({i + 0.5f, j + 0.5f}, ssize));
  cv::Mat out(tsize, CV_32FC3);
  for (int tj = 0; tj < tsize.height; ++tj)
    for (int ti = 0; ti < tsize.width; ++ti) {
      const glm::vec3 c = Environment::direction_from_equirect({ti + 0.5f, tj + 0.5f}, tsize);
      const double theta_t = kPi * (0.5 - (tj + 0.5) / tsize.height);
      double sum[3] = {0.0, 0.0, 0.0}, weight = 0.0;
      for (int j = 0; j < ssize.height; ++j) {
        const double theta_s = kPi * (0.5 - (j + 0.5) / ssize.height);
        if (std::abs(theta_s - theta_t) > cone + 0.5 * kPi / ssize.height) continue;
        const double d_omega = pixel_solid_angle(j, ssize);
        for (int i = 0; i < ssize.width; ++i) {
          if (glm::dot(source_dir[size_t(j) * ssize.width + i], c) < cos_cone) continue;
          for (int k = 0; k < 3; ++k) sum[k] += source.at<cv::Vec3f>(j, i)[k] * d_omega;
          weight += d_omega;
        }
      }
      cv::Vec3f& v = out.at<cv::Vec3f>(tj, ti);
      if (weight > 0.0) {
        for (int k = 0; k < 3; ++k) v[k] = float(sum[k] / weight);
      } else {
        const glm::vec3 l = point.radiance_env(c);
        v = cv::Vec3f(l.x, l.y, l.z);
      }
    }
  return out;
}

TEST(Environment, FilteredMapMatchesTheBruteForceConeFilterBitForBit) {
  SSDO_REFERENCE_MEASUREMENT();
  cv::RNG rng(3);
  // Sources used as they are (64 rows or fewer, of either aspect) and box-averaged ones.
  for (const cv::Size size : {cv::Size(128, 64), cv::Size(90, 37), cv::Size(200, 100)}) {
    cv::Mat img(size, CV_32FC3);
    rng.fill(img, cv::RNG::UNIFORM, 0.0, 4.0);
    for (const float cone_deg : {0.0f, 1.0f, 7.3f, 15.0f, 40.0f, 90.0f})
      for (const int height : {8, 29, 48}) {
        EnvironmentSettings s;
        s.filter_cone_half_angle_deg = cone_deg;
        s.filtered_height_px = height;
        const cv::Mat got = Environment::equirect(img, s).filtered_map();
        const cv::Mat want = reference_filtered_map(img, s);
        ASSERT_EQ(got.size(), want.size());
        ASSERT_EQ(std::memcmp(got.data, want.data, want.total() * want.elemSize()), 0)
            << size << " cone " << cone_deg << " height " << height;
      }
  }
}

}  // namespace
}  // namespace ssdo
