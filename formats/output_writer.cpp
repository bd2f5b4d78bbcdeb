#include "formats/output_writer.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <optional>
#include <random>
#include <set>
#include <sstream>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfThreading.h>
#include <Imath/half.h>
#include <OpenImageIO/imageio.h>

#include "formats/camera_io.h"
#include "kernels/parallel.h"

namespace ssdo {

std::string temp_file_host() {
  char name[256] = {};
  if (::gethostname(name, sizeof name - 1) != 0 || name[0] == '\0') return "localhost";
  std::string host(name);
  // Only characters that cannot be confused with the name's separators.
  for (char& c : host)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_') c = '_';
  return host;
}

namespace {

namespace fs = std::filesystem;

// Header attribute names of the clip distances (OpenEXR has no standard one); read back by
// read_gbuffer.
constexpr const char* kClipNearAttribute = "clipNear";
constexpr const char* kClipFarAttribute = "clipFar";

std::optional<Imf::Compression> parse_compression(const std::string& name) {
  if (name == "none") return Imf::NO_COMPRESSION;
  if (name == "zip") return Imf::ZIP_COMPRESSION;
  if (name == "zips") return Imf::ZIPS_COMPRESSION;
  if (name == "piz") return Imf::PIZ_COMPRESSION;
  if (name == "rle") return Imf::RLE_COMPRESSION;
  if (name == "dwaa") return Imf::DWAA_COMPRESSION;
  return std::nullopt;
}

std::vector<std::string> channel_names(const OutputTerm& t) {
  if (t.image.channels() == 1) return {t.name};
  if (t.vector) return {t.name + ".X", t.name + ".Y", t.name + ".Z"};
  return {t.name + ".R", t.name + ".G", t.name + ".B"};
}

// ".NAME.tmp-<host>-<pid>-<random>" beside the final file: same file system, so rename()
// is atomic, and hidden, so watchers of the folder skip it. The host name lets a task on a
// render farm that shares the output folder tell its own host's abandoned temp files
// (dead pid) from another host's files in progress (service/frame_list.h).
fs::path temp_path_for(const fs::path& final_path) {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  std::ostringstream s;
  s << "." << final_path.filename().string() << ".tmp-" << temp_file_host() << "-" << ::getpid()
    << "-" << std::hex << rng();
  return final_path.parent_path() / s.str();
}

// Moves a finished temp file into place; removes it on failure.
std::string commit(const fs::path& temp, const fs::path& final_path) {
  std::error_code ec;
  fs::rename(temp, final_path, ec);
  if (ec) {
    fs::remove(temp, ec);
    return final_path.string() + ": cannot rename the temp file into place: " + ec.message();
  }
  return {};
}

Imath::M44f to_imath(const glm::mat4& m) {
  // Same 16 floats in memory order: glm column-vector form == Imath row-vector form.
  Imath::M44f r;
  std::copy(&m[0][0], &m[0][0] + 16, &r.x[0][0]);
  return r;
}

// sRGB encoding (IEC 61966-2-1) of a linear value clamped to [0, 1].
uint8_t srgb8(float v) {
  if (!std::isfinite(v)) v = 0.0f;
  v = std::clamp(v, 0.0f, 1.0f);
  const float e = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
  return uint8_t(std::lround(e * 255.0f));
}

// Vector terms (unit directions) are shown as 0.5 v + 0.5, linear, the usual normal-map
// colouring: sRGB encoding would bend the mapping of directions to colours.
uint8_t vector8(float v) {
  if (!std::isfinite(v)) v = 0.0f;
  return uint8_t(std::lround(std::clamp(0.5f * v + 0.5f, 0.0f, 1.0f) * 255.0f));
}

std::string write_png(const fs::path& final_path, const OutputTerm& t) {
  const int w = t.image.cols, h = t.image.rows, nc = t.image.channels();
  std::vector<uint8_t> pixels(size_t(w) * h * nc);
  for (int y = 0; y < h; ++y) {
    const float* row = t.image.ptr<float>(y);
    for (int i = 0; i < w * nc; ++i)
      pixels[size_t(y) * w * nc + i] = t.vector ? vector8(row[i]) : srgb8(row[i]);
  }
  const fs::path temp = temp_path_for(final_path);
  auto out = OIIO::ImageOutput::create("png");
  if (!out) return final_path.string() + ": no PNG writer: " + OIIO::geterror();
  OIIO::ImageSpec spec(w, h, nc, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", t.vector ? "Linear" : "sRGB");
  bool ok = out->open(temp.string(), spec) &&
            out->write_image(OIIO::TypeDesc::UINT8, pixels.data());
  ok = out->close() && ok;
  if (!ok) {
    const std::string message = out->geterror();
    std::error_code ec;
    fs::remove(temp, ec);
    return final_path.string() + ": cannot write PNG preview: " + message;
  }
  return commit(temp, final_path);
}

std::string write_outputs_unguarded(const std::string& path, const std::vector<OutputTerm>& terms,
                                    const Camera& camera, const WriteOptions& options) {
  const fs::path final_path(path);
  if (terms.empty()) return path + ": no output terms to write";
  const auto compression = parse_compression(options.compression);
  if (!compression)
    return path + ": unknown compression \"" + options.compression +
           "\" (use zip, zips, piz, rle, none, or dwaa for colour terms)";
  if (options.zip_level < 1 || options.zip_level > 9)
    return path + ": zip level " + std::to_string(options.zip_level) + " is not in [1, 9]";
  std::set<std::string> names;
  const cv::Size size = terms[0].image.size();
  for (const auto& t : terms) {
    if (t.name.empty()) return path + ": an output term has no name";
    if (!names.insert(t.name).second) return path + ": output term \"" + t.name + "\" given twice";
    if (t.image.empty()) return path + ": output term \"" + t.name + "\" has no image";
    if (t.image.type() != CV_32FC1 && t.image.type() != CV_32FC3)
      return path + ": output term \"" + t.name + "\" must be CV_32FC1 or CV_32FC3";
    if (t.image.size() != size)
      return path + ": output term \"" + t.name + "\" is " + std::to_string(t.image.cols) + "x" +
             std::to_string(t.image.rows) + ", the others " + std::to_string(size.width) + "x" +
             std::to_string(size.height);
    // DWAA quantises in a perceptual colour space: fine for pictures, wrong for numbers
    // (AO, confidences) and directions that later stages compute with.
    if (*compression == Imf::DWAA_COMPRESSION && (t.image.channels() == 1 || t.vector))
      return path + ": dwaa compression is lossy and only allowed for colour terms; \"" +
             t.name + "\" is a " + (t.vector ? "vector" : "numeric") + " term (use zip or piz)";
  }
  if (camera.width_px > 0 && (camera.width_px != size.width || camera.height_px != size.height))
    return path + ": terms are " + std::to_string(size.width) + "x" +
           std::to_string(size.height) + " but the camera grid is " +
           std::to_string(camera.width_px) + "x" + std::to_string(camera.height_px);
  std::error_code ec;
  const fs::path folder = final_path.has_parent_path() ? final_path.parent_path() : fs::path(".");
  if (!fs::is_directory(folder, ec)) return path + ": output folder does not exist";

  const fs::path temp = temp_path_for(final_path);
  try {
    Imf::Header header(size.width, size.height);
    header.compression() = *compression;
    header.zipCompressionLevel() = options.zip_level;
    for (const auto& t : terms)
      for (const auto& c : channel_names(t))
        header.channels().insert(c, Imf::Channel(t.type == SampleType::half ? Imf::HALF
                                                                            : Imf::FLOAT));
    const ExrCameraMatrices m = exr_matrices_from_camera(camera);
    Imf::addWorldToCamera(header, to_imath(m.world_to_camera));
    Imf::addWorldToNDC(header, to_imath(m.world_to_ndc));
    if (camera.near_view > 0.0f)
      header.insert(kClipNearAttribute, Imf::FloatAttribute(camera.near_view));
    if (camera.far_view > 0.0f)
      header.insert(kClipFarAttribute, Imf::FloatAttribute(camera.far_view));

    // OpenEXR writes a slice only into a channel of the same pixel type, so half terms are
    // converted into an interleaved half buffer first; float terms are written in place.
    Imf::FrameBuffer fb;
    std::vector<std::vector<half>> half_buffers;
    for (const auto& t : terms) {
      const auto channels = channel_names(t);
      const int n = t.image.channels();
      if (t.type == SampleType::half) {
        std::vector<half>& buffer = half_buffers.emplace_back(size_t(size.area()) * n);
        parallel_rows(cv::Range(0, size.height), options.threads, [&](const cv::Range& rows) {
          for (int y = rows.start; y < rows.end; ++y) {
            const float* row = t.image.ptr<float>(y);
            half* out = buffer.data() + size_t(y) * size.width * n;
            for (int i = 0; i < size.width * n; ++i) out[i] = half(row[i]);
          }
        }, 32);
        for (int c = 0; c < n; ++c)
          fb.insert(channels[c], Imf::Slice(Imf::HALF, reinterpret_cast<char*>(buffer.data() + c),
                                            sizeof(half) * n, sizeof(half) * n * size.width));
        continue;
      }
      for (int c = 0; c < n; ++c)
        fb.insert(channels[c],
                  Imf::Slice(Imf::FLOAT,
                             const_cast<char*>(reinterpret_cast<const char*>(
                                 t.image.ptr<float>() + c)),
                             sizeof(float) * n, t.image.step[0]));
    }
    {
      // Compression runs on OpenEXR's global pool (sized by its owner, e.g. the worker);
      // asking for N threads makes sure it has N.
      if (options.threads > 1 && Imf::globalThreadCount() < options.threads)
        Imf::setGlobalThreadCount(options.threads);
      const int threads = options.threads > 0 ? options.threads : Imf::globalThreadCount();
      Imf::OutputFile out(temp.c_str(), header, threads);
      out.setFrameBuffer(fb);
      out.writePixels(size.height);
    }  // closed (and flushed) here, before the rename
  } catch (const std::exception& e) {
    fs::remove(temp, ec);
    return path + ": cannot write EXR: " + e.what();
  }
  if (std::string error = commit(temp, final_path); !error.empty()) return error;

  if (options.png_previews) {
    const fs::path stem = final_path.parent_path() / final_path.stem();
    for (const auto& t : terms) {
      const fs::path png = fs::path(stem.string() + "." + t.name + ".png");
      if (std::string error = write_png(png, t); !error.empty()) return error;
    }
  }
  return {};
}

}  // namespace

std::string write_outputs(const std::string& path, const std::vector<OutputTerm>& terms,
                          const Camera& camera, const WriteOptions& options) {
  // Nothing throws across the API: file-system, OpenCV or allocation failures outside the
  // EXR writing itself end up here as messages too.
  try {
    return write_outputs_unguarded(path, terms, camera, options);
  } catch (const std::exception& e) {
    return path + ": cannot write outputs: " + e.what();
  } catch (...) {
    return path + ": cannot write outputs: unknown error";
  }
}

}  // namespace ssdo
