#include "kernels/temporal.h"

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <span>
#include <vector>

#include <gtest/gtest.h>

#include "kernels/reprojection.h"
#include "kernels/temporal_change.h"
#include "tests/support/raycast.h"

namespace ssdo {
namespace {

constexpr int kWidth = 96, kHeight = 54;

// A floor, a wall behind it and a box standing on the floor at box_x.
raycast::Scene room(float box_x) {
  raycast::Scene s;
  s.planes.push_back({glm::vec3(0.0f), glm::vec3(0, 0, 1), glm::vec3(0.8f)});
  s.planes.push_back({glm::vec3(0, 4, 0), glm::vec3(0, -1, 0), glm::vec3(0.8f)});
  s.boxes.push_back({glm::vec3(box_x, 1.5f, 0.5f), glm::vec3(0.5f), glm::mat3(1.0f), glm::vec3(0.8f)});
  return s;
}

// Looking at the wall from the front and above, the eye moved sideways by eye_x.
Camera room_camera(float eye_x) {
  return raycast::look_at({eye_x, -3.0f, 2.0f}, {eye_x, 2.0f, 0.5f}, {0, 0, 1}, kWidth, kHeight, 60.0f);
}

// A rendered frame with its raw terms: AO-like (one channel) and light-like (RGB).
struct Frame {
  GBuffer g;
  cv::Mat ao, light;
  mutable std::vector<const cv::Mat*> terms;  // set by view(): a copied Frame points to its own
  TemporalFrame view() const {
    terms = {&ao, &light};
    return {g.camera, g.depth_view, g.normal_view, g.mask, terms};
  }
};

// A function of the world point only (what every frame should agree on).
float truth_at(const glm::vec3& p_world) { return 0.5f + 0.3f * std::sin(2.0f * p_world.x) * std::cos(1.5f * p_world.y); }

// Terms = truth + Gaussian noise of sigma_noise (independent per frame: its own seed).
Frame render(const raycast::Scene& scene, const Camera& camera, float sigma_noise, uint64_t seed) {
  Frame f;
  f.g = raycast::render_gbuffer(scene, camera, 1);
  f.ao.create(f.g.depth_view.size(), CV_32FC1);
  f.light.create(f.g.depth_view.size(), CV_32FC3);
  cv::RNG rng(seed);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      float v = 1.0f;
      if (f.g.mask.at<uint8_t>(y, x)) {
        const glm::vec3 p = glm::vec3(camera.view_to_world * glm::vec4(
            camera.view_from_pixel_depth({x + 0.5f, y + 0.5f}, f.g.depth_view.at<float>(y, x)), 1.0f));
        v = truth_at(p) + float(rng.gaussian(sigma_noise));
      }
      f.ao.at<float>(y, x) = v;
      f.light.at<cv::Vec3f>(y, x) = cv::Vec3f(v, 0.5f * v, 2.0f * v);
    }
  return f;
}

std::vector<TemporalFrame> views(const std::vector<Frame>& frames) {
  std::vector<TemporalFrame> v;
  for (const Frame& f : frames) v.push_back(f.view());
  return v;
}

struct Filtered {
  cv::Mat ao, light;
  std::vector<TemporalUse> uses;
};

Filtered filter(const Frame& f, const std::vector<Frame>& neighbours, int nthreads = 0, cv::Rect roi = {},
                const TemporalSettings& s = {}) {
  Filtered out;
  cv::Mat* dsts[] = {&out.ao, &out.light};
  const std::vector<TemporalFrame> n = views(neighbours);
  out.uses = filter_temporal(f.view(), n, s, dsts, roi, nthreads);
  return out;
}

bool same_bits(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int y = 0; y < a.rows; ++y)
    if (std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()) != 0) return false;
  return true;
}

// Mean squared error of the AO-like term against the truth over the foreground.
double mse_against_truth(const Frame& f, const cv::Mat& ao) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      if (!f.g.mask.at<uint8_t>(y, x)) continue;
      const glm::vec3 p = glm::vec3(f.g.camera.view_to_world * glm::vec4(
          f.g.camera.view_from_pixel_depth({x + 0.5f, y + 0.5f}, f.g.depth_view.at<float>(y, x)), 1.0f));
      const double d = ao.at<float>(y, x) - truth_at(p);
      sum += d * d;
      ++n;
    }
  return sum / n;
}

// Channel `channel` of a frame's terms at (x, y): -1 the AO-like term, 0 .. 2 the light-like
// term's.
float term_at(const Frame& f, int channel, int x, int y) {
  return channel < 0 ? f.ao.at<float>(y, x) : f.light.at<cv::Vec3f>(y, x)[channel];
}

// The filter written out (kernels/temporal.h) in double precision with the camera's own
// functions: channel `channel` (term_at) of the frame's terms at (x, y).
double brute_force(const Frame& f, const std::vector<Frame>& neighbours, int x, int y, const TemporalSettings& s,
                   int channel = -1) {
  if (!f.g.mask.at<uint8_t>(y, x)) return term_at(f, channel, x, y);
  const Camera& c = f.g.camera;
  const double d = f.g.depth_view.at<float>(y, x);
  const glm::dvec3 p_world(glm::dmat4(c.view_to_world) *
                           glm::dvec4(c.view_from_pixel_depth({x + 0.5f, y + 0.5f}, float(d)), 1.0));
  const cv::Vec3f nf = f.g.normal_view.at<cv::Vec3f>(y, x);
  const glm::dvec3 n_world(glm::dmat4(c.view_to_world) * glm::dvec4(nf[0], nf[1], nf[2], 0.0));
  double sum = term_at(f, channel, x, y), total = 1.0;
  for (const Frame& u : neighbours) {
    const Camera& cu = u.g.camera;
    const glm::vec2 q = cu.pixel_from_view(glm::vec3(glm::dmat4(cu.world_to_view) * glm::dvec4(p_world, 1.0)));
    const int x0 = int(std::floor(q.x - 0.5)), y0 = int(std::floor(q.y - 0.5));
    const double ax = q.x - 0.5 - x0, ay = q.y - 0.5 - y0;
    for (int ty = y0; ty <= y0 + 1; ++ty)
      for (int tx = x0; tx <= x0 + 1; ++tx) {
        if (tx < 0 || ty < 0 || tx >= kWidth || ty >= kHeight || !u.g.mask.at<uint8_t>(ty, tx)) continue;
        const double bilinear = (tx == x0 ? 1 - ax : ax) * (ty == y0 ? 1 - ay : ay);
        const float du = u.g.depth_view.at<float>(ty, tx);
        const glm::dvec3 q_world(glm::dmat4(cu.view_to_world) *
                                 glm::dvec4(cu.view_from_pixel_depth({tx + 0.5f, ty + 0.5f}, du), 1.0));
        const double w_plane = 1.0 - std::abs(glm::dot(n_world, q_world - p_world)) / (s.depth_tolerance_relative * d);
        const cv::Vec3f nu = u.g.normal_view.at<cv::Vec3f>(ty, tx);
        const double cosine =
            glm::dot(n_world, glm::dvec3(glm::dmat4(cu.view_to_world) * glm::dvec4(nu[0], nu[1], nu[2], 0.0)));
        if (w_plane <= 0 || cosine <= 0) continue;
        const double w = bilinear * w_plane * std::pow(cosine, double(s.normal_power));
        sum += w * term_at(u, channel, tx, ty);
        total += w;
      }
  }
  return sum / total;
}

TEST(Temporal, MatchesTheFilterWrittenOut) {
  const raycast::Scene scene = room(0.0f);
  const Frame f = render(scene, room_camera(0.0f), 0.1f, 1);
  const std::vector<Frame> neighbours = {render(scene, room_camera(-0.15f), 0.1f, 2),
                                         render(room(0.3f), room_camera(0.1f), 0.1f, 3)};  // the box moved
  for (const float power : {16.0f, 2.5f}) {
    TemporalSettings s;
    s.normal_power = power;
    s.reject_changed_surroundings = false;  // the pixel's own surface only (written out here)
    const Filtered out = filter(f, neighbours, 0, {}, s);
    // The AO-like term and each channel of the RGB one (read per texel as one record),
    // whose values are the AO-like term's times 1, 0.5 and 2 (render), and so are the
    // errors of float against double (measured: 7.3e-5 times that factor).
    const Frame filtered{{}, out.ao, out.light, {}};
    for (int channel = -1; channel < 3; ++channel) {
      const double scale = channel < 0 ? 1.0 : std::array{1.0, 0.5, 2.0}[size_t(channel)];
      double worst = 0;
      for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x)
          worst = std::max(worst, std::abs(term_at(filtered, channel, x, y) -
                                           brute_force(f, neighbours, x, y, s, channel)));
      EXPECT_LT(worst, 1e-4 * scale) << power << " channel " << channel;
    }
  }
}

TEST(Temporal, NoNeighboursIsACopy) {
  const Frame f = render(room(0.0f), room_camera(0.0f), 0.1f, 1);
  const Filtered out = filter(f, {});
  EXPECT_TRUE(out.uses.empty());
  EXPECT_TRUE(same_bits(out.ao, f.ao));
  EXPECT_TRUE(same_bits(out.light, f.light));
}

TEST(Temporal, StaticCameraNoiseFalls) {
  // Five frames from one camera with independent noise: the mean of five samples has a
  // fifth of the variance of one.
  const raycast::Scene scene = room(0.0f);
  const Frame f = render(scene, room_camera(0.0f), 0.1f, 1);
  std::vector<Frame> neighbours;
  for (uint64_t seed = 2; seed <= 5; ++seed) neighbours.push_back(render(scene, room_camera(0.0f), 0.1f, seed));
  const Filtered out = filter(f, neighbours);
  for (const TemporalUse& u : out.uses) {
    EXPECT_TRUE(u.used);
    EXPECT_GT(u.overlap, 0.99f);
    EXPECT_LT(u.disagreement, 0.01f);
    EXPECT_EQ(u.changed_px, 0);  // nothing moved
  }
  const double before = mse_against_truth(f, f.ao), after = mse_against_truth(f, out.ao);
  EXPECT_NEAR(before, 0.01, 0.001);
  EXPECT_LT(after, 0.25 * before);
  EXPECT_GT(after, 0.15 * before);  // five samples at most: nothing is blurred in
  // The RGB term gets the same weights.
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x)
      ASSERT_NEAR(out.light.at<cv::Vec3f>(y, x)[2], 2.0f * out.ao.at<float>(y, x), 1e-5f);
}

TEST(Temporal, MovingCameraNoiseFallsAndTruthStays) {
  // The camera trucks 0.1 per frame (a few pixels): the same surfaces, other pixels.
  const raycast::Scene scene = room(0.0f);
  const Frame f = render(scene, room_camera(0.0f), 0.1f, 1);
  std::vector<Frame> neighbours;
  for (int u : {-2, -1, 1, 2}) neighbours.push_back(render(scene, room_camera(0.1f * u), 0.1f, uint64_t(10 + u)));
  const Filtered out = filter(f, neighbours);
  // Nothing moved: the camera's disocclusions are no change of the surroundings.
  const int foreground = cv::countNonZero(f.g.mask);
  for (const TemporalUse& u : out.uses) {
    EXPECT_TRUE(u.used);
    EXPECT_LT(double(u.changed_px), 0.005 * foreground);
  }
  EXPECT_LT(mse_against_truth(f, out.ao), 0.35 * mse_against_truth(f, f.ao));
  // Without noise the filter keeps the truth (bilinear taps of a smooth function).
  const Frame clean = render(scene, room_camera(0.0f), 0.0f, 1);
  std::vector<Frame> clean_neighbours;
  for (int u : {-2, -1, 1, 2}) clean_neighbours.push_back(render(scene, room_camera(0.1f * u), 0.0f, 1));
  EXPECT_LT(mse_against_truth(clean, filter(clean, clean_neighbours).ao), 1e-4);
}

TEST(Temporal, SameBitsForAnyThreadCountAndRoi) {
  const raycast::Scene scene = room(0.0f);
  const Frame f = render(scene, room_camera(0.0f), 0.1f, 1);
  const std::vector<Frame> neighbours = {render(scene, room_camera(-0.2f), 0.1f, 2),
                                         render(room(0.6f), room_camera(0.15f), 0.1f, 3)};  // the box moved
  const Filtered one = filter(f, neighbours, 1), many = filter(f, neighbours, 4);
  EXPECT_EQ(one.uses[0].changed_px, 0);
  EXPECT_GT(one.uses[1].changed_px, 0);
  EXPECT_EQ(one.uses[1].changed_px, many.uses[1].changed_px);
  EXPECT_TRUE(same_bits(one.ao, many.ao));
  EXPECT_TRUE(same_bits(one.light, many.light));
  const cv::Rect roi(10, 7, 40, 20);
  const Filtered part = filter(f, neighbours, 2, roi);
  EXPECT_TRUE(same_bits(part.ao(roi), one.ao(roi)));
  EXPECT_TRUE(same_bits(part.light(roi), one.light(roi)));
}

// Pixels of frame f whose surface point frame u does not see (another surface in front of
// it there, or it moved): by ray casting u's scene from u's eye towards the point.
cv::Mat disagreement_truth(const Frame& f, const raycast::Scene& scene_u, const Camera& camera_u) {
  cv::Mat disagree = cv::Mat::zeros(f.g.mask.size(), CV_8UC1);
  const glm::vec3 eye_u(camera_u.view_to_world[3]);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      if (!f.g.mask.at<uint8_t>(y, x)) continue;
      const glm::vec3 p = glm::vec3(f.g.camera.view_to_world * glm::vec4(
          f.g.camera.view_from_pixel_depth({x + 0.5f, y + 0.5f}, f.g.depth_view.at<float>(y, x)), 1.0f));
      const float distance = glm::length(p - eye_u);
      const raycast::Hit hit = raycast::intersect(scene_u, eye_u, (p - eye_u) / distance);
      if (!(std::abs(hit.t - distance) <= 1e-3f * distance)) disagree.at<uint8_t>(y, x) = 255;
    }
  return disagree;
}

// The pixels of `region` (CV_8UC1) whose 3x3 neighbourhoods, `steps` times over, lie in it.
cv::Mat shrink(const cv::Mat& region, int steps) {
  cv::Mat r = region.clone();
  for (int i = 0; i < steps; ++i) {
    cv::Mat next = cv::Mat::zeros(r.size(), CV_8UC1);
    for (int y = 1; y + 1 < r.rows; ++y)
      for (int x = 1; x + 1 < r.cols; ++x) {
        bool all = true;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) all = all && r.at<uint8_t>(y + dy, x + dx);
        next.at<uint8_t>(y, x) = all ? 255 : 0;
      }
    r = next;
  }
  return r;
}

TEST(Temporal, MovedObjectLeavesNoTrace) {
  // The box moves 0.6 sideways between the frames (the camera too, a little): where the
  // neighbour sees another surface than the frame, the frame's own value stays, bit for bit;
  // where both see the same surface, the neighbour's value is taken in.
  const Camera camera_t = room_camera(0.0f), camera_u = room_camera(0.1f);
  Frame f = render(room(0.0f), camera_t, 0.0f, 1);
  Frame u = render(room(0.6f), camera_u, 0.0f, 1);
  f.ao.setTo(0.2f), f.light.setTo(cv::Scalar::all(0.2f));
  u.ao.setTo(0.9f), u.light.setTo(cv::Scalar::all(0.9f));
  TemporalSettings s;
  s.reject_changed_surroundings = false;  // the pixel's own surface only
  const Filtered out = filter(f, {u}, 0, {}, s);
  ASSERT_TRUE(out.uses[0].used);
  const cv::Mat disagree = disagreement_truth(f, room(0.6f), camera_u);
  // Two pixels in from the edge of the disagreement (the bilinear taps reach one texel).
  const cv::Mat inner_disagree = shrink(disagree, 2), inner_agree = shrink(~disagree & f.g.mask, 2);
  ASSERT_GT(cv::countNonZero(inner_disagree), 100);
  int agreeing = 0;
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      if (inner_disagree.at<uint8_t>(y, x)) {
        ASSERT_EQ(out.ao.at<float>(y, x), 0.2f) << x << "," << y;
        ASSERT_EQ(out.light.at<cv::Vec3f>(y, x)[1], 0.2f) << x << "," << y;
      }
      if (inner_agree.at<uint8_t>(y, x)) agreeing += out.ao.at<float>(y, x) > 0.4f;
    }
  EXPECT_GT(agreeing, 0.95 * cv::countNonZero(inner_agree));
}

TEST(Temporal, CameraCutIsNotUsed) {
  // The neighbour looks at the scene from the other side: almost nothing agrees.
  const raycast::Scene scene = room(0.0f);
  const Frame f = render(scene, room_camera(0.0f), 0.1f, 1);
  const Camera other = raycast::look_at({3.0f, 6.0f, 1.0f}, {0, 0, 0.5f}, {0, 0, 1}, kWidth, kHeight, 60.0f);
  const Filtered out = filter(f, {render(scene, other, 0.1f, 2)});
  EXPECT_FALSE(out.uses[0].used);
  EXPECT_TRUE(same_bits(out.ao, f.ao));
  EXPECT_TRUE(same_bits(out.light, f.light));
}

TEST(Temporal, ValidateNamesTheField) {
  TemporalSettings s;
  EXPECT_EQ(validate(s), "");
  s.depth_tolerance_relative = 0.0f;
  EXPECT_NE(validate(s).find("depth_tolerance_relative"), std::string::npos);
  s = {};
  s.max_disagreement = 2.0f;
  EXPECT_NE(validate(s).find("max_disagreement"), std::string::npos);
  s = {};
  s.radius_world = 0.0f;
  EXPECT_NE(validate(s).find("radius_world"), std::string::npos);
  s = {};
  s.max_radius_px = 1.0f;
  EXPECT_NE(validate(s).find("max_radius_px"), std::string::npos);
}


// ---- A moving object's contact shadow: the surroundings of a pixel changed ----

// A floor and a 0.6 cube standing on it at x = box_x.
raycast::Scene floor_with_box(float box_x) {
  raycast::Scene s;
  s.planes.push_back({glm::vec3(0.0f), glm::vec3(0, 0, 1), glm::vec3(0.8f)});
  s.boxes.push_back({glm::vec3(box_x, 0.0f, 0.3f), glm::vec3(0.3f), glm::mat3(1.0f), glm::vec3(0.8f)});
  return s;
}
// A fixed camera looking down at the floor from the front, the box's three places in view.
Camera floor_camera(int width_px = 128, int height_px = 72) {
  return raycast::look_at({0.0f, -3.5f, 3.0f}, {0.0f, 0.0f, 0.0f}, {0, 0, 1}, width_px, height_px, 70.0f);
}

constexpr float kShadowRadiusWorld = 0.5f;  // the AO radius of the shot's terms

// A frame of the shot with the box at box_x: its exact AO within kShadowRadiusWorld (the
// ray caster's, 256 directions, the same pattern in every frame) and its raw term, that AO
// plus Gaussian noise of sigma_noise (the frame's own seed). light: 1 (unused).
struct ShadowFrame {
  Frame frame;
  cv::Mat exact;
};
ShadowFrame shadow_frame(float box_x, float sigma_noise, uint64_t seed) {
  ShadowFrame f;
  const raycast::Scene scene = floor_with_box(box_x);
  f.frame.g = raycast::render_gbuffer(scene, floor_camera(), 1);
  f.exact = raycast::reference_ao(scene, f.frame.g, kShadowRadiusWorld, 256, 7, 1);
  f.frame.ao = f.exact.clone();
  cv::RNG rng(seed);
  for (int y = 0; y < f.exact.rows; ++y)
    for (int x = 0; x < f.exact.cols; ++x)
      if (f.frame.g.mask.at<uint8_t>(y, x)) f.frame.ao.at<float>(y, x) += float(rng.gaussian(sigma_noise));
  f.frame.light = cv::Mat(f.exact.size(), CV_32FC3, cv::Scalar::all(1.0f));
  return f;
}

// Whether pixel (x, y) of frame f sees the floor (not the box) at a world point farther than
// `distance` from every box footprint of `box_xs` (the footprint: |x - box_x| <= 0.3, |y| <= 0.3).
bool floor_farther_than(const Frame& f, int x, int y, std::span<const float> box_xs, float distance) {
  if (!f.g.mask.at<uint8_t>(y, x)) return false;
  const Camera& c = f.g.camera;
  const glm::vec3 p = glm::vec3(c.view_to_world * glm::vec4(c.view_from_pixel_depth({x + 0.5f, y + 0.5f},
                                                                                     f.g.depth_view.at<float>(y, x)), 1.0f));
  if (p.z > 1e-3f) return false;  // on the box
  for (const float bx : box_xs) {
    const float dx = std::max(std::abs(p.x - bx) - 0.3f, 0.0f), dy = std::max(std::abs(p.y) - 0.3f, 0.0f);
    if (dx * dx + dy * dy <= distance * distance) return false;
  }
  return true;
}

TEST(Temporal, MovedObjectLeavesNoContactShadow) {
  // The box moves 1.0 (more than its size) per frame under a fixed camera. Frame t's floor
  // where a neighbour's box darkened it (or t's box darkens it and the neighbours' did not)
  // is the same surface in both frames, so the tangent-plane test takes the neighbours'
  // values: averaged, a ghost of the contact shadow trails the box. The filter must keep
  // t's own term there, and still average the floor far from every position of the box.
  const float box_xs[] = {-1.0f, 0.0f, 1.0f};
  const float sigma = 0.03f;
  const ShadowFrame t = shadow_frame(box_xs[1], sigma, 1);
  const std::vector<ShadowFrame> around = {shadow_frame(box_xs[0], sigma, 2), shadow_frame(box_xs[2], sigma, 3)};
  TemporalSettings s;
  s.radius_world = kShadowRadiusWorld;
  const Filtered out = filter(t.frame, {around[0].frame, around[1].frame}, 0, {}, s);
  ASSERT_TRUE(out.uses[0].used && out.uses[1].used);
  // The ghost: what a mean over the frames that see the same floor there would add to t's
  // exact AO. Its size, and the filtered error along it (positive: the ghost is there).
  double ghost_sum = 0, along_sum = 0;
  int ghost_px = 0;
  // Far floor: the noise falls as it does for an average of three.
  double raw_error = 0, filtered_error = 0;
  int far_px = 0, far_averaged = 0;
  for (int y = 0; y < t.exact.rows; ++y)
    for (int x = 0; x < t.exact.cols; ++x) {
      if (floor_farther_than(t.frame, x, y, box_xs, 2.0f * kShadowRadiusWorld)) {
        const double e0 = t.frame.ao.at<float>(y, x) - t.exact.at<float>(y, x);
        const double e1 = out.ao.at<float>(y, x) - t.exact.at<float>(y, x);
        raw_error += e0 * e0, filtered_error += e1 * e1, ++far_px;
        far_averaged += out.ao.at<float>(y, x) != t.frame.ao.at<float>(y, x);
      }
      if (!floor_farther_than(t.frame, x, y, box_xs, 0.0f)) continue;  // t's floor only
      double sum = t.exact.at<float>(y, x);
      int n = 1;
      for (const ShadowFrame& u : around)
        if (floor_farther_than(u.frame, x, y, box_xs, 0.0f)) sum += u.exact.at<float>(y, x), ++n;
      const double ghost = sum / n - t.exact.at<float>(y, x);
      if (std::abs(ghost) < 0.02) continue;
      ghost_sum += std::abs(ghost);
      along_sum += (out.ao.at<float>(y, x) - t.exact.at<float>(y, x)) * (ghost > 0 ? 1.0 : -1.0);
      ++ghost_px;
    }
  ASSERT_GT(ghost_px, 100);
  const double ghost_size = ghost_sum / ghost_px, along = along_sum / ghost_px;
  EXPECT_GT(ghost_size, 0.04);
  EXPECT_LT(std::abs(along), 0.1 * ghost_size) << "ghost " << ghost_size << ", " << ghost_px << " px";
  // The test of the surroundings bounds them in pixels (kernels/temporal_change.h): the
  // floor behind a box, farther from the eye, lies within a few pixels of the box's top,
  // and a few percent of the far floor keep their own term.
  ASSERT_GT(far_px, 1000);
  EXPECT_GT(far_averaged, 0.95 * far_px);
  EXPECT_LT(filtered_error, 0.45 * raw_error) << far_px << " px";
  std::printf("ghost %.4f over %d px, filtered error along it %.4f; far floor %d px (%d averaged), MSE %.5f -> %.5f\n",
              ghost_size, ghost_px, along, far_px, far_averaged, raw_error / far_px, filtered_error / far_px);
}


TEST(Temporal, ChangedSurroundingsAtAnySize) {
  // The box moves by 1.0 between the frames; the frame's terms are 0.2, the neighbour's 0.9.
  // At any size (the search's lattice is coarser on wider frames), the floor near the box's
  // place in either frame keeps the frame's own value, bit for bit, and the floor far from
  // both takes the neighbour's. The same bits for 1 and 4 threads.
  const float box_xs[] = {0.0f, 1.0f};
  for (const int width : {128, 1000}) {
    const int height = width * 9 / 16;
    Frame f, u;
    f.g = raycast::render_gbuffer(floor_with_box(box_xs[0]), floor_camera(width, height), 2);
    u.g = raycast::render_gbuffer(floor_with_box(box_xs[1]), floor_camera(width, height), 2);
    for (Frame* frame : {&f, &u}) {
      const float v = frame == &f ? 0.2f : 0.9f;
      frame->ao = cv::Mat(frame->g.depth_view.size(), CV_32FC1, cv::Scalar::all(v));
      frame->light = cv::Mat(frame->g.depth_view.size(), CV_32FC3, cv::Scalar::all(v));
    }
    TemporalSettings s;
    s.radius_world = kShadowRadiusWorld;
    const Filtered out = filter(f, {u}, 4, {}, s);
    ASSERT_TRUE(out.uses[0].used);
    const Filtered serial = filter(f, {u}, 1, {}, s);
    EXPECT_TRUE(same_bits(serial.ao, out.ao)) << width;
    EXPECT_EQ(serial.uses[0].changed_px, out.uses[0].changed_px) << width;
    int near_px = 0, near_kept = 0, far_px = 0, far_averaged = 0;
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) {
        if (!floor_farther_than(f, x, y, box_xs, 0.0f) || !floor_farther_than(u, x, y, box_xs, 0.0f)) continue;
        const float v = out.ao.at<float>(y, x);
        if (!floor_farther_than(f, x, y, box_xs, kShadowRadiusWorld)) near_px++, near_kept += v == 0.2f;
        if (floor_farther_than(f, x, y, box_xs, 3.0f * kShadowRadiusWorld)) far_px++, far_averaged += v > 0.4f;
      }
    ASSERT_GT(near_px, 100) << width;
    EXPECT_EQ(near_kept, near_px) << width;
    EXPECT_GT(far_averaged, 0.95 * far_px) << width;
    std::printf("%d px wide: %lld changed, near %d/%d kept, far %d/%d averaged\n", width,
                static_cast<long long>(out.uses[0].changed_px), near_kept, near_px, far_averaged, far_px);
  }
}


// The changed pixels as a mask at the frame's size where the box moved, and nothing at all
// (no image) where the scene stood still.
TEST(Temporal, ChangedSurroundingsAreAMaskOnlyWhereSomethingChanged) {
  auto frame = [](float box_x) {
    Frame f;
    f.g = raycast::render_gbuffer(floor_with_box(box_x), floor_camera(), 1);
    f.ao = cv::Mat(f.g.depth_view.size(), CV_32FC1, cv::Scalar::all(0.5f));
    f.light = cv::Mat(f.g.depth_view.size(), CV_32FC3, cv::Scalar::all(0.5f));
    return f;
  };
  const Frame f = frame(0.0f), still = frame(0.0f), moved = frame(1.0f);
  TemporalSettings s;
  s.radius_world = kShadowRadiusWorld;
  int64_t changed_px = -1;
  const cv::Mat none = changed_surroundings(f.view(), still.view(), s, changed_px);
  EXPECT_TRUE(none.empty());
  EXPECT_EQ(changed_px, 0);
  const cv::Mat some = changed_surroundings(f.view(), moved.view(), s, changed_px);
  ASSERT_EQ(some.size(), f.g.depth_view.size());
  ASSERT_EQ(some.type(), CV_8UC1);
  EXPECT_GT(changed_px, 100);
  EXPECT_EQ(cv::countNonZero(some), changed_px);
  EXPECT_EQ(cv::countNonZero(some & ~f.g.mask), 0);  // foreground pixels only
}
}  // namespace
}  // namespace ssdo
