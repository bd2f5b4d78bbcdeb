#include "kernels/denoise.h"

#include "kernels/settings_check.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <vector>

#include "core/parallel.h"

namespace ssdo {
namespace {

constexpr int kMaxRadiusPx = 32;

template <int C>
void bilateral(const cv::Mat& src, const cv::Mat& depth_view, const cv::Mat& normal_view,
               const cv::Mat& mask, const DenoiseSettings& s, cv::Mat& dst, const cv::Rect& r,
               int nthreads) {
  using Pixel = cv::Vec<float, C>;
  const int R = s.radius_px;
  const int width = src.cols, height = src.rows;
  // Gaussian spatial weights g(k), k in [-R, R], computed once.
  float g[2 * kMaxRadiusPx + 1];
  for (int k = -R; k <= R; ++k) g[k + R] = std::exp(-0.5f * float(k * k) / (s.sigma_px * s.sigma_px));
  const float power = s.normal_power;
  // Integer powers (the default 16) by repeated squaring: std::pow per tap costs more than
  // the rest of the weight together.
  const bool integer_power = power == std::floor(power);
  const unsigned ipower = integer_power ? unsigned(power) : 0u;
  auto lobe = [&](float c) -> float {
    if (!integer_power) return std::pow(c, power);
    float result = 1.0f, base = c;
    for (unsigned e = ipower; e; e >>= 1) {
      if (e & 1u) result *= base;
      base *= base;
    }
    return result;
  };
  const float inv_tol = 1.0f / s.depth_tolerance_relative;

  // Range weight of a tap against a centre (depth d, normal n): hard-cut linear depth
  // weight times the normal lobe; 0 for masked taps.
  auto range_weight = [&](int tx, int ty, float d, const cv::Vec3f& n) -> float {
    if (!mask.ptr<uint8_t>(ty)[tx]) return 0.0f;
    const float dt = depth_view.ptr<float>(ty)[tx];
    const float wd = 1.0f - std::abs(dt - d) * inv_tol / d;
    if (!(wd > 0.0f)) return 0.0f;
    const float cosn = n.dot(normal_view.ptr<cv::Vec3f>(ty)[tx]);
    if (!(cosn > 0.0f)) return 0.0f;
    return wd * lobe(cosn);
  };

  // Pass 1 (horizontal) over the rows the vertical pass reads, roi columns only.
  const int y0 = std::max(0, r.y - R), y1 = std::min(height, r.y + r.height + R);
  cv::Mat tmp(y1 - y0, r.width, CV_MAKETYPE(CV_32F, C));
  parallel_rows(cv::Range(y0, y1), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const Pixel* in = src.ptr<Pixel>(y);
      const uint8_t* m = mask.ptr<uint8_t>(y);
      const float* dep = depth_view.ptr<float>(y);
      const cv::Vec3f* nor = normal_view.ptr<cv::Vec3f>(y);
      Pixel* out = tmp.ptr<Pixel>(y - y0);
      for (int x = r.x; x < r.x + r.width; ++x) {
        if (!m[x]) {
          out[x - r.x] = in[x];
          continue;
        }
        const float d = dep[x];
        const cv::Vec3f n = nor[x];
        const int k0 = std::max(-R, -x), k1 = std::min(R, width - 1 - x);
        Pixel sum = Pixel::all(0.0f);
        float wsum = 0.0f;
        for (int k = k0; k <= k1; ++k) {
          const float w = g[k + R] * range_weight(x + k, y, d, n);
          sum += w * in[x + k];
          wsum += w;
        }
        out[x - r.x] = sum * (1.0f / wsum);  // wsum >= g(0) * 1 (the centre) > 0
      }
    }
  });

  // Pass 2 (vertical) over the roi, reading pass 1.
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const Pixel* in = src.ptr<Pixel>(y);
      const uint8_t* m = mask.ptr<uint8_t>(y);
      const float* dep = depth_view.ptr<float>(y);
      const cv::Vec3f* nor = normal_view.ptr<cv::Vec3f>(y);
      Pixel* out = dst.ptr<Pixel>(y);
      const int k0 = std::max(-R, y0 - y), k1 = std::min(R, y1 - 1 - y);
      for (int x = r.x; x < r.x + r.width; ++x) {
        if (!m[x]) {
          out[x] = in[x];
          continue;
        }
        const float d = dep[x];
        const cv::Vec3f n = nor[x];
        Pixel sum = Pixel::all(0.0f);
        float wsum = 0.0f;
        for (int k = k0; k <= k1; ++k) {
          const float w = g[k + R] * range_weight(x, y + k, d, n);
          sum += w * tmp.ptr<Pixel>(y + k - y0)[x - r.x];
          wsum += w;
        }
        out[x] = sum * (1.0f / wsum);
      }
    }
  });
}

// c^P by squaring, unrolled at compile time so the pixel loop stays branch-free.
// T: float or a vector of floats (Lanes).
template <unsigned P, typename T>
inline T ipow(T c) {
  if constexpr (P == 0) {
    return T{} + 1.0f;
  } else if constexpr (P == 1) {
    return c;
  } else {
    const T h = ipow<P / 2>(c);
    if constexpr (P % 2 == 0) return h * h;
    else return h * h * c;
  }
}

// Eight pixels of a row in one value (GCC/Clang vector extension: AVX registers where
// the kernels are built for them, pairs of SSE registers or scalars elsewhere), so that a
// pass keeps its per-channel sums in registers across the taps.
constexpr int kLanes = 8;
typedef float Lanes __attribute__((vector_size(kLanes * sizeof(float))));
typedef int32_t LaneMask __attribute__((vector_size(kLanes * sizeof(int32_t))));

inline Lanes load_lanes(const float* p) {
  Lanes v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}

inline void store_lanes(float* p, Lanes v) { std::memcpy(p, &v, sizeof(v)); }

inline Lanes broadcast(float x) { return Lanes{} + x; }

// std::max(0.0f, x) lane by lane: x where 0 < x, else 0 (NaN -> 0, as std::max).
inline Lanes max0(Lanes x) { return x > 0.0f ? x : broadcast(0.0f); }

inline Lanes abs_lanes(Lanes x) {
  LaneMask bits;
  std::memcpy(&bits, &x, sizeof(x));
  bits &= 0x7fffffff;
  std::memcpy(&x, &bits, sizeof(x));
  return x;
}

// Tile of the planar bilateral, pixels: kTileRows x kTileCols outputs. With the halo of R
// rows and columns either side, every plane of a tile (depth, normal x/y/z, C values, C
// horizontal results) is at most (32 + 64) x (256 + 64) floats x 10 planes = 1.2 MB at
// R = 32 and ~0.2 MB at the default R = 4: the passes run out of L2, and the frame's guides
// and source are read from memory once (the halo re-reads 2R / kTileRows of the rows).
constexpr int kTileRows = 32;
constexpr int kTileCols = 256;

// Per-thread scratch of the tiles, grown once per thread (never inside the pixel loops).
struct TileScratch {
  std::vector<float> buffer;
  float* get(size_t floats) {
    if (buffer.size() < floats) buffer.resize(floats);
    return buffer.data();
  }
};

// The bilateral above restructured to vectorise (same weights, same per-pixel summation
// order, so the same values up to the rounding of the depth weight's division): per tile,
// the guides and the source as planes (depth, normal x, y, z, C value planes) over the tile
// and its halo, the normal zeroed where mask is 0 or outside the image so that the lobe
// weighs those taps 0 (the terms they add are exact zeros), the source zeroed there so that
// no masked value is read into a sum. Each pass is an outer loop over the tap offset k and
// an inner, branch-free loop over a tile row. Integer normal powers only (the lobe by
// squaring, ipow).
// The channels one planar pass denoises together, from one image or several of the same
// frame: channel c of the pass is channel offset[c] of *src[c] (stride[c] channels per
// pixel), written to the same channel of *dst[c].
template <int C>
struct ChannelMap {
  const cv::Mat* src[C];
  cv::Mat* dst[C];
  int offset[C];
  int stride[C];
};

template <int C, class Lobe>
void bilateral_planar(const ChannelMap<C>& ch, const cv::Mat& depth_view, const cv::Mat& normal_view,
                      const cv::Mat& mask, const DenoiseSettings& s, const cv::Rect& r,
                      int nthreads, Lobe lobe_of) {
  const int R = s.radius_px;
  const int width = depth_view.cols, height = depth_view.rows;
  float g[2 * kMaxRadiusPx + 1];
  for (int k = -R; k <= R; ++k) g[k + R] = std::exp(-0.5f * float(k * k) / (s.sigma_px * s.sigma_px));
  const float inv_tol = 1.0f / s.depth_tolerance_relative;
  // Plane geometry of a tile: rows [ya - R, yb + R), columns [xa - R, xb + R), stride pw.
  const int pw = kTileCols + 2 * R, ph = kTileRows + 2 * R;
  const size_t plane = size_t(pw) * size_t(ph);
  // depth, nx, ny, nz, C values, C horizontal results, 3 C + 1 accumulators of a row.
  const size_t scratch_floats = plane * size_t(4 + 2 * C) + size_t(kTileCols) * size_t(C + 2);

  auto tile = [&](int ya, int yb, int xa, int xb, float* scratch) {
    float* pd = scratch;
    float* pnx = pd + plane;
    float* pny = pnx + plane;
    float* pnz = pny + plane;
    float* pv = pnz + plane;       // C planes
    float* ph_out = pv + C * plane;  // C planes: the horizontal pass, tile columns only
    float* acc = ph_out + C * plane;  // C sums, the weight sum and the depth scale of a row
    const int tw = xb - xa;
    // Fill: plane row j is image row ya - R + j, plane column i is image column xa - R + i.
    for (int j = 0; j < (yb - ya) + 2 * R; ++j) {
      const int y = ya - R + j;
      float* d = pd + size_t(j) * pw;
      float* nx = pnx + size_t(j) * pw;
      float* ny = pny + size_t(j) * pw;
      float* nz = pnz + size_t(j) * pw;
      if (y < 0 || y >= height) {
        for (int i = 0; i < tw + 2 * R; ++i) d[i] = nx[i] = ny[i] = nz[i] = 0.0f;
        for (int c = 0; c < C; ++c)
          for (int i = 0; i < tw + 2 * R; ++i) pv[c * plane + size_t(j) * pw + i] = 0.0f;
        continue;
      }
      const uint8_t* m = mask.ptr<uint8_t>(y);
      const float* dep = depth_view.ptr<float>(y);
      const cv::Vec3f* n = normal_view.ptr<cv::Vec3f>(y);
      const float* v[C];
      for (int c = 0; c < C; ++c) v[c] = ch.src[c]->template ptr<float>(y) + ch.offset[c];
      for (int i = 0; i < tw + 2 * R; ++i) {
        const int x = xa - R + i;
        const bool on = x >= 0 && x < width && m[x] != 0;
        d[i] = on ? dep[x] : 0.0f;
        nx[i] = on ? n[x][0] : 0.0f;
        ny[i] = on ? n[x][1] : 0.0f;
        nz[i] = on ? n[x][2] : 0.0f;
        for (int c = 0; c < C; ++c)
          pv[c * plane + size_t(j) * pw + i] = on ? v[c][x * ch.stride[c]] : 0.0f;
      }
    }
    float* sum = acc;
    float* wsum = acc + C * kTileCols;
    float* scale = wsum + kTileCols;
    // One pass over a tile row: out[c][i] = sum_k w_k tap_c,k / sum_k w_k, i in [0, tw).
    // Centre guides at plane row cj, column R + i; tap k at plane offset k * step from the
    // centre in the guide planes; the taps of value plane c at tap0 + c * tap_plane +
    // k * tap_step.
    auto pass = [&](int cj, ptrdiff_t step, const float* tap0, ptrdiff_t tap_step, size_t tap_plane,
                    float* const* out) {
      const float* cd = pd + size_t(cj) * pw + R;
      const float* cx = pnx + size_t(cj) * pw + R;
      const float* cy = pny + size_t(cj) * pw + R;
      const float* cz = pnz + size_t(cj) * pw + R;
      // Blocks of kLanes pixels: the sums stay in registers over the taps. Each lane
      // computes what the loop below computes for its pixel, in the same order (the same
      // bits).
      int i0 = 0;
      for (; i0 + kLanes <= tw; i0 += kLanes) {
        const Lanes d0 = load_lanes(cd + i0), x0 = load_lanes(cx + i0), y0 = load_lanes(cy + i0),
                    z0 = load_lanes(cz + i0);
        const Lanes sc = inv_tol / d0;
        Lanes acc_c[C], acc_w = broadcast(0.0f);
        for (int c = 0; c < C; ++c) acc_c[c] = broadcast(0.0f);
        for (int k = -R; k <= R; ++k) {
          const ptrdiff_t off = k * step + i0;
          const Lanes wd = max0(1.0f - abs_lanes(load_lanes(cd + off) - d0) * sc);
          const Lanes cn = max0(x0 * load_lanes(cx + off) + y0 * load_lanes(cy + off) + z0 * load_lanes(cz + off));
          const Lanes w = g[k + R] * (wd * lobe_of(cn));
          const float* tv = tap0 + k * tap_step + i0;
          for (int c = 0; c < C; ++c) acc_c[c] += w * load_lanes(tv + c * tap_plane);
          acc_w += w;
        }
        const Lanes inv = 1.0f / acc_w;
        for (int c = 0; c < C; ++c) store_lanes(out[c] + i0, acc_c[c] * inv);
      }
      if (i0 == tw) return;
      for (int i = i0; i < tw; ++i) {
        for (int c = 0; c < C; ++c) sum[c * kTileCols + i] = 0.0f;
        wsum[i] = 0.0f;
        scale[i] = inv_tol / cd[i];
      }
      for (int k = -R; k <= R; ++k) {
        const ptrdiff_t off = k * step;
        const float* td = cd + off;
        const float* tx = cx + off;
        const float* ty = cy + off;
        const float* tz = cz + off;
        const float* tv = tap0 + k * tap_step;
        const float gk = g[k + R];
        // The accumulators and the planes are disjoint parts of one scratch buffer, which
        // the compiler's runtime overlap check cannot prove: without ivdep it takes the
        // scalar copy of this loop (5x slower at 3 channels).
#pragma GCC ivdep
        for (int i = i0; i < tw; ++i) {
          const float wd = std::max(0.0f, 1.0f - std::abs(td[i] - cd[i]) * scale[i]);
          const float cn = std::max(0.0f, cx[i] * tx[i] + cy[i] * ty[i] + cz[i] * tz[i]);
          const float w = gk * (wd * lobe_of(cn));
          for (int c = 0; c < C; ++c) sum[c * kTileCols + i] += w * tv[c * tap_plane + i];
          wsum[i] += w;
        }
      }
      for (int i = i0; i < tw; ++i) {
        const float inv = 1.0f / wsum[i];
        for (int c = 0; c < C; ++c) out[c][i] = sum[c * kTileCols + i] * inv;
      }
    };
    // Pass 1 (horizontal) on every plane row: guides and taps in the same planes.
    for (int j = 0; j < (yb - ya) + 2 * R; ++j) {
      const int y = ya - R + j;
      float* out[C];
      for (int c = 0; c < C; ++c) out[c] = ph_out + c * plane + size_t(j) * pw;
      if (y < 0 || y >= height) {
        for (int c = 0; c < C; ++c)
          for (int i = 0; i < tw; ++i) out[c][i] = 0.0f;
        continue;
      }
      pass(j, 1, pv + size_t(j) * pw + R, 1, plane, out);
      // Masked pixels: 0 (their normal is 0, so pass 2 weighs them 0 anyway; no NaN read).
      const uint8_t* m = mask.ptr<uint8_t>(y);
      for (int c = 0; c < C; ++c)
        for (int i = 0; i < tw; ++i) out[c][i] = m[xa + i] ? out[c][i] : 0.0f;
    }
    // Pass 2 (vertical) on the tile's rows; masked pixels copy the source.
    for (int y = ya; y < yb; ++y) {
      const int j = y - ya + R;
      float result[C][kTileCols];
      float* to[C];
      for (int c = 0; c < C; ++c) to[c] = result[c];
      pass(j, pw, ph_out + size_t(j) * pw, pw, plane, to);
      const uint8_t* m = mask.ptr<uint8_t>(y);
      for (int c = 0; c < C; ++c) {
        const float* in = ch.src[c]->template ptr<float>(y) + ch.offset[c];
        float* row = ch.dst[c]->template ptr<float>(y) + ch.offset[c];
        const int stride = ch.stride[c];
        for (int i = 0; i < tw; ++i) {
          const int x = xa + i;
          row[x * stride] = m[x] ? result[c][i] : in[x * stride];
        }
      }
    }
  };

  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    thread_local TileScratch scratch;
    float* buffer = scratch.get(scratch_floats);
    for (int ya = rows.start; ya < rows.end; ya += kTileRows) {
      const int yb = std::min(ya + kTileRows, rows.end);
      for (int xa = r.x; xa < r.x + r.width; xa += kTileCols)
        tile(ya, yb, xa, std::min(xa + kTileCols, r.x + r.width), buffer);
    }
  }, kTileRows);
}

template <int C>
void box4(const cv::Mat& src, cv::Mat& dst, const cv::Rect& r, int nthreads) {
  using Pixel = cv::Vec<float, C>;
  const int width = src.cols, height = src.rows;
  parallel_rows(cv::Range(r.y, r.y + r.height), nthreads, [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const int ya = std::max(0, y - 2), yb = std::min(height - 1, y + 1);
      Pixel* out = dst.ptr<Pixel>(y);
      for (int x = r.x; x < r.x + r.width; ++x) {
        const int xa = std::max(0, x - 2), xb = std::min(width - 1, x + 1);
        Pixel sum = Pixel::all(0.0f);
        for (int ty = ya; ty <= yb; ++ty) {
          const Pixel* in = src.ptr<Pixel>(ty);
          for (int tx = xa; tx <= xb; ++tx) sum += in[tx];
        }
        out[x] = sum * (1.0f / float((yb - ya + 1) * (xb - xa + 1)));
      }
    }
  });
}

void prepare_dst(const cv::Mat& src, cv::Mat& dst) {
  CV_Assert(src.type() == CV_32FC1 || src.type() == CV_32FC3);
  CV_Assert(dst.empty() || dst.data != src.data);
  if (dst.size() != src.size() || dst.type() != src.type()) dst.create(src.size(), src.type());
}

}  // namespace

std::string validate(const DenoiseSettings& s) {
  if (s.radius_px < 0 || s.radius_px > kMaxRadiusPx) return detail::out_of_range("radius_px", s.radius_px, "[0, 32]");
  if (!(s.sigma_px > 0.0f) || !std::isfinite(s.sigma_px)) return detail::out_of_range("sigma_px", s.sigma_px, "(0, inf)");
  if (!(s.depth_tolerance_relative > 0.0f) || !std::isfinite(s.depth_tolerance_relative))
    return detail::out_of_range("depth_tolerance_relative", s.depth_tolerance_relative, "(0, inf)");
  if (!(s.normal_power >= 0.0f && s.normal_power <= 256.0f))
    return detail::out_of_range("normal_power", s.normal_power, "[0, 256]");
  return {};
}

void denoise_bilateral(const cv::Mat& src, const cv::Mat& depth_view, const cv::Mat& normal_view,
                       const cv::Mat& mask, const DenoiseSettings& settings, cv::Mat& dst,
                       cv::Rect roi, int nthreads) {
  const cv::Mat* srcs[] = {&src};
  cv::Mat* dsts[] = {&dst};
  denoise_bilateral(srcs, depth_view, normal_view, mask, settings, dsts, roi, nthreads);
}

void denoise_bilateral(std::span<const cv::Mat* const> srcs, const cv::Mat& depth_view,
                       const cv::Mat& normal_view, const cv::Mat& mask,
                       const DenoiseSettings& settings, std::span<cv::Mat* const> dsts,
                       cv::Rect roi, int nthreads) {
  CV_Assert(validate(settings).empty());
  CV_Assert(srcs.size() == dsts.size() && !srcs.empty());
  int channels = 0;
  for (size_t i = 0; i < srcs.size(); ++i) {
    const cv::Mat& src = *srcs[i];
    CV_Assert(depth_view.type() == CV_32FC1 && depth_view.size() == src.size());
    CV_Assert(normal_view.type() == CV_32FC3 && normal_view.size() == src.size());
    CV_Assert(mask.type() == CV_8UC1 && mask.size() == src.size());
    for (size_t k = 0; k < i; ++k) CV_Assert(dsts[k] != dsts[i]);
    prepare_dst(src, *dsts[i]);
    channels += src.channels();
  }
  for (cv::Mat* dst : dsts)
    for (const cv::Mat* src : srcs) CV_Assert(dst->data != src->data);
  const cv::Rect r = resolve_roi(roi, depth_view.size());
  if (r.empty()) return;
  const float p = settings.normal_power;
  const bool planar = p == 16.0f || p == 8.0f || p == 4.0f || p == 1.0f || p == 0.0f;
  // One pass over every channel for the channel counts the pipeline uses: AO 1, a colour
  // term 3, the two SSDO terms 6, AO and both SSDO terms 7.
  const bool together = planar && (channels == 1 || channels == 3 || channels == 6 || channels == 7);
  if (!together) {
    for (size_t i = 0; i < srcs.size(); ++i) {
      const cv::Mat& src = *srcs[i];
      cv::Mat& dst = *dsts[i];
      if (planar) {
        const cv::Mat* one_src[] = {&src};
        cv::Mat* one_dst[] = {&dst};
        denoise_bilateral(one_src, depth_view, normal_view, mask, settings, one_dst, r, nthreads);
      } else if (src.channels() == 1) {
        bilateral<1>(src, depth_view, normal_view, mask, settings, dst, r, nthreads);
      } else {
        bilateral<3>(src, depth_view, normal_view, mask, settings, dst, r, nthreads);
      }
    }
    return;
  }
  auto run_with = [&](auto channel_count, auto lobe) {
    constexpr int C = decltype(channel_count)::value;
    ChannelMap<C> map{};
    int c = 0;
    for (size_t i = 0; i < srcs.size(); ++i)
      for (int k = 0; k < srcs[i]->channels(); ++k, ++c) {
        map.src[c] = srcs[i];
        map.dst[c] = dsts[i];
        map.offset[c] = k;
        map.stride[c] = srcs[i]->channels();
      }
    bilateral_planar<C>(map, depth_view, normal_view, mask, settings, r, nthreads, lobe);
  };
  // The planar path for the integer powers the settings use in practice (the default 16
  // and its halvings); any other power takes the per-pixel path with std::pow.
  auto run = [&](auto lobe) {
    switch (channels) {
      case 1: run_with(std::integral_constant<int, 1>{}, lobe); break;
      case 3: run_with(std::integral_constant<int, 3>{}, lobe); break;
      case 6: run_with(std::integral_constant<int, 6>{}, lobe); break;
      default: run_with(std::integral_constant<int, 7>{}, lobe); break;
    }
  };
  // Each lobe takes a float or Lanes.
  if (p == 16.0f)
    run([](auto c) { return ipow<16>(c); });
  else if (p == 8.0f)
    run([](auto c) { return ipow<8>(c); });
  else if (p == 4.0f)
    run([](auto c) { return ipow<4>(c); });
  else if (p == 1.0f)
    run([](auto c) { return c; });
  else
    run([](auto c) {
      using T = decltype(c);
      return c > 0.0f ? T{} + 1.0f : T{};
    });
}

void box_blur_4x4(const cv::Mat& src, cv::Mat& dst, cv::Rect roi, int nthreads) {
  prepare_dst(src, dst);
  const cv::Rect r = resolve_roi(roi, src.size());
  if (r.empty()) return;
  if (src.channels() == 1)
    box4<1>(src, dst, r, nthreads);
  else
    box4<3>(src, dst, r, nthreads);
}

}  // namespace ssdo
