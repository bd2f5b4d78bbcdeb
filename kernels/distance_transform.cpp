#include "kernels/distance_transform.h"

#include <algorithm>
#include <limits>

namespace ssdo {

void lower_envelope(const float* f, int n, float* d, int* nearest, EnvelopeScratch& scratch) {
  constexpr double kInfD = std::numeric_limits<double>::infinity();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  std::vector<int>& v = scratch.v;
  std::vector<double>& z = scratch.z;
  int k = -1;
  auto rooted = [&](int p) { return double(f[p]) + double(p) * double(p); };
  for (int q = 0; q < n; ++q) {
    if (!(f[q] < kInf)) continue;
    if (k < 0) {
      k = 0, v[0] = q, z[0] = -kInfD, z[1] = kInfD;
      continue;
    }
    // Where q's parabola meets the envelope's last one; those it passes under are dropped.
    double s = (rooted(q) - rooted(v[size_t(k)])) / (2.0 * double(q - v[size_t(k)]));
    while (s <= z[size_t(k)]) --k, s = (rooted(q) - rooted(v[size_t(k)])) / (2.0 * double(q - v[size_t(k)]));
    ++k, v[size_t(k)] = q, z[size_t(k)] = s, z[size_t(k) + 1] = kInfD;
  }
  if (k < 0) {
    std::fill(d, d + n, kInf);
    if (nearest) std::fill(nearest, nearest + n, -1);
    return;
  }
  k = 0;
  for (int q = 0; q < n; ++q) {
    while (z[size_t(k) + 1] < double(q)) ++k;
    const int p = v[size_t(k)];
    d[q] = float(double(q - p) * double(q - p) + double(f[p]));
    if (nearest) nearest[q] = p;
  }
}

}  // namespace ssdo
