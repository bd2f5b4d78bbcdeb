#include "formats/png_file.h"

#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <vector>

#include <png.h>

namespace ssdo {
namespace {

// libpng reports an error by longjmp back into write_rows, after its message is copied here.
struct ErrorText {
  char text[256] = {};
};

[[noreturn]] void on_error(png_structp png, png_const_charp message) {
  auto* error = static_cast<ErrorText*>(png_get_error_ptr(png));
  std::snprintf(error->text, sizeof error->text, "%s", message ? message : "unknown libpng error");
  png_longjmp(png, 1);
}

void on_warning(png_structp, png_const_charp) {}

// The libpng calls. A longjmp from libpng lands in this function's setjmp: no local here
// has a destructor, and none changes between the setjmp and the jump.
bool write_rows(std::FILE* file, const cv::Mat& pixels, png_bytep* rows, PngTransfer transfer, int zlib_level,
                ErrorText& error) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, on_error, on_warning);
  if (png == nullptr) {
    std::snprintf(error.text, sizeof error.text, "libpng cannot start");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (info == nullptr || setjmp(png_jmpbuf(png))) {
    if (info == nullptr) std::snprintf(error.text, sizeof error.text, "libpng cannot start");
    png_destroy_write_struct(&png, &info);
    return false;
  }
  static constexpr int kColourType[] = {0, PNG_COLOR_TYPE_GRAY, 0, PNG_COLOR_TYPE_RGB, PNG_COLOR_TYPE_RGB_ALPHA};
  png_init_io(png, file);
  png_set_compression_level(png, zlib_level);
  png_set_IHDR(png, info, png_uint_32(pixels.cols), png_uint_32(pixels.rows), 8, kColourType[pixels.channels()],
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (transfer == PngTransfer::srgb)
    png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  else
    png_set_gAMA(png, info, 1.0);
  png_write_info(png, info);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

std::string write_png_8bit(const std::string& path, const cv::Mat& pixels, PngTransfer transfer, int zlib_level) {
  const int channels = pixels.channels();
  if (pixels.depth() != CV_8U || (channels != 1 && channels != 3 && channels != 4) || pixels.empty())
    return path + ": a PNG preview needs an 8-bit image of 1, 3 or 4 channels";
  if (zlib_level < 0 || zlib_level > 9) return path + ": zlib level " + std::to_string(zlib_level) + " is not 0-9";
  std::vector<png_bytep> rows(size_t(pixels.rows));
  for (int y = 0; y < pixels.rows; ++y) rows[size_t(y)] = const_cast<png_bytep>(pixels.ptr<uint8_t>(y));
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) return path + ": cannot create: " + std::strerror(errno);
  ErrorText error;
  const bool written = write_rows(file, pixels, rows.data(), transfer, zlib_level, error);
  bool stored = std::fflush(file) == 0 && std::ferror(file) == 0;
  int io_errno = stored ? 0 : errno;
  if (std::fclose(file) != 0 && stored) {
    stored = false;
    io_errno = errno;
  }
  if (!written) return path + ": cannot write PNG: " + error.text;
  if (!stored) return path + ": cannot write PNG: " + std::strerror(io_errno);
  return {};
}

}  // namespace ssdo
