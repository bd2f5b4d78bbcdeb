// A frame's geometry and shading inputs in the kernels' internal conventions.
// formats/ fills it (converting spaces and depth conventions once); kernels read it.
//
// Every image is a cv::Mat of the data window's size (height_px rows x width_px cols),
// float32, row 0 = top scanline. Three-channel images store (x, y, z) or (R, G, B) in
// that order (never OpenCV's BGR).
#pragma once

#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera.h"

namespace ssdo {

// Another camera's depth of the same scene: a neighbouring frame of a shot (or any other
// view with a known camera). The kernels treat it as an extra view of what this frame hides
// (kernels/multiview.h): space it sees in front of its surfaces is free, space just behind
// them is occupied.
struct DepthView {
  Camera camera;       // its own projection, grid and world_to_view (the same world as the frame's)
  cv::Mat depth_view;  // CV_32FC1 planar depth in its camera, +infinity on background
  std::string name;    // where it came from (a file), for notes
  // CV_32FC3 at depth_view's size, or empty: the view's albedo and diffuse lighting (as
  // GBuffer::albedo and GBuffer::lighting), the light of the senders it shows past this
  // frame's edges (kernels/multiview.h, the guard band). Empty: depth only.
  cv::Mat albedo = {}, lighting = {};
};

struct GBuffer {
  Camera camera;

  // CV_32FC1. Planar view-space depth (= -z_view), scene units, > 0 on foreground.
  // Background and invalid pixels hold +infinity: test `mask` before doing arithmetic
  // with a tap's depth.
  cv::Mat depth_view;

  // CV_8UC1. 255 = foreground geometry, 0 = background, non-finite or otherwise unusable.
  cv::Mat mask;

  // CV_32FC3. Unit view-space normals (x, y, z), facing the camera side of the surface.
  // (0, 0, 0) where mask is 0. The reader leaves it empty when the frame has none, and
  // (0, 0, 0) where normal_missing is set; service/frame_inputs.h rebuilds both from depth
  // before any kernel reads them.
  cv::Mat normal_view;

  // CV_8UC1, empty when every foreground pixel has a usable normal. 1 on the foreground
  // pixels whose stored normal is unusable ((0, 0, 0): a renderer's "no normal").
  cv::Mat normal_missing;

  // CV_32FC1, optional (empty when absent). A second depth layer: planar depth of the
  // nearest back face on each pixel's ray (a back-face pass, or the second sample of a
  // deep EXR), scene units, >= depth_view; +infinity where the surface has no far side
  // within the frame (a floor, a wall) or on background. Between depth_view and
  // depth_back_view a ray is inside the object (depth peeling as in the SSDO paper).
  cv::Mat depth_back_view;

  // CV_32FC3, optional (empty when absent). View-space positions (x, y, z).
  cv::Mat position_view;

  // CV_32FC3, optional. Linear diffuse albedo (R, G, B) in [0, 1].
  cv::Mat albedo;

  // CV_32FC3, optional. Outgoing diffuse radiance of each pixel from the renderer's own
  // direct lighting (R, G, B): the sender light of the SSDO bounce.
  cv::Mat lighting;

  // Named reference images from the frame (e.g. "AO": CV_32FC1 ray-traced ambient
  // occlusion; "DiffDir", "DiffInd": CV_32FC3 light passes). Same size as depth.
  std::map<std::string, cv::Mat> references;

  // Extra views of the scene (neighbouring frames), empty for a frame computed alone. The
  // service fills them (a shot's sequence context); formats/ never does.
  std::vector<DepthView> views;

  // Where the images' pixel (0, 0) lies in the picture's pixel space: the EXR data window's
  // origin (a crop's offset in its display window; negative with overscan). The terms'
  // per-pixel noise is keyed to the picture's pixels, so a crop of a frame gets the same
  // noise as the whole frame, and the same terms wherever its taps stay inside it.
  cv::Point data_origin_px{0, 0};

  int width_px() const { return depth_view.cols; }
  int height_px() const { return depth_view.rows; }
  bool has_normals() const { return !normal_view.empty(); }
  bool has_albedo() const { return !albedo.empty(); }
};

}  // namespace ssdo
