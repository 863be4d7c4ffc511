// Census kernels (kernels.h): one template, inlined into a 32-lane AVX-512 function and a
// 16-lane function cloned for AVX2 and the baseline.
//
// Cost (issue 29). Every centre needs 80 "darker than the centre" bits per image: 160 compares per
// pixel, whatever the formulation (bit-packed signatures need the same compares before their
// popcount; sharing a pair's compare between its two centres does not work with ties, which 8-bit
// images are full of). The loop was bound by its compares and loads at 8 float lanes per AVX2
// vector (about 1.9 cycles per step of 4 loads and 4 compares, ~60 of the ~105 ms of 8-bit census
// at 12 MP on an AMD EPYC's AVX2 path, 2x the floor of those compares). The compares now run on
// 16-bit keys (kernels.h CensusKey): 16 lanes per AVX2 vector, 32 per AVX-512 one, counts in
// 16-bit lanes too. Tried and not kept earlier (float keys; same values, measured slower or no
// faster): two centre rows per pass sharing the row loads (GCC reloads or spills the centres), the
// rows unrolled, integer compares of the float bits, software prefetch of the rows, luma straight
// from the bytes by tables.
#include <cstdint>

#include "rephoto/metrics/kernels.h"
#include "rephoto/metrics/simd.h"

namespace rephoto::metrics::internal {
namespace {

// values[x] for x in [r, w - r) when at least one block of 2 vectors of centres fits (the last
// block overlaps its predecessor and recomputes some values with the same arithmetic); returns
// w - r, or r when no block fits. Inlined into one function per target, with the vector width
// that suits it (CensusValues).
template <typename VS>
[[gnu::always_inline]] inline int CensusBlocks(const int16_t* const* photo_rows,
                                               const int16_t* const* rephoto_rows, int r, int w,
                                               float inv_bits, float* values) {
  constexpr int kLanes = sizeof(VS) / sizeof(int16_t);
  constexpr int kBlock = 2 * kLanes;
  const int end = w - r;
  if (end - r < kBlock) return r;
  for (int x = r;; x += kBlock) {
    if (x + kBlock > end) {
      if (x >= end) break;
      x = end - kBlock;
    }
    VS cp0, cp1, cr0, cr1;
    __builtin_memcpy(&cp0, photo_rows[r] + x, sizeof(VS));
    __builtin_memcpy(&cp1, photo_rows[r] + x + kLanes, sizeof(VS));
    __builtin_memcpy(&cr0, rephoto_rows[r] + x, sizeof(VS));
    __builtin_memcpy(&cr1, rephoto_rows[r] + x + kLanes, sizeof(VS));
    VS n0 = {}, n1 = {};
    for (int dy = 0; dy <= 2 * r; ++dy) {
      const int16_t* pr = photo_rows[dy] + x;
      const int16_t* rr = rephoto_rows[dy] + x;
      for (int dx = -r; dx <= r; ++dx) {
        // The centre compares false with itself in both images and adds nothing.
        VS p0, p1, q0, q1;
        __builtin_memcpy(&p0, pr + dx, sizeof(VS));
        __builtin_memcpy(&p1, pr + dx + kLanes, sizeof(VS));
        __builtin_memcpy(&q0, rr + dx, sizeof(VS));
        __builtin_memcpy(&q1, rr + dx + kLanes, sizeof(VS));
        n0 -= (p0 < cp0) ^ (q0 < cr0);
        n1 -= (p1 < cp1) ^ (q1 < cr1);
      }
    }
    int16_t counts[kBlock];
    __builtin_memcpy(counts, &n0, sizeof(VS));
    __builtin_memcpy(counts + kLanes, &n1, sizeof(VS));
    for (int i = 0; i < kBlock; ++i) values[x + i] = static_cast<float>(counts[i]) * inv_bits;
  }
  return end;
}

// 16 lanes: one ymm register each with AVX2, SSE pairs in the baseline. (64-byte GCC vectors,
// which the AVX-512 version uses, were lowered to scalar compares in the AVX2 clone.)
[[gnu::always_inline]] inline int CensusValues16Body(const int16_t* const* photo_rows,
                                                     const int16_t* const* rephoto_rows, int r,
                                                     int w, float inv_bits, float* values) {
  return CensusBlocks<V16s>(photo_rows, rephoto_rows, r, w, inv_bits, values);
}
REPHOTO_ISA_DISPATCH_AVX2(int, CensusValues16,
                          (const int16_t* const* photo_rows, const int16_t* const* rephoto_rows,
                           int r, int w, float inv_bits, float* values),
                          (photo_rows, rephoto_rows, r, w, inv_bits, values))

#ifdef REPHOTO_HAVE_AVX512_KERNELS
// 32 lanes: one zmm register each.
REPHOTO_TARGET_AVX512 int CensusValues32(const int16_t* const* photo_rows,
                                         const int16_t* const* rephoto_rows, int r, int w,
                                         float inv_bits, float* values) {
  return CensusBlocks<V32s>(photo_rows, rephoto_rows, r, w, inv_bits, values);
}
#endif

}  // namespace

int CensusValues(const int16_t* const* photo_rows, const int16_t* const* rephoto_rows, int r,
                 int w, float inv_bits, float* values) {
  // The counts are 16-bit lanes.
  if ((2 * r + 1) * (2 * r + 1) - 1 > 32767) return r;
#ifdef REPHOTO_HAVE_AVX512_KERNELS
  if (internal::HasAvx512()) {
    return CensusValues32(photo_rows, rephoto_rows, r, w, inv_bits, values);
  }
#endif
  return CensusValues16(photo_rows, rephoto_rows, r, w, inv_bits, values);
}

}  // namespace rephoto::metrics::internal
