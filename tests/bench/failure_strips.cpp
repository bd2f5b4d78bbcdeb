// Image strips of the failure-case suite (tests/accuracy/failure_cases.h) for the
// docs/accuracy.md's "Where screen space fails": one PNG per case, tiles left to right
//   input (view-facing shading of the input normals; masked pixels black) | reference |
//   hemisphere high | hbao high | gtao high | raymarch low | raymarch low + back-face
//   depth | |gtao high - reference| x 2 | confidence
// The pan shows its last frame (the box has left the view).
//
//   failure_strips OUT_DIR     (writes OUT_DIR/<case>.png; the repository keeps them in
//                               examples/failure_cases/)
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "formats/output_writer.h"
#include "tests/accuracy/failure_cases.h"

namespace fs = std::filesystem;
using namespace ssdo;
using namespace ssdo::failure;

namespace {

// Grey tile (CV_32FC3) from a CV_32FC1 image, scaled.
cv::Mat grey(const cv::Mat& v, float scale = 1.0f) {
  cv::Mat s = v * scale, out;
  cv::Mat channels[] = {s, s, s};
  cv::merge(channels, 3, out);
  return out;
}

cv::Mat shaded_input(const GBuffer& g) {
  cv::Mat out(g.depth_view.size(), CV_32FC1, cv::Scalar(0));
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      if (!g.mask.at<uint8_t>(y, x)) continue;
      const cv::Vec3f n = g.normal_view.at<cv::Vec3f>(y, x);
      const glm::vec3 ray =
          g.camera.view_ray_direction({float(x) + 0.5f, float(y) + 0.5f});
      out.at<float>(y, x) = 0.1f + 0.9f * std::max(0.0f, -(n[0] * ray.x + n[1] * ray.y + n[2] * ray.z));
    }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: failure_strips OUT_DIR\n");
    return 2;
  }
  const fs::path out_dir = argv[1];
  fs::create_directories(out_dir);
  const fs::path tmp = fs::temp_directory_path() / ("failure_strips_" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  for (const std::string& name : case_names()) {
    const Case c = build_case(name);
    const Frame& f = c.frames.back();
    std::vector<cv::Mat> tiles;
    tiles.push_back(grey(shaded_input(f.input)));
    tiles.push_back(grey(f.reference));
    cv::Mat gtao;
    for (AoMethod m : {AoMethod::hemisphere, AoMethod::hbao, AoMethod::gtao}) {
      const cv::Mat ao = run(f, settings_of({m, Preset::high}));
      if (m == AoMethod::gtao) gtao = ao;
      tiles.push_back(grey(ao));
    }
    const AoSettings rm = settings_of({AoMethod::raymarch, Preset::low});
    tiles.push_back(grey(run(f, rm, false)));
    tiles.push_back(grey(run(f, rm, true)));
    cv::Mat err;
    cv::absdiff(gtao, f.reference, err);
    err.setTo(0, f.eval_mask == 0);
    tiles.push_back(grey(err, 2.0f));
    tiles.push_back(grey(confidence_of(f, settings_of({AoMethod::gtao, Preset::high}))));
    // 2-pixel black gaps between tiles.
    std::vector<cv::Mat> row;
    for (size_t k = 0; k < tiles.size(); ++k) {
      if (k) row.push_back(cv::Mat(kHeight, 2, CV_32FC3, cv::Scalar(0, 0, 0)));
      row.push_back(tiles[k]);
    }
    cv::Mat strip;
    cv::hconcat(row, strip);
    Camera cam;  // no camera attributes: the strip is not a frame
    WriteOptions options;
    options.png_previews = true;
    const std::string err_msg =
        write_outputs((tmp / (name + ".exr")).string(), {{"strip", strip, SampleType::half, false}},
                      cam, options);
    if (!err_msg.empty()) {
      std::fprintf(stderr, "%s\n", err_msg.c_str());
      return 1;
    }
    fs::copy_file(tmp / (name + ".strip.png"), out_dir / (name + ".png"),
                  fs::copy_options::overwrite_existing);
    std::printf("%s\n", (out_dir / (name + ".png")).string().c_str());
  }
  fs::remove_all(tmp);
  return 0;
}
