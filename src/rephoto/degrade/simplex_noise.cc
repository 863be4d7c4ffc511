#include "rephoto/degrade/simplex_noise.h"

#include <cmath>
#include <utility>

namespace rephoto::degrade {
namespace {

// The 12 edge midpoints of a cube: gradient directions of 3D simplex noise.
constexpr int kGradients[12][3] = {{1, 1, 0}, {-1, 1, 0}, {1, -1, 0}, {-1, -1, 0},
                                   {1, 0, 1}, {-1, 0, 1}, {1, 0, -1}, {-1, 0, -1},
                                   {0, 1, 1}, {0, -1, 1}, {0, 1, -1}, {0, -1, -1}};

inline float Corner(int gradient, float x, float y, float z) {
  float t = 0.6f - x * x - y * y - z * z;
  if (t < 0) return 0.f;
  const int* g = kGradients[gradient % 12];
  t *= t;
  return t * t * (static_cast<float>(g[0]) * x + static_cast<float>(g[1]) * y +
                  static_cast<float>(g[2]) * z);
}

}  // namespace

SimplexNoise::SimplexNoise(uint64_t seed) {
  std::array<uint8_t, 256> p;
  for (int i = 0; i < 256; ++i) p[i] = static_cast<uint8_t>(i);
  uint64_t state = seed;
  for (int i = 255; i > 0; --i) {
    const int j = static_cast<int>(SplitMix64(state) % static_cast<uint64_t>(i + 1));
    std::swap(p[i], p[j]);
  }
  for (int i = 0; i < 512; ++i) perm_[i] = p[i & 255];
}

float SimplexNoise::Noise(float xin, float yin, float zin) const {
  constexpr float kSkew = 1.f / 3.f;
  constexpr float kUnskew = 1.f / 6.f;
  // Skew the input space to find the simplex cell.
  const float s = (xin + yin + zin) * kSkew;
  const int i = static_cast<int>(std::floor(xin + s));
  const int j = static_cast<int>(std::floor(yin + s));
  const int k = static_cast<int>(std::floor(zin + s));
  const float t = static_cast<float>(i + j + k) * kUnskew;
  const float x0 = xin - (static_cast<float>(i) - t);
  const float y0 = yin - (static_cast<float>(j) - t);
  const float z0 = zin - (static_cast<float>(k) - t);
  // Which of the six tetrahedra of the cube holds the point.
  int i1, j1, k1, i2, j2, k2;
  if (x0 >= y0) {
    if (y0 >= z0) {
      i1 = 1, j1 = 0, k1 = 0, i2 = 1, j2 = 1, k2 = 0;
    } else if (x0 >= z0) {
      i1 = 1, j1 = 0, k1 = 0, i2 = 1, j2 = 0, k2 = 1;
    } else {
      i1 = 0, j1 = 0, k1 = 1, i2 = 1, j2 = 0, k2 = 1;
    }
  } else {
    if (y0 < z0) {
      i1 = 0, j1 = 0, k1 = 1, i2 = 0, j2 = 1, k2 = 1;
    } else if (x0 < z0) {
      i1 = 0, j1 = 1, k1 = 0, i2 = 0, j2 = 1, k2 = 1;
    } else {
      i1 = 0, j1 = 1, k1 = 0, i2 = 1, j2 = 1, k2 = 0;
    }
  }
  const float x1 = x0 - i1 + kUnskew, y1 = y0 - j1 + kUnskew, z1 = z0 - k1 + kUnskew;
  const float x2 = x0 - i2 + 2 * kUnskew, y2 = y0 - j2 + 2 * kUnskew, z2 = z0 - k2 + 2 * kUnskew;
  const float x3 = x0 - 1 + 3 * kUnskew, y3 = y0 - 1 + 3 * kUnskew, z3 = z0 - 1 + 3 * kUnskew;
  const int ii = i & 255, jj = j & 255, kk = k & 255;
  const int g0 = perm_[ii + perm_[jj + perm_[kk]]];
  const int g1 = perm_[ii + i1 + perm_[jj + j1 + perm_[kk + k1]]];
  const int g2 = perm_[ii + i2 + perm_[jj + j2 + perm_[kk + k2]]];
  const int g3 = perm_[ii + 1 + perm_[jj + 1 + perm_[kk + 1]]];
  return 32.f * (Corner(g0, x0, y0, z0) + Corner(g1, x1, y1, z1) + Corner(g2, x2, y2, z2) +
                 Corner(g3, x3, y3, z3));
}

}  // namespace rephoto::degrade
