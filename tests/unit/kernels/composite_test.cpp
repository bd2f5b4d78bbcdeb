// Composite: term selection, weights, the meaning of missing inputs, background.
#include "kernels/composite.h"

#include <cstring>

#include <gtest/gtest.h>

namespace ssdo {
namespace {

struct Images {
  cv::Mat mask{2, 3, CV_8UC1, cv::Scalar(255)};
  cv::Mat albedo{2, 3, CV_32FC3, cv::Scalar(0.5, 0.25, 1.0)};
  cv::Mat ao{2, 3, CV_32FC1, cv::Scalar(0.6)};
  cv::Mat direct{2, 3, CV_32FC3, cv::Scalar(0.8, 0.4, 0.2)};
  cv::Mat indirect{2, 3, CV_32FC3, cv::Scalar(0.1, 0.2, 0.3)};
  cv::Mat lighting{2, 3, CV_32FC3, cv::Scalar(2.0, 3.0, 4.0)};
  Images() { mask.at<uint8_t>(1, 2) = 0; }
};

cv::Vec3f composite_at(const CompositeInputs& in, const CompositeSettings& s, int x = 0, int y = 0) {
  EXPECT_EQ(validate(in, s), "");
  cv::Mat out;
  compute_composite(in, s, out, {}, 1);
  return out.at<cv::Vec3f>(y, x);
}

void expect_rgb(const cv::Vec3f& v, float r, float g, float b) {
  EXPECT_FLOAT_EQ(v[0], r);
  EXPECT_FLOAT_EQ(v[1], g);
  EXPECT_FLOAT_EQ(v[2], b);
}

TEST(Composite, DefaultIsAlbedoTimesDirectPlusIndirect) {
  Images im;
  const CompositeInputs in{im.mask, &im.albedo, &im.ao, &im.direct, &im.indirect};
  expect_rgb(composite_at(in, {}), 0.5f * 0.9f, 0.25f * 0.6f, 1.0f * 0.5f);
}

TEST(Composite, ModesAreTermLists) {
  Images im;
  const CompositeInputs in{im.mask, &im.albedo, &im.ao, &im.direct, &im.indirect};
  CompositeSettings s;
  s.terms = composite_mode_terms(CompositeMode::off);
  expect_rgb(composite_at(in, s), 0.5f, 0.25f, 1.0f);
  s.terms = composite_mode_terms(CompositeMode::ssao);
  expect_rgb(composite_at(in, s), 0.5f * 0.6f, 0.25f * 0.6f, 0.6f);
  s.terms = composite_mode_terms(CompositeMode::ssao_ssdo);
  s.ambient_radiance = glm::vec3(0.5f);
  expect_rgb(composite_at(in, s), 0.5f * (0.3f + 0.9f), 0.25f * (0.3f + 0.6f), 0.3f + 0.5f);
  EXPECT_EQ(parse_composite_mode("ssao+ssdo"), CompositeMode::ssao_ssdo);
  EXPECT_EQ(parse_composite_term("lighting"), CompositeTerm::lighting);
  EXPECT_FALSE(parse_composite_mode("both").has_value());
}

TEST(Composite, WeightsAndLampLighting) {
  Images im;
  const CompositeInputs in{im.mask, &im.albedo, &im.ao, &im.direct, &im.indirect, &im.lighting};
  CompositeSettings s;
  s.terms = {{CompositeTerm::ssdo_indirect, 2.0f}, {CompositeTerm::ssdo_direct, 0.5f},
             {CompositeTerm::lighting, 0.25f}};
  // Order of the list does not matter; lighting is not multiplied by albedo.
  expect_rgb(composite_at(in, s), 0.5f * (0.4f + 0.2f) + 0.5f, 0.25f * (0.2f + 0.4f) + 0.75f,
             1.0f * (0.1f + 0.6f) + 1.0f);
}

TEST(Composite, MissingInputsMeanWhiteAlbedoAndNoOcclusion) {
  Images im;
  const CompositeInputs in{im.mask, nullptr, nullptr, &im.direct};
  CompositeSettings s;
  s.terms = {{CompositeTerm::ambient_ao, 1.0f}, {CompositeTerm::ssdo_direct, 1.0f}};
  expect_rgb(composite_at(in, s), 1.0f + 0.8f, 1.0f + 0.4f, 1.0f + 0.2f);
  // A selected term without its input is an error that names it.
  s.terms = composite_mode_terms(CompositeMode::ssdo);
  EXPECT_NE(validate(in, s).find("ssdo_indirect"), std::string::npos);
  s.terms = {{CompositeTerm::lighting, 1.0f}};
  EXPECT_NE(validate(in, s).find("lighting"), std::string::npos);
  s.terms = {{CompositeTerm::ambient, 1.0f}, {CompositeTerm::ambient, 1.0f}};
  EXPECT_NE(validate(in, s).find("twice"), std::string::npos);
  s.terms = {{CompositeTerm::ambient, -1.0f}};
  EXPECT_NE(validate(in, s).find("range"), std::string::npos);
  cv::Mat wrong(3, 3, CV_32FC1, cv::Scalar(1));
  const CompositeInputs bad{im.mask, nullptr, &wrong};
  EXPECT_NE(validate(bad, {}).find("ao"), std::string::npos);
}

TEST(Composite, BackgroundFromImageEnvironmentOrZero) {
  Images im;
  CompositeSettings s;
  s.terms = composite_mode_terms(CompositeMode::off);
  const CompositeInputs none{im.mask, &im.albedo};
  expect_rgb(composite_at(none, s, 2, 1), 0.0f, 0.0f, 0.0f);
  cv::Mat bg(2, 3, CV_32FC3, cv::Scalar(7, 8, 9));
  const CompositeInputs with_bg{im.mask, &im.albedo, nullptr, nullptr, nullptr, nullptr, &bg};
  expect_rgb(composite_at(with_bg, s, 2, 1), 7.0f, 8.0f, 9.0f);
  // Environment: a sky seen by a camera looking straight up sees the top colour.
  Camera cam = Camera::from_fov_x(3, 2, 1.0f);
  // Columns = world images of the view axes: X -> -X, Y -> +Y, Z -> -Z (so -Z view = +Z world).
  cam.view_to_world = glm::mat4(glm::vec4(-1, 0, 0, 0), glm::vec4(0, 1, 0, 0), glm::vec4(0, 0, -1, 0),
                                glm::vec4(0, 0, 0, 1));
  cam.world_to_view = glm::inverse(cam.view_to_world);
  const SkyGradient sky;
  const Environment env = Environment::sky(sky);
  const CompositeInputs with_env{im.mask, &im.albedo, nullptr, nullptr, nullptr, nullptr, nullptr, &env, &cam};
  const cv::Vec3f v = composite_at(with_env, s, 2, 1);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(v[c], sky.top[c], 1e-6f);
}

TEST(Composite, RoiAndThreads) {
  cv::Mat mask(64, 48, CV_8UC1, cv::Scalar(255)), direct(64, 48, CV_32FC3), albedo(64, 48, CV_32FC3);
  cv::randu(direct, 0.0f, 1.0f);
  cv::randu(albedo, 0.0f, 1.0f);
  const CompositeInputs in{mask, &albedo, nullptr, &direct};
  CompositeSettings s;
  s.terms = {{CompositeTerm::ssdo_direct, 1.0f}};
  cv::Mat one, two, part(64, 48, CV_32FC3, cv::Scalar(-1, -1, -1));
  compute_composite(in, s, one, {}, 1);
  compute_composite(in, s, two, {}, 2);
  EXPECT_EQ(std::memcmp(one.data, two.data, one.total() * one.elemSize()), 0);
  const cv::Rect roi(5, 9, 20, 30);
  compute_composite(in, s, part, roi, 2);
  EXPECT_EQ(cv::norm(part(roi), one(roi), cv::NORM_INF), 0.0);
  EXPECT_EQ(part.at<cv::Vec3f>(0, 0)[0], -1.0f);
}

// The composite of one pixel as composite.h states it, term by term.
cv::Vec3f reference_pixel(const CompositeInputs& in, const CompositeSettings& s, int x, int y) {
  auto rgb = [&](const cv::Mat* m, glm::vec3 missing) {
    if (!m || m->empty()) return missing;
    const cv::Vec3f& v = m->at<cv::Vec3f>(y, x);
    return glm::vec3(v[0], v[1], v[2]);
  };
  glm::vec3 c(0.0f);
  if (!in.mask.at<uint8_t>(y, x)) {
    if (in.background && !in.background->empty()) {
      c = rgb(in.background, glm::vec3(0.0f));
    } else if (in.environment && in.camera) {
      const glm::vec3 d_view = in.camera->view_ray_direction({x + 0.5f, y + 0.5f});
      c = in.environment->radiance(in.camera->world_from_view_direction(d_view));
    }
    return {c.x, c.y, c.z};
  }
  float w[5] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  for (const WeightedTerm& t : s.terms) w[int(t.term)] = t.weight;
  const float ao = in.ao && !in.ao->empty() ? in.ao->at<float>(y, x) : 1.0f;
  glm::vec3 irradiance_like = (w[int(CompositeTerm::ambient)] + w[int(CompositeTerm::ambient_ao)] * ao) *
                              s.ambient_radiance;
  if (w[int(CompositeTerm::ssdo_direct)] > 0.0f)
    irradiance_like += w[int(CompositeTerm::ssdo_direct)] * rgb(in.direct, glm::vec3(0.0f));
  if (w[int(CompositeTerm::ssdo_indirect)] > 0.0f)
    irradiance_like += w[int(CompositeTerm::ssdo_indirect)] * rgb(in.indirect, glm::vec3(0.0f));
  c = rgb(in.albedo, glm::vec3(1.0f)) * irradiance_like;
  if (w[int(CompositeTerm::lighting)] > 0.0f)
    c += w[int(CompositeTerm::lighting)] * rgb(in.lighting, glm::vec3(0.0f));
  return {c.x, c.y, c.z};
}

TEST(Composite, MatchesThePerPixelReferenceBitForBit) {
  const cv::Size size(67, 41);
  cv::RNG rng(7);
  cv::Mat mask(size, CV_8UC1), albedo(size, CV_32FC3), ao(size, CV_32FC1), direct(size, CV_32FC3),
      indirect(size, CV_32FC3), lighting(size, CV_32FC3), background(size, CV_32FC3);
  rng.fill(mask, cv::RNG::UNIFORM, 0, 2);
  mask *= 255;
  for (cv::Mat* m : {&albedo, &ao, &direct, &indirect, &lighting, &background})
    rng.fill(*m, cv::RNG::UNIFORM, 0.0, 2.0);
  const Environment env = Environment::sky(SkyGradient{});
  const Camera cam = Camera::from_fov_x(size.width, size.height, 60.0f);
  for (int subset = 0; subset < 32; ++subset)
    for (int inputs = 0; inputs < 4; ++inputs) {
      CompositeSettings s;
      s.terms.clear();
      for (int t = 0; t < 5; ++t)
        if (subset & (1 << t)) s.terms.push_back({CompositeTerm(t), t == 2 && inputs == 3 ? 0.0f : 0.25f + 0.5f * t});
      s.ambient_radiance = glm::vec3(0.7f, 1.0f, 1.3f);
      const CompositeInputs in{mask,
                               inputs == 1 ? nullptr : &albedo,
                               inputs == 2 ? nullptr : &ao,
                               &direct,
                               &indirect,
                               &lighting,
                               inputs == 0 ? &background : nullptr,
                               inputs == 1 ? nullptr : &env,
                               inputs == 1 ? nullptr : &cam};
      ASSERT_EQ(validate(in, s), "");
      cv::Mat out;
      compute_composite(in, s, out, {}, 2);
      for (int y = 0; y < size.height; ++y)
        for (int x = 0; x < size.width; ++x) {
          const cv::Vec3f want = reference_pixel(in, s, x, y), got = out.at<cv::Vec3f>(y, x);
          ASSERT_EQ(std::memcmp(&want, &got, sizeof want), 0) << "terms " << subset << " inputs " << inputs
                                                              << " pixel " << x << ", " << y;
        }
    }
}

}  // namespace
}  // namespace ssdo
