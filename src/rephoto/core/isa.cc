#include "rephoto/core/isa.h"

#include <atomic>
#include <cstdlib>

#include "rephoto/core/error.h"

namespace rephoto::core {
namespace {

Isa Detect() {
#if defined(REPHOTO_HAVE_ISA_TARGETS)
  __builtin_cpu_init();
  // x86-64-v3 also has F16C, MOVBE and LZCNT, which every CPU with AVX2 + FMA + BMI2 has
  // (clang 14's __builtin_cpu_supports does not know the first two).
  const bool v3 = __builtin_cpu_supports("avx") && __builtin_cpu_supports("avx2") &&
                  __builtin_cpu_supports("fma") && __builtin_cpu_supports("bmi") &&
                  __builtin_cpu_supports("bmi2");
  const bool v4 = v3 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                  __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl") &&
                  __builtin_cpu_supports("avx512cd");
  return v4 ? Isa::kAvx512 : v3 ? Isa::kAvx2 : Isa::kBaseline;
#else
  return Isa::kBaseline;
#endif
}

bool ParseIsa(std::string_view text, Isa* isa) {
  for (Isa candidate : {Isa::kBaseline, Isa::kAvx2, Isa::kAvx512}) {
    if (text == IsaName(candidate)) {
      *isa = candidate;
      return true;
    }
  }
  return false;
}

// The path REPHOTO_ISA asks for, or the detected one when unset or invalid.
Isa FromEnvironment() {
  const char* text = std::getenv("REPHOTO_ISA");
  Isa isa;
  if (text == nullptr || *text == '\0' || !ParseIsa(text, &isa) || !CpuSupports(isa)) {
    return DetectedIsa();
  }
  return isa;
}

std::atomic<int>& Active() {
  static std::atomic<int> active{static_cast<int>(FromEnvironment())};
  return active;
}

}  // namespace

std::string_view IsaName(Isa isa) {
  switch (isa) {
    case Isa::kAvx512:
      return "avx512";
    case Isa::kAvx2:
      return "avx2";
    case Isa::kBaseline:
      break;
  }
  return "baseline";
}

Isa DetectedIsa() {
  static const Isa detected = Detect();
  return detected;
}

bool CpuSupports(Isa isa) { return static_cast<int>(isa) <= static_cast<int>(DetectedIsa()); }

Isa ActiveIsa() { return static_cast<Isa>(Active().load(std::memory_order_relaxed)); }

void CheckIsaEnvironment() {
  const char* text = std::getenv("REPHOTO_ISA");
  if (text == nullptr || *text == '\0') return;
  Isa isa;
  if (!ParseIsa(text, &isa)) {
    throw UsageError(fmt::format("REPHOTO_ISA={}: must be baseline, avx2 or avx512", text));
  }
  if (!CpuSupports(isa)) {
    throw UsageError(fmt::format("REPHOTO_ISA={}: this CPU cannot run that path (best path: {})",
                                 text, IsaName(DetectedIsa())));
  }
}

std::vector<Isa> SupportedIsas() {
  std::vector<Isa> isas;
  for (Isa isa : {Isa::kBaseline, Isa::kAvx2, Isa::kAvx512}) {
    if (CpuSupports(isa)) isas.push_back(isa);
  }
  return isas;
}

std::string EmbreeDeviceConfig() {
  switch (ActiveIsa()) {
    case Isa::kAvx512:
      return "max_isa=avx512";
    case Isa::kAvx2:
      return "max_isa=avx2";
    case Isa::kBaseline:
      break;
  }
  return "max_isa=sse2";
}

ScopedIsa::ScopedIsa(Isa isa) : previous_(ActiveIsa()) {
  if (!CpuSupports(isa)) {
    ThrowError("ISA path {}: this CPU cannot run it (best path: {})", IsaName(isa),
               IsaName(DetectedIsa()));
  }
  Active().store(static_cast<int>(isa), std::memory_order_relaxed);
}

ScopedIsa::~ScopedIsa() { Active().store(static_cast<int>(previous_), std::memory_order_relaxed); }

}  // namespace rephoto::core
