#include "tests/fuzz/seed_exr.h"

#include <cmath>
#include <exception>
#include <limits>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDeepFrameBuffer.h>
#include <OpenEXR/ImfDeepScanLineOutputFile.h>
#include <OpenEXR/ImfDeepTiledOutputFile.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfMultiPartOutputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfOutputPart.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfTiledOutputFile.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfTileDescription.h>
#include <Imath/half.h>

namespace ssdo::fuzz {

namespace {

constexpr int kW = 8, kH = 6;

// Planar depth of a tilted plane, with one pixel of each special value.
std::vector<float> depth_values() {
  std::vector<float> z(kW * kH);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) z[y * kW + x] = 2.0f + 0.1f * float(x) + 0.05f * float(y);
  z[0] = 1e10f;                                        // background (Blender's value)
  z[1] = std::numeric_limits<float>::quiet_NaN();
  z[2] = std::numeric_limits<float>::infinity();
  z[3] = -1.0f;
  return z;
}

// Normals facing +Z (world = view for an identity camera), one (0, 0, 0).
std::vector<float> normal_component(int c) {
  std::vector<float> n(kW * kH, c == 2 ? 1.0f : 0.0f);
  n[10] = 0.0f;
  return n;
}

void add_float(Imf::Header& h, Imf::FrameBuffer& fb, const std::string& name, std::vector<float>& v, int data_x,
               int data_y, int width) {
  h.channels().insert(name, Imf::Channel(Imf::FLOAT));
  char* base = reinterpret_cast<char*>(v.data()) - (int64_t(data_y) * width + data_x) * int64_t(sizeof(float));
  fb.insert(name, Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * size_t(width)));
}

void add_half(Imf::Header& h, Imf::FrameBuffer& fb, const std::string& name, std::vector<half>& v, int data_x,
              int data_y, int width) {
  h.channels().insert(name, Imf::Channel(Imf::HALF));
  char* base = reinterpret_cast<char*>(v.data()) - (int64_t(data_y) * width + data_x) * int64_t(sizeof(half));
  fb.insert(name, Imf::Slice(Imf::HALF, base, sizeof(half), sizeof(half) * size_t(width)));
}

std::vector<half> to_half(const std::vector<float>& v) { return std::vector<half>(v.begin(), v.end()); }

// An identity world-to-camera (OpenEXR convention: +Z forward) and a 60 degree
// perspective world-to-NDC over an 8 x 6 display window.
void add_camera(Imf::Header& h) {
  Imath::M44f world_to_camera;  // identity
  const float f = 1.0f / std::tan(0.5f * 60.0f * 3.14159265f / 180.0f);
  const float aspect = float(kW) / float(kH);
  // NDC x = 0.5 + 0.5 f x / z, y = 0.5 - 0.5 f aspect y / z (row-vector form p' = p M).
  Imath::M44f ndc(0.5f * f, 0, 0, 0,                // x
                  0, -0.5f * f * aspect, 0, 0,      // y
                  0.5f, 0.5f, 1, 1,                 // z
                  0, 0, -0.1f, 0);
  Imf::addWorldToCamera(h, world_to_camera);
  Imf::addWorldToNDC(h, ndc);
  h.insert("clipNear", Imf::FloatAttribute(0.1f));
  h.insert("clipFar", Imf::FloatAttribute(100.0f));
}

// A deep frame: pixel i holds i % 4 samples (none: background) of Z = the flat depth plus
// 0.5 per sample, farthest first, and N; scanline (ZIPS) or tiled 4 x 4 (RLE).
void write_deep_seed(const std::string& path, const Imath::Box2i& window, bool tiled) {
  Imf::Header h(window, window, 1, Imath::V2f(0, 0), 1, Imf::INCREASING_Y,
                tiled ? Imf::RLE_COMPRESSION : Imf::ZIPS_COMPRESSION);
  h.setType(tiled ? Imf::DEEPTILE : Imf::DEEPSCANLINE);
  if (tiled) h.setTileDescription(Imf::TileDescription(4, 4, Imf::ONE_LEVEL));
  const std::vector<float> z = depth_values();
  const char* names[4] = {"Z", "N.X", "N.Y", "N.Z"};
  std::vector<unsigned> counts(kW * kH);
  std::vector<std::vector<float>> values(4);
  for (int i = 0; i < kW * kH; ++i) {
    counts[i] = unsigned(i % 4);
    for (int k = int(counts[i]) - 1; k >= 0; --k) {
      values[0].push_back(z[i] + 0.5f * float(k));
      values[1].push_back(0.0f);
      values[2].push_back(0.0f);
      values[3].push_back(k == 0 ? 1.0f : -1.0f);
    }
  }
  std::vector<std::vector<float*>> pointers(4, std::vector<float*>(kW * kH));
  Imf::DeepFrameBuffer fb;
  fb.insertSampleCountSlice(Imf::Slice(Imf::UINT, reinterpret_cast<char*>(counts.data()), 4, 4 * kW));
  for (int c = 0; c < 4; ++c) {
    h.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
    size_t at = 0;
    for (int i = 0; i < kW * kH; ++i) {
      pointers[c][i] = values[c].data() + at;
      at += counts[i];
    }
    fb.insert(names[c], Imf::DeepSlice(Imf::FLOAT, reinterpret_cast<char*>(pointers[c].data()),
                                       sizeof(float*), sizeof(float*) * kW, sizeof(float)));
  }
  if (tiled) {
    Imf::DeepTiledOutputFile out(path.c_str(), h, 1);
    out.setFrameBuffer(fb);
    out.writeTiles(0, out.numXTiles() - 1, 0, out.numYTiles() - 1);
  } else {
    Imf::DeepScanLineOutputFile out(path.c_str(), h, 1);
    out.setFrameBuffer(fb);
    out.writePixels(kH);
  }
}

}  // namespace

bool write_seed_exr(const std::string& path, int variant) {
  try {
    std::vector<float> z = depth_values(), nx = normal_component(0), ny = normal_component(1),
                       nz = normal_component(2), ao(kW * kH, 0.5f), one(kW * kH, 0.8f);
    const Imath::Box2i window(Imath::V2i(0, 0), Imath::V2i(kW - 1, kH - 1));
    switch (variant) {
      case 0: {
        Imf::Header h(window, window, 1, Imath::V2f(0, 0), 1, Imf::INCREASING_Y, Imf::NO_COMPRESSION);
        Imf::FrameBuffer fb;
        add_float(h, fb, "ViewLayer.Depth.Z", z, 0, 0, kW);
        add_float(h, fb, "ViewLayer.Normal.X", nx, 0, 0, kW);
        add_float(h, fb, "ViewLayer.Normal.Y", ny, 0, 0, kW);
        add_float(h, fb, "ViewLayer.Normal.Z", nz, 0, 0, kW);
        add_float(h, fb, "ViewLayer.DiffCol.R", one, 0, 0, kW);
        add_float(h, fb, "ViewLayer.DiffCol.G", one, 0, 0, kW);
        add_float(h, fb, "ViewLayer.DiffCol.B", one, 0, 0, kW);
        add_float(h, fb, "ViewLayer.AO.R", ao, 0, 0, kW);
        add_camera(h);
        Imf::OutputFile out(path.c_str(), h, 1);
        out.setFrameBuffer(fb);
        out.writePixels(kH);
        return true;
      }
      case 1: {
        const Imath::Box2i display(Imath::V2i(-2, -1), Imath::V2i(kW + 3, kH + 2));
        const Imath::Box2i data(Imath::V2i(1, 1), Imath::V2i(kW, kH));
        Imf::Header h(display, data, 1, Imath::V2f(0, 0), 1, Imf::INCREASING_Y, Imf::ZIP_COMPRESSION);
        Imf::FrameBuffer fb;
        std::vector<half> hz = to_half(z), hx = to_half(nx), hy = to_half(ny), hn = to_half(nz);
        add_half(h, fb, "Z", hz, 1, 1, kW);
        add_half(h, fb, "N.X", hx, 1, 1, kW);
        add_half(h, fb, "N.Y", hy, 1, 1, kW);
        add_half(h, fb, "N.Z", hn, 1, 1, kW);
        Imf::OutputFile out(path.c_str(), h, 1);
        out.setFrameBuffer(fb);
        out.writePixels(kH);
        return true;
      }
      case 2: {
        Imf::Header h(window, window, 1, Imath::V2f(0, 0), 1, Imf::DECREASING_Y, Imf::RLE_COMPRESSION);
        Imf::FrameBuffer fb;
        std::vector<float> px(kW * kH, 0.1f), py(kW * kH, 0.2f), pz(kW * kH, -2.0f);
        add_float(h, fb, "depth.Z", z, 0, 0, kW);
        add_float(h, fb, "P.X", px, 0, 0, kW);
        add_float(h, fb, "P.Y", py, 0, 0, kW);
        add_float(h, fb, "P.Z", pz, 0, 0, kW);
        add_float(h, fb, "albedo.R", one, 0, 0, kW);
        add_float(h, fb, "albedo.G", one, 0, 0, kW);
        add_float(h, fb, "albedo.B", one, 0, 0, kW);
        Imf::OutputFile out(path.c_str(), h, 1);
        out.setFrameBuffer(fb);
        out.writePixels(kH);
        return true;
      }
      case 3: {
        Imf::Header h(window, window, 1, Imath::V2f(0, 0), 1, Imf::INCREASING_Y, Imf::PIZ_COMPRESSION);
        h.setTileDescription(Imf::TileDescription(4, 4, Imf::ONE_LEVEL));
        Imf::FrameBuffer fb;
        add_float(h, fb, "Z", z, 0, 0, kW);
        add_float(h, fb, "N.R", nx, 0, 0, kW);
        add_float(h, fb, "N.G", ny, 0, 0, kW);
        add_float(h, fb, "N.B", nz, 0, 0, kW);
        Imf::TiledOutputFile out(path.c_str(), h, 1);
        out.setFrameBuffer(fb);
        out.writeTiles(0, out.numXTiles() - 1, 0, out.numYTiles() - 1);
        return true;
      }
      case 4: {
        Imf::Header depth(window, window, 1, Imath::V2f(0, 0), 1, Imf::INCREASING_Y, Imf::ZIP_COMPRESSION);
        depth.setName("depth");
        depth.setType(Imf::SCANLINEIMAGE);
        Imf::FrameBuffer fb_depth;
        add_float(depth, fb_depth, "Z", z, 0, 0, kW);
        add_camera(depth);
        const Imath::Box2i small(Imath::V2i(0, 0), Imath::V2i(kW - 1, kH - 2));
        Imf::Header color(window, small, 1, Imath::V2f(0, 0), 1, Imf::INCREASING_Y, Imf::ZIP_COMPRESSION);
        color.setName("color");
        color.setType(Imf::SCANLINEIMAGE);
        Imf::FrameBuffer fb_color;
        add_float(color, fb_color, "R", one, 0, 0, kW);
        add_float(color, fb_color, "G", one, 0, 0, kW);
        add_float(color, fb_color, "B", one, 0, 0, kW);
        std::vector<Imf::Header> headers{depth, color};
        Imf::MultiPartOutputFile out(path.c_str(), headers.data(), int(headers.size()), false, 1);
        Imf::OutputPart p0(out, 0);
        p0.setFrameBuffer(fb_depth);
        p0.writePixels(kH);
        Imf::OutputPart p1(out, 1);
        p1.setFrameBuffer(fb_color);
        p1.writePixels(kH - 1);
        return true;
      }
      case 5:
      case 6: write_deep_seed(path, window, variant == 6); return true;
      default: return false;
    }
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace ssdo::fuzz
