#include "service/guard_band.h"

#include "formats/camera_io.h"

namespace ssdo {

std::string crop_guard_band(ComputedFrame& frame, Camera& camera, int px) {
  if (px <= 0) return {};
  const int width = camera.width_px, height = camera.height_px;
  if (width <= 2 * px || height <= 2 * px)
    return "--guard-band " + std::to_string(px) + " leaves nothing of a " + std::to_string(width) + "x" +
           std::to_string(height) + " frame";
  const cv::Rect inner(px, px, width - 2 * px, height - 2 * px);
  for (OutputTerm& term : frame.terms) term.image = term.image(inner).clone();
  // The whole grid plays the display window, the inner picture the data window.
  const PixelBox whole{0, 0, width - 1, height - 1};
  const PixelBox picture{px, px, width - 1 - px, height - 1 - px};
  camera.view_to_clip = projection_for_data_window(camera.view_to_clip, whole, picture);
  camera.width_px = inner.width;
  camera.height_px = inner.height;
  return {};
}

}  // namespace ssdo
