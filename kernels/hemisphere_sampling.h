// Cosine-weighted hemisphere sampling shared by the reference ray caster
// (tests/support/raycast.cpp) and the raymarch AO oracle (ao_raymarch.cpp), so the two
// estimate the same integral with the same directions; SSDO's sample frames use the same
// orthonormal basis. Header-only: the per-sample loops see through every call.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

#include <glm/glm.hpp>

namespace ssdo::sampling {

// Orthonormal basis (t, b, n) around unit n (Duff et al. 2017, "Building an Orthonormal
// Basis, Revisited", JCGT 6(1), listing 3): continuous except across n.z = 0's sign flip,
// no normalisation needed.
inline void orthonormal_basis(const glm::vec3& n, glm::vec3& t, glm::vec3& b) {
  const float sign = std::copysign(1.0f, n.z);
  const float a = -1.0f / (sign + n.z);
  const float c = n.x * n.y * a;
  t = glm::vec3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
  b = glm::vec3(c, sign + n.y * n.y * a, -n.y);
}

// Cosine-weighted direction in the local frame (z = normal) from a point (u, v) of
// [0,1)^2: Shirley & Chiu's concentric square-to-disk map (1997, "A Low Distortion Map
// Between Disk and Square"), which keeps a low-discrepancy sequence's stratification,
// lifted to the hemisphere by Malley's method: pdf(w) = cos(theta) / pi, so the mean of
// f(w) over the samples estimates (1/pi) \int_H f(w) cos(theta) dw.
inline glm::vec3 cosine_hemisphere_local(float u, float v) {
  constexpr float kQuarterPi = std::numbers::pi_v<float> / 4.0f;
  constexpr float kHalfPi = std::numbers::pi_v<float> / 2.0f;
  const float a = 2.0f * u - 1.0f, b = 2.0f * v - 1.0f;
  float r = 0.0f, phi = 0.0f;
  if (a == 0.0f && b == 0.0f) {
    r = 0.0f;
  } else if (std::abs(a) > std::abs(b)) {
    r = a;
    phi = kQuarterPi * (b / a);
  } else {
    r = b;
    phi = kHalfPi - kQuarterPi * (a / b);
  }
  const float x = r * std::cos(phi), y = r * std::sin(phi);
  return {x, y, std::sqrt(std::max(0.0f, 1.0f - x * x - y * y))};
}

// The same direction in the frame (t, b, n), unit length.
inline glm::vec3 cosine_hemisphere(const glm::vec3& n, const glm::vec3& t, const glm::vec3& b,
                                   float u, float v) {
  const glm::vec3 l = cosine_hemisphere_local(u, v);
  return glm::normalize(l.x * t + l.y * b + l.z * n);
}

}  // namespace ssdo::sampling
