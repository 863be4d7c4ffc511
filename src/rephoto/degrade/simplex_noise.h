// 3D simplex noise (Perlin 2002, "Improving noise"; the simplex-grid formulation of Gustavson,
// "Simplex noise demystified", 2005), seeded so that defects are reproducible on any machine.
//
// Noise(p) is a smooth function of the position p with values in about [-1, 1] (the exact
// extremes of this kernel are within +-1; Noise is scaled by 32 as in Gustavson's reference) and
// a feature size of about 1 unit: scale positions to choose the frequency.
//
// Thread safety: a SimplexNoise is immutable after construction; Noise may be called from several
// threads at once. The SplitMix64/UniformDouble helpers advance the state they are given: one state
// per thread.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>

namespace rephoto::degrade {

class SimplexNoise {
 public:
  // The permutation table is a Fisher-Yates shuffle of 0..255 driven by splitmix64(seed), so a
  // seed gives the same noise on every platform and compiler.
  explicit SimplexNoise(uint64_t seed);

  float Noise(float x, float y, float z) const;
  float Noise(const Eigen::Vector3f& p) const { return Noise(p.x(), p.y(), p.z()); }

 private:
  std::array<uint8_t, 512> perm_{};
};

// splitmix64 step: a portable 64-bit generator used for every seeded choice in rephoto's
// synthetic data (std:: distributions are implementation-defined and would differ by platform).
inline uint64_t SplitMix64(uint64_t& state) {
  uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// Uniform double in [0, 1) from splitmix64 (53 random bits).
inline double UniformDouble(uint64_t& state) {
  return static_cast<double>(SplitMix64(state) >> 11) * (1.0 / 9007199254740992.0);
}

}  // namespace rephoto::degrade
