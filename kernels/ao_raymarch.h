// The raymarch AO oracle with its confidence output (compute_ao() with
// AoMethod::raymarch runs the same core without it).
#pragma once

#include <opencv2/core.hpp>

#include "kernels/ao.h"

namespace ssdo {

// As compute_ao(in, s, out, roi, nthreads) for s.method == AoMethod::raymarch, and also
// writes `confidence` (CV_32FC1, allocated at the input size when empty; only roi is
// written; 1 on background): the fraction of the pixel's directions whose verdict rests on
// on-screen foreground samples only, i.e. rays that were blocked, or that stayed open
// without any step landing off-screen, behind the eye or on a masked pixel (such steps
// never occlude: what lies there is unknown to the frame).
void compute_ao_raymarch(const AoInputs& in, const AoSettings& s, AoOutput& out,
                         cv::Mat& confidence, cv::Rect roi = {}, int nthreads = 0);

}  // namespace ssdo
