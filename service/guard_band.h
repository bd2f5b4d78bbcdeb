// Frames rendered with overscan (a guard band): the renderer drew `px` extra pixels on each
// side of the picture, so that the screen-space taps of pixels near the borders find the
// occluders just outside it instead of nothing. The terms are computed on the whole frame
// and cropped to the inner picture before they are written.
#pragma once

#include <string>

#include "core/camera.h"
#include "service/pipeline.h"

namespace ssdo {

// Crops `px` pixels off each side of every term of `frame` and re-targets `camera` to the
// inner grid (same rays per pixel: the projection of the picture without overscan). px = 0
// leaves both untouched. Returns an error when the frame is not wider and taller than 2 px.
std::string crop_guard_band(ComputedFrame& frame, Camera& camera, int px);

}  // namespace ssdo
