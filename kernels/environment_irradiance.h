// The irradiance table of an environment (kernels/environment.h, irradiance_over_pi): the
// cosine-convolved radiance on a lat-long of normals, by quadrature over the radiance
// box-averaged to the same lat-long. Its own file so that its loop is compiled once per
// instruction set (core/simd.h): 70 million multiply-adds for a 128 x 64 table.
#pragma once

#include <opencv2/core.hpp>

namespace ssdo {

// E(n) / pi at the centre normals of a lat-long table of source's size (CV_32FC3 radiance,
// equirect layout of kernels/environment.h, any aspect; at most a few hundred texels high):
//   E(n) / pi = sum_t w_t L_t / sum_t w_t,  w_t = Omega_t max(0, n . d_t)
// over the source's texels t (centre direction d_t, solid angle Omega_t). The weights'
// exact sum is pi, so the normalisation only removes the quadrature's error and a constant
// environment gives its radiance exactly. The same bits on every instruction set.
cv::Mat irradiance_table(const cv::Mat& source, int nthreads = 0);

}  // namespace ssdo
