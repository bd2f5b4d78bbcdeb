// Squared Euclidean distance transforms of sampled functions: the lower envelope of the
// parabolas rooted at the samples (Felzenszwalb & Huttenlocher 2012, "Distance Transforms of
// Sampled Functions", algorithm DT(f)), along one line; separable over an image (a pass
// along its columns, then one along its rows over the columns' results). The temporal
// filter's distances to its marks and the thickness estimate's nearest silhouette take it.
#pragma once

#include <cstddef>
#include <vector>

namespace ssdo {

// Scratch of lower_envelope for lines of up to n samples.
struct EnvelopeScratch {
  std::vector<int> v;
  std::vector<double> z;
  explicit EnvelopeScratch(int n) : v(std::size_t(n)), z(std::size_t(n) + 1) {}
};

// d[q] = min over p with finite f[p] of f[p] + (q - p)^2, q in [0, n) (+inf when no f[p] is
// finite); `nearest` (may be null) receives the p attaining it (-1 when none).
void lower_envelope(const float* f, int n, float* d, int* nearest, EnvelopeScratch& scratch);

}  // namespace ssdo
