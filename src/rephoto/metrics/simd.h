// GCC vector types and helpers shared by the metrics' SIMD kernels (internal to metrics/).
//
// The kernels are written once with these types and compiled for several ISAs (core/isa.h
// REPHOTO_ISA_DISPATCH, or one template inlined into per-width functions). Loads and stores are
// macros and the helpers below always inline: passing vectors by value to a function that is not
// compiled for their width changes the ABI (GCC's -Wpsabi). Pure data movement; no state.
#pragma once

namespace rephoto::metrics::internal {

typedef float V8f __attribute__((vector_size(32)));
typedef int V8i __attribute__((vector_size(32)));
typedef float V16f __attribute__((vector_size(64)));
typedef int V16i __attribute__((vector_size(64)));
typedef short V8s __attribute__((vector_size(16)));
typedef short V16s __attribute__((vector_size(32)));
typedef short V32s __attribute__((vector_size(64)));

#define REPHOTO_LOAD(VF, p)                 \
  ({                                        \
    VF v_;                                  \
    __builtin_memcpy(&v_, (p), sizeof(v_)); \
    v_;                                     \
  })
#define REPHOTO_STORE(p, v)                 \
  do {                                      \
    const auto s_ = (v);                    \
    __builtin_memcpy((p), &s_, sizeof(s_)); \
  } while (false)

// Census keys (kernels.h CensusKey) of eight pixels, lane by lane the scalar arithmetic, stored
// at keys[0..8) (vectors by pointer: see above).
[[gnu::always_inline]] inline void CensusKeys8(const V8f* r, const V8f* g, const V8f* b,
                                               short* keys) {
  const V8f zero = V8f{}, top = V8f{} + 255000.f;
  V8f t = 76245.f * *r + 149685.f * *g + 29070.f * *b;
  t = t >= zero ? (t <= top ? t : top) : zero;  // NaN -> 0
  const V8i k = __builtin_convertvector((t + 0.5f) * 0.25f, V8i) - 32768;
  const V8s s = __builtin_convertvector(k, V8s);
  __builtin_memcpy(keys, &s, sizeof(s));
}

// Eight interleaved triples p[0..23] (RGB pixels, or 3 channel values per pixel) split into
// their three planes by shuffles: c0 = p[0], p[3], ..., c1 = p[1], p[4], ..., c2 = p[2], ...
[[gnu::always_inline]] inline void Deinterleave8(const float* p, V8f* c0, V8f* c1, V8f* c2) {
  V8f a, b, c;
  __builtin_memcpy(&a, p, 32);
  __builtin_memcpy(&b, p + 8, 32);
  __builtin_memcpy(&c, p + 16, 32);
  const V8f ab0 = __builtin_shufflevector(a, b, 0, 3, 6, 9, 12, 15, 0, 0);
  const V8f ab1 = __builtin_shufflevector(a, b, 1, 4, 7, 10, 13, 0, 0, 0);
  const V8f ab2 = __builtin_shufflevector(a, b, 2, 5, 8, 11, 14, 0, 0, 0);
  *c0 = __builtin_shufflevector(ab0, c, 0, 1, 2, 3, 4, 5, 10, 13);
  *c1 = __builtin_shufflevector(ab1, c, 0, 1, 2, 3, 4, 8, 11, 14);
  *c2 = __builtin_shufflevector(ab2, c, 0, 1, 2, 3, 4, 9, 12, 15);
}

// 8 x 8 transpose: lane t of out[j] = lane j of r[t] (unpack, shuffle within 128-bit halves,
// then swap halves: 24 shuffles for 8 vectors).
[[gnu::always_inline]] inline void Transpose8(const V8f* r, V8f* out) {
  const V8f t0 = __builtin_shufflevector(r[0], r[1], 0, 8, 1, 9, 4, 12, 5, 13);
  const V8f t1 = __builtin_shufflevector(r[0], r[1], 2, 10, 3, 11, 6, 14, 7, 15);
  const V8f t2 = __builtin_shufflevector(r[2], r[3], 0, 8, 1, 9, 4, 12, 5, 13);
  const V8f t3 = __builtin_shufflevector(r[2], r[3], 2, 10, 3, 11, 6, 14, 7, 15);
  const V8f t4 = __builtin_shufflevector(r[4], r[5], 0, 8, 1, 9, 4, 12, 5, 13);
  const V8f t5 = __builtin_shufflevector(r[4], r[5], 2, 10, 3, 11, 6, 14, 7, 15);
  const V8f t6 = __builtin_shufflevector(r[6], r[7], 0, 8, 1, 9, 4, 12, 5, 13);
  const V8f t7 = __builtin_shufflevector(r[6], r[7], 2, 10, 3, 11, 6, 14, 7, 15);
  const V8f u0 = __builtin_shufflevector(t0, t2, 0, 1, 8, 9, 4, 5, 12, 13);
  const V8f u1 = __builtin_shufflevector(t0, t2, 2, 3, 10, 11, 6, 7, 14, 15);
  const V8f u2 = __builtin_shufflevector(t1, t3, 0, 1, 8, 9, 4, 5, 12, 13);
  const V8f u3 = __builtin_shufflevector(t1, t3, 2, 3, 10, 11, 6, 7, 14, 15);
  const V8f u4 = __builtin_shufflevector(t4, t6, 0, 1, 8, 9, 4, 5, 12, 13);
  const V8f u5 = __builtin_shufflevector(t4, t6, 2, 3, 10, 11, 6, 7, 14, 15);
  const V8f u6 = __builtin_shufflevector(t5, t7, 0, 1, 8, 9, 4, 5, 12, 13);
  const V8f u7 = __builtin_shufflevector(t5, t7, 2, 3, 10, 11, 6, 7, 14, 15);
  out[0] = __builtin_shufflevector(u0, u4, 0, 1, 2, 3, 8, 9, 10, 11);
  out[1] = __builtin_shufflevector(u1, u5, 0, 1, 2, 3, 8, 9, 10, 11);
  out[2] = __builtin_shufflevector(u2, u6, 0, 1, 2, 3, 8, 9, 10, 11);
  out[3] = __builtin_shufflevector(u3, u7, 0, 1, 2, 3, 8, 9, 10, 11);
  out[4] = __builtin_shufflevector(u0, u4, 4, 5, 6, 7, 12, 13, 14, 15);
  out[5] = __builtin_shufflevector(u1, u5, 4, 5, 6, 7, 12, 13, 14, 15);
  out[6] = __builtin_shufflevector(u2, u6, 4, 5, 6, 7, 12, 13, 14, 15);
  out[7] = __builtin_shufflevector(u3, u7, 4, 5, 6, 7, 12, 13, 14, 15);
}

}  // namespace rephoto::metrics::internal
