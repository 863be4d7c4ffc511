// Census kernels (kernels.h): one template, inlined into a 16-wide AVX-512 function and an
// 8-wide function cloned for AVX2 and the baseline.
//
// Cost (issue 29). Every centre needs 80 "darker than the centre" bits per image: 160 float
// compares per pixel, whatever the formulation (bit-packed signatures need the same compares
// before their popcount; sharing a pair's compare between its two centres does not work with
// ties, which 8-bit images are full of). This loop does them 8 (AVX2) or 16 (AVX-512) lanes at a
// time with one xor and one subtract per compare pair, ~1.9 cycles per step of 4 loads and 4
// compares on the AMD EPYC measured: ~60 ms of the ~105 ms CPU of 8-bit census at 12 MP on the
// AVX2 path; the rest is the band's 8-bit -> float rows, luma, validity and the masked sums.
// Tried and not kept (same values, measured slower or no faster in a standalone harness or
// perf): two centre rows per pass sharing the row loads (57-88 ms against 62 ms: GCC reloads or
// spills the centres), the rows unrolled, integer compares of the float bits (no faster:
// compares are not the only bound), software prefetch of the rows, luma straight from the bytes
// by tables for census alone (30 ms scalar against 15 + 15 ms for conversion and luma).
#include "rephoto/metrics/kernels.h"
#include "rephoto/metrics/simd.h"

namespace rephoto::metrics::internal {
namespace {

// values[x] for x in [r, end): the number of window neighbours whose census bit differs, times
// inv_bits, where end = r + whole blocks of 2 vectors of pixels that fit before w - r; returns
// end. `photo_rows` / `rephoto_rows` point to the 2r+1 luma rows of the window. Inlined into
// one function per target, with the vector width that suits it (CensusValues).
template <typename VF, typename VI>
[[gnu::always_inline]] inline int CensusBlocks(const float* const* photo_rows,
                                               const float* const* rephoto_rows, int r, int w,
                                               float inv_bits, float* values) {
  constexpr int kLanes = sizeof(VF) / sizeof(float);
  int x = r;
  for (; x + 2 * kLanes <= w - r; x += 2 * kLanes) {
    VF cp0, cp1, cr0, cr1;
    __builtin_memcpy(&cp0, photo_rows[r] + x, sizeof(VF));
    __builtin_memcpy(&cp1, photo_rows[r] + x + kLanes, sizeof(VF));
    __builtin_memcpy(&cr0, rephoto_rows[r] + x, sizeof(VF));
    __builtin_memcpy(&cr1, rephoto_rows[r] + x + kLanes, sizeof(VF));
    VI n0 = {}, n1 = {};
    for (int dy = 0; dy <= 2 * r; ++dy) {
      const float* pr = photo_rows[dy] + x;
      const float* rr = rephoto_rows[dy] + x;
      for (int dx = -r; dx <= r; ++dx) {
        // The centre compares false with itself in both images and adds nothing.
        VF p0, p1, q0, q1;
        __builtin_memcpy(&p0, pr + dx, sizeof(VF));
        __builtin_memcpy(&p1, pr + dx + kLanes, sizeof(VF));
        __builtin_memcpy(&q0, rr + dx, sizeof(VF));
        __builtin_memcpy(&q1, rr + dx + kLanes, sizeof(VF));
        n0 -= (p0 < cp0) ^ (q0 < cr0);
        n1 -= (p1 < cp1) ^ (q1 < cr1);
      }
    }
    const VF v0 = __builtin_convertvector(n0, VF) * inv_bits;
    const VF v1 = __builtin_convertvector(n1, VF) * inv_bits;
    __builtin_memcpy(values + x, &v0, sizeof(VF));
    __builtin_memcpy(values + x + kLanes, &v1, sizeof(VF));
  }
  return x;
}

// 8-wide vectors: one ymm register each with AVX2, SSE pairs in the baseline. (64-byte GCC
// vectors, which the AVX-512 version uses, were lowered to scalar compares in the AVX2 clone:
// census 10x slower on CPUs without AVX-512.)
[[gnu::always_inline]] inline int CensusValues8Body(const float* const* photo_rows,
                                                    const float* const* rephoto_rows, int r, int w,
                                                    float inv_bits, float* values) {
  return CensusBlocks<V8f, V8i>(photo_rows, rephoto_rows, r, w, inv_bits, values);
}
REPHOTO_ISA_DISPATCH_AVX2(int, CensusValues8,
                          (const float* const* photo_rows, const float* const* rephoto_rows, int r,
                           int w, float inv_bits, float* values),
                          (photo_rows, rephoto_rows, r, w, inv_bits, values))

#ifdef REPHOTO_HAVE_AVX512_KERNELS
// 16-wide: one zmm register each (15 % faster than ymm on the AMD EPYC this was measured on).
REPHOTO_TARGET_AVX512 int CensusValues16(const float* const* photo_rows,
                                         const float* const* rephoto_rows, int r, int w,
                                         float inv_bits, float* values) {
  return CensusBlocks<V16f, V16i>(photo_rows, rephoto_rows, r, w, inv_bits, values);
}
#endif

}  // namespace

int CensusValues(const float* const* photo_rows, const float* const* rephoto_rows, int r, int w,
                 float inv_bits, float* values) {
#ifdef REPHOTO_HAVE_AVX512_KERNELS
  if (internal::HasAvx512()) {
    return CensusValues16(photo_rows, rephoto_rows, r, w, inv_bits, values);
  }
#endif
  return CensusValues8(photo_rows, rephoto_rows, r, w, inv_bits, values);
}

}  // namespace rephoto::metrics::internal
