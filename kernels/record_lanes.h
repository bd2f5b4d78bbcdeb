// Records of four or two consecutive 4-byte fields (a texel's) read into lanes for the
// kernels' lane loops (Highway), instead of a gather instruction per field: four fields at
// any float offset with a 16-byte load per lane; two fields of 8-byte records with one
// 64-bit gather per record.
//
// Included once per instruction set (by the kernels' foreach_target files, after
// hwy/highway.h), into that target's namespace, as kernels/integer_power.h.
#if defined(SSDO_KERNELS_RECORD_LANES_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef SSDO_KERNELS_RECORD_LANES_H_
#undef SSDO_KERNELS_RECORD_LANES_H_
#else
#define SSDO_KERNELS_RECORD_LANES_H_
#endif

#include <cstddef>
#include <cstdint>
#include <cstring>

#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace ssdo::HWY_NAMESPACE {

// field[f] lane l = base[offset[l] + f], f = 0..3, for the lanes of one vector of d; every
// base[offset[l] .. offset[l] + 3] is read. A vector's 128-bit blocks are filled from four
// lanes' records each: block b of A_i holds the record of lane 4 b + i, so that the
// transpose within blocks (two rounds of interleaves) leaves lane 4 b + i of every field in
// its place. Loads and shuffles beat a gather instruction per field (four per vector). d
// has whole 128-bit blocks, or one lane (four loads).
template <class D>
HWY_INLINE void load_records4(D d, const float* base, const int32_t* offset, hwy::HWY_NAMESPACE::Vec<D>* field) {
  namespace hn = hwy::HWY_NAMESPACE;
  static_assert(hn::MaxLanes(d) == 1 || hn::MaxLanes(d) % 4 == 0, "one lane or whole blocks of four floats");
#if HWY_TARGET != HWY_SCALAR
  if constexpr (hn::MaxLanes(d) > 1) {
    const hn::RebindToSigned<D> di;
    const hn::Repartition<uint64_t, D> d64;
    constexpr size_t kBlockLanes = 16 / sizeof(float);
    constexpr size_t kMaxBlocks = HWY_MAX_BYTES / 16;
    const size_t blocks = hn::Lanes(d) / kBlockLanes;
    // Lanes of block b (b >= 1).
    hn::Mask<D> block[kMaxBlocks];
    const auto lane = hn::Iota(di, 0);
    for (size_t b = 1; b < blocks; ++b)
      block[b] = hn::RebindMask(d, hn::And(hn::Gt(lane, hn::Set(di, int32_t(b * kBlockLanes) - 1)),
                                           hn::Lt(lane, hn::Set(di, int32_t((b + 1) * kBlockLanes)))));
    auto record = [&](size_t l) { return hn::LoadDup128(d, base + offset[l]); };
    hn::Vec<D> a[4];
    for (size_t i = 0; i < 4; ++i) {
      a[i] = record(i);
      for (size_t b = 1; b < blocks; ++b) a[i] = hn::IfThenElse(block[b], record(b * kBlockLanes + i), a[i]);
    }
    // Per block: t0 = (x0 x1 y0 y1), t1 = (x2 x3 y2 y3), t2 = (z0 z1 w0 w1), t3 = (z2 z3 w2 w3).
    const auto t0 = hn::BitCast(d64, hn::InterleaveLower(d, a[0], a[1]));
    const auto t1 = hn::BitCast(d64, hn::InterleaveLower(d, a[2], a[3]));
    const auto t2 = hn::BitCast(d64, hn::InterleaveUpper(d, a[0], a[1]));
    const auto t3 = hn::BitCast(d64, hn::InterleaveUpper(d, a[2], a[3]));
    field[0] = hn::BitCast(d, hn::InterleaveLower(d64, t0, t1));
    field[1] = hn::BitCast(d, hn::InterleaveUpper(d64, t0, t1));
    field[2] = hn::BitCast(d, hn::InterleaveLower(d64, t2, t3));
    field[3] = hn::BitCast(d, hn::InterleaveUpper(d64, t2, t3));
    return;
  }
#endif
  // One lane.
  for (size_t f = 0; f < 4; ++f) field[f] = hn::Set(d, base[offset[0] + ptrdiff_t(f)]);
}

// field[0] lane l = the first 4-byte field of the 8-byte record index[l] of `records`,
// field[1] its second, for the lanes of one vector of d: the records gathered as 64-bit
// lanes (half of d's lanes per vector, two gathers), then each record's two halves moved
// into their fields' lanes (ConcatEven, ConcatOdd: a record's first field is the low half
// of its 64-bit lane, the targets being little-endian). index[l] >= 0.
template <class D>
HWY_INLINE void load_records2(D d, const void* records, const int32_t* index, hwy::HWY_NAMESPACE::Vec<D>* field) {
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::RebindToUnsigned<D> du;
#if HWY_TARGET != HWY_SCALAR
  if constexpr (hn::MaxLanes(d) > 1) {
    const hn::Repartition<uint64_t, D> d64;
    const hn::RebindToSigned<decltype(d64)> di64;
    const hn::Rebind<int32_t, decltype(d64)> d32;
    const size_t half = hn::Lanes(d64);
    const auto* words = static_cast<const uint64_t*>(records);
    const auto lo = hn::GatherIndex(d64, words, hn::PromoteTo(di64, hn::LoadU(d32, index)));
    const auto hi = hn::GatherIndex(d64, words, hn::PromoteTo(di64, hn::LoadU(d32, index + half)));
    field[0] = hn::BitCast(d, hn::ConcatEven(du, hn::BitCast(du, hi), hn::BitCast(du, lo)));
    field[1] = hn::BitCast(d, hn::ConcatOdd(du, hn::BitCast(du, hi), hn::BitCast(du, lo)));
    return;
  }
#endif
  // One lane.
  uint64_t r;
  std::memcpy(&r, static_cast<const uint8_t*>(records) + size_t(index[0]) * sizeof(r), sizeof(r));
  field[0] = hn::BitCast(d, hn::Set(du, uint32_t(r)));
  field[1] = hn::BitCast(d, hn::Set(du, uint32_t(r >> 32)));
}

}  // namespace ssdo::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // SSDO_KERNELS_RECORD_LANES_H_
