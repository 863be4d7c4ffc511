// A seeded random permutation that is the same on every machine, compiler and standard
// library: SplitMix64 (Steele, Lea, Flood 2014; Vigna's reference splitmix64.c) for the bits,
// unbiased bounded integers by rejection, Fisher-Yates for the shuffle. std::shuffle and
// std::uniform_int_distribution are implementation-defined and are not used.
//
// Thread safety: SeededShuffle is reentrant; a SplitMix64 is a plain mutable generator, one per
// thread.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

namespace rephoto::split {

class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  // The next 64 random bits (Vigna's splitmix64 next()).
  uint64_t Next() {
    uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  // Uniform integer in [0, bound), bound >= 1, without modulo bias: draws below
  // 2^64 mod bound are rejected.
  uint64_t UniformBelow(uint64_t bound) {
    const uint64_t threshold = (0 - bound) % bound;  // = 2^64 mod bound
    for (;;) {
      const uint64_t r = Next();
      if (r >= threshold) return r % bound;
    }
  }

 private:
  uint64_t state_;
};

// Fisher-Yates (Durstenfeld) shuffle: for i = n-1 .. 1 swap items[i] with items[j],
// j = UniformBelow(i + 1).
template <typename T>
void SeededShuffle(std::vector<T>& items, uint64_t seed) {
  SplitMix64 rng(seed);
  for (size_t i = items.size(); i > 1; --i) {
    const size_t j = static_cast<size_t>(rng.UniformBelow(i));
    std::swap(items[i - 1], items[j]);
  }
}

}  // namespace rephoto::split
