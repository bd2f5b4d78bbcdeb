// Classic hemisphere SSAO against closed forms. It estimates the fraction of sample points
// inside geometry, bounded by the screen (samples projecting off screen count as open), so
// it is the loose baseline: open planes exact; corner line within 0.12 at radius 1 (points
// nearer than the wall never occlude and some samples leave the screen: 0.58-0.61); the sphere within 0.1 (volume, not rays: under-occluded).
#include "tests/unit/kernels/ao_closed_forms.h"

namespace ssdo::ao_test {
namespace {

TEST(AoHemisphere, Invariants) {
  check_invariants(AoMethod::hemisphere, Preset::high);
}

TEST(AoHemisphere, NoBentNormal) {
  const Frame f = render(raycast::corner_scene(), raycast::corner_camera(64, 36));
  AoOutput out;
  out.bent_normal_view = cv::Mat(f.g.depth_view.size(), CV_32FC3);
  compute_ao_at_resolution(f.inputs(), ao_preset(AoMethod::hemisphere, Preset::low), out);
  EXPECT_TRUE(out.bent_normal_view.empty());
}

TEST(AoHemisphere, CornerLineIsHalf) {
  const Frame f = render(raycast::corner_scene(), raycast::corner_camera(160, 90));
  for (Preset p : {Preset::high, Preset::ultra}) {
    AoSettings s = ao_preset(AoMethod::hemisphere, p);
    s.radius_world = 1.0f;  // mostly on screen: the camera is 2.5 from the corner
    const double ao = mean_at(run(f, s).ao, corner_line_pixels(f));
    std::printf("hemisphere %s corner (radius 1) %.4f (exact 0.5)\n", to_string(p).data(), ao);
    EXPECT_NEAR(ao, 0.5, 0.12) << to_string(p);
  }
}

TEST(AoHemisphere, SphereOverPlane) {
  for (Preset p : {Preset::high, Preset::ultra}) {
    const double ao = sphere_ao(ao_preset(AoMethod::hemisphere, p), std::numeric_limits<float>::infinity());
    std::printf("hemisphere %s sphere %.4f (exact %.4f)\n", to_string(p).data(), ao, kSphereExact);
    EXPECT_NEAR(ao, kSphereExact, 0.1) << to_string(p);
  }
}

TEST(AoHemisphere, OpenPlanesAreUnoccludedAtAnyAngle) {
  for (Preset p : {Preset::low, Preset::high})
    EXPECT_LE(open_plane_worst(ao_preset(AoMethod::hemisphere, p)), 1e-6) << to_string(p);
}

}  // namespace
}  // namespace ssdo::ao_test
