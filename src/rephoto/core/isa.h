// Which x86-64 instruction-set path rephoto's SIMD kernels take, decided in one place.
//
// Three paths: kAvx512 (x86-64-v4: AVX-512 F/BW/DQ/VL), kAvx2 (x86-64-v3: AVX2 + FMA + BMI2)
// and kBaseline (x86-64, SSE2; also every non-x86 CPU). Each kernel with ISA-specific code is
// compiled once per path (REPHOTO_ISA_DISPATCH below, or functions with REPHOTO_TARGET_AVX512 /
// REPHOTO_TARGET_AVX2) and picks the variant of ActiveIsa() on each call, so a process can be
// pinned to a path:
//   - by default the best path the CPU has;
//   - REPHOTO_ISA=baseline|avx2|avx512 in the environment forces one (read once, at the first
//     ActiveIsa() call; the CLI calls CheckIsaEnvironment() at start-up, so a bad value or a path
//     the CPU lacks exits 2 naming it);
//   - ScopedIsa (tests, benchmarks) switches the path of the whole process for a scope.
// Embree devices follow the path too (EmbreeDeviceConfig).
//
// The results contract (docs/determinism.md): renders are bit-identical on every path; metric
// values are bit-identical between kAvx512 and kAvx2 (both use FMA with the same reduction
// order) and within 1e-6 relative on kBaseline (no FMA: products round once more).
//
// Thread safety: ActiveIsa() is a relaxed atomic load after the first call (which initializes
// under a function-local static). ScopedIsa changes the path for every thread: use it only
// while no other thread runs kernels (tests, benchmark set-up).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace rephoto::core {

enum class Isa : int { kBaseline = 0, kAvx2 = 1, kAvx512 = 2 };

// "baseline", "avx2", "avx512".
std::string_view IsaName(Isa isa);

// The best path this CPU supports (cpuid; kBaseline on non-x86 builds or compilers without the
// per-function target attributes).
Isa DetectedIsa();

// Whether the CPU can run `isa` (every path up to DetectedIsa()).
bool CpuSupports(Isa isa);

// The path the kernels take now (see above). Never throws: an invalid REPHOTO_ISA leaves the
// detected path (CheckIsaEnvironment reports it).
Isa ActiveIsa();

// Throws UsageError when REPHOTO_ISA is set to something other than baseline/avx2/avx512 or to a
// path this CPU lacks ("REPHOTO_ISA=avx512: this CPU has no AVX-512 (best path: avx2)").
void CheckIsaEnvironment();

// Every path this CPU can run, baseline first (for tests that compare the paths).
std::vector<Isa> SupportedIsas();

// The Embree device configuration that makes Embree use at most the active path's ISA
// ("max_isa=sse2", "max_isa=avx2", "max_isa=avx512"), for rtcNewDevice.
std::string EmbreeDeviceConfig();

// Forces `isa` for the whole process while alive (restores the previous path). Throws Error when
// the CPU lacks it.
class ScopedIsa {
 public:
  explicit ScopedIsa(Isa isa);
  ~ScopedIsa();
  ScopedIsa(const ScopedIsa&) = delete;
  ScopedIsa& operator=(const ScopedIsa&) = delete;

 private:
  Isa previous_;
};

}  // namespace rephoto::core

// Per-function target attributes for the two vector paths (GCC and clang on x86-64).
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define REPHOTO_HAVE_ISA_TARGETS 1
#define REPHOTO_TARGET_AVX512 __attribute__((target("arch=x86-64-v4")))
#define REPHOTO_TARGET_AVX2 __attribute__((target("arch=x86-64-v3")))
#else
#define REPHOTO_TARGET_AVX512
#define REPHOTO_TARGET_AVX2
#endif

// REPHOTO_ISA_DISPATCH(ret, Name, (params), (args)) defines `ret Name params` that calls
// `NameBody args` compiled for the active path. NameBody must be an always-inline function
// (`[[gnu::always_inline]] inline`) defined before; the three variants are NameAvx512, NameAvx2
// and NameBaseline (each the body inlined under that path's target attribute).
#if defined(REPHOTO_HAVE_ISA_TARGETS)
#define REPHOTO_ISA_DISPATCH(ret, Name, params, args)                       \
  REPHOTO_TARGET_AVX512 ret Name##Avx512 params { return Name##Body args; } \
  REPHOTO_TARGET_AVX2 ret Name##Avx2 params { return Name##Body args; }     \
  ret Name##Baseline params { return Name##Body args; }                     \
  ret Name params {                                                         \
    switch (::rephoto::core::ActiveIsa()) {                                 \
      case ::rephoto::core::Isa::kAvx512:                                   \
        return Name##Avx512 args;                                           \
      case ::rephoto::core::Isa::kAvx2:                                     \
        return Name##Avx2 args;                                             \
      case ::rephoto::core::Isa::kBaseline:                                 \
        break;                                                              \
    }                                                                       \
    return Name##Baseline args;                                             \
  }
// REPHOTO_ISA_DISPATCH_AVX2: the same with two variants, NameAvx2 (taken on the AVX2 and
// AVX-512 paths) and NameBaseline, for kernels whose AVX-512 version is a separate function.
#define REPHOTO_ISA_DISPATCH_AVX2(ret, Name, params, args)                 \
  REPHOTO_TARGET_AVX2 ret Name##Avx2 params { return Name##Body args; }    \
  ret Name##Baseline params { return Name##Body args; }                    \
  ret Name params {                                                        \
    if (::rephoto::core::ActiveIsa() != ::rephoto::core::Isa::kBaseline) { \
      return Name##Avx2 args;                                              \
    }                                                                      \
    return Name##Baseline args;                                            \
  }
#else
#define REPHOTO_ISA_DISPATCH(ret, Name, params, args) \
  ret Name params { return Name##Body args; }
#define REPHOTO_ISA_DISPATCH_AVX2(ret, Name, params, args) \
  ret Name params { return Name##Body args; }
#endif
