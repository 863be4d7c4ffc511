#include "rephoto/degrade/degrade.h"

#include <gtest/gtest.h>

#include <cmath>

#include "rephoto/core/error.h"
#include "rephoto/degrade/simplex_noise.h"

namespace rephoto::degrade {
namespace {

// A flat n x n grid in the z = 0 plane, unit square, grey, normals +z.
mesh::Mesh Grid(int n) {
  mesh::Mesh m;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      m.positions.emplace_back(float(x) / (n - 1), float(y) / (n - 1), 0.f);
      m.colors.emplace_back(0.5f, 0.5f, 0.5f);
    }
  }
  for (int y = 0; y + 1 < n; ++y) {
    for (int x = 0; x + 1 < n; ++x) {
      const uint32_t a = y * n + x, b = a + 1, c = a + n, d = c + 1;
      m.faces.push_back({a, b, d});
      m.faces.push_back({a, d, c});
    }
  }
  return m;
}

TEST(SimplexNoise, ZeroAtLatticePointsBoundedAndSmooth) {
  const SimplexNoise noise(7);
  // A simplex-grid vertex has zero gradient contribution and every other corner is farther
  // than the kernel radius (squared distance 0.75 > 0.6), so the noise vanishes there.
  EXPECT_FLOAT_EQ(noise.Noise(0, 0, 0), 0.f);
  float low = 0, high = 0;
  uint64_t state = 1;
  for (int i = 0; i < 200000; ++i) {
    const float x = float(UniformDouble(state) * 50), y = float(UniformDouble(state) * 50),
                z = float(UniformDouble(state) * 50);
    const float v = noise.Noise(x, y, z);
    low = std::min(low, v);
    high = std::max(high, v);
    // Lipschitz: the kernel's gradient is bounded, so a tiny step changes the value little.
    EXPECT_LT(std::abs(noise.Noise(x + 1e-3f, y, z) - v), 0.02f);
  }
  EXPECT_GE(low, -1.f);
  EXPECT_LE(high, 1.f);
  EXPECT_LT(low, -0.7f);  // the range is actually used
  EXPECT_GT(high, 0.7f);
}

TEST(SimplexNoise, SeedDeterminesTheField) {
  const SimplexNoise a(1), b(1), c(2);
  EXPECT_EQ(a.Noise(0.3f, 1.7f, 2.2f), b.Noise(0.3f, 1.7f, 2.2f));
  EXPECT_NE(a.Noise(0.3f, 1.7f, 2.2f), c.Noise(0.3f, 1.7f, 2.2f));
}

TEST(Degrade, TextureNoiseOffsetsEachChannelByAtMostN) {
  const mesh::Mesh grid = Grid(101);
  DegradeOptions options;
  options.texture_noise = 0.2f;
  options.seed = 3;
  const mesh::Mesh noisy = Degrade(grid, options);
  double mean_abs = 0;
  for (size_t v = 0; v < grid.colors.size(); ++v) {
    for (int c = 0; c < 3; ++c) {
      const float d = noisy.colors[v][c] - grid.colors[v][c];
      EXPECT_LE(std::abs(d), 0.2f + 1e-6f);
      mean_abs += std::abs(d);
    }
    EXPECT_EQ(noisy.positions[v], grid.positions[v]);
  }
  mean_abs /= 3.0 * grid.colors.size();
  EXPECT_GT(mean_abs, 0.02);
  // Same seed, same result; other seed, other result.
  EXPECT_EQ(Degrade(grid, options).colors, noisy.colors);
  options.seed = 4;
  EXPECT_NE(Degrade(grid, options).colors, noisy.colors);
}

TEST(Degrade, GeometryNoiseMovesAlongNormalsWithinTheExtentFraction) {
  const mesh::Mesh grid = Grid(81);
  DegradeOptions options;
  options.geometry_noise = 0.01f;
  DegradeReport report;
  const mesh::Mesh noisy = Degrade(grid, options, &report);
  EXPECT_NEAR(report.extent, std::sqrt(2.0), 1e-6);
  float max_offset = 0;
  for (size_t v = 0; v < grid.positions.size(); ++v) {
    const Eigen::Vector3f d = noisy.positions[v] - grid.positions[v];
    EXPECT_FLOAT_EQ(d.x(), 0.f);  // along the +z normal only
    EXPECT_FLOAT_EQ(d.y(), 0.f);
    max_offset = std::max(max_offset, std::abs(d.z()));
  }
  EXPECT_LE(max_offset, 0.01f * std::sqrt(2.f) + 1e-6f);
  EXPECT_GT(max_offset, 0.005f);
  EXPECT_EQ(noisy.colors, grid.colors);
}

TEST(Degrade, SimplificationRemovesTheRequestedFractionAndKeepsColours) {
  mesh::Mesh grid = Grid(101);
  for (size_t v = 0; v < grid.positions.size(); ++v) {
    grid.colors[v] = Eigen::Vector3f(grid.positions[v].x(), grid.positions[v].y(), 0.25f);
  }
  DegradeOptions options;
  options.simplify = 0.9f;
  DegradeReport report;
  const mesh::Mesh simple = Degrade(grid, options, &report);
  EXPECT_NEAR(report.removed_fraction, 0.9, 0.03);
  EXPECT_EQ(simple.positions.size(), simple.colors.size());
  simple.Validate("simplified");
  // Colours travel with their vertices.
  for (size_t v = 0; v < simple.positions.size(); ++v) {
    EXPECT_FLOAT_EQ(simple.colors[v].x(), simple.positions[v].x());
    EXPECT_FLOAT_EQ(simple.colors[v].y(), simple.positions[v].y());
  }
}

TEST(Degrade, ImpossibleRequestsAreErrors) {
  mesh::Mesh points;
  points.positions = {{0, 0, 0}, {1, 0, 0}};
  DegradeOptions options;
  options.simplify = 0.5f;
  EXPECT_THROW(Degrade(points, options), Error);
  options = {};
  options.texture_noise = 0.1f;
  EXPECT_THROW(Degrade(points, options), Error);  // no colours
  options = {};
  options.simplify = 1.5f;
  EXPECT_THROW(Degrade(Grid(3), options), Error);
}

}  // namespace
}  // namespace rephoto::degrade
