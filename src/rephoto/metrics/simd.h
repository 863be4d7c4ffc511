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

}  // namespace rephoto::metrics::internal
