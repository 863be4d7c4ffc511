#include "rephoto/degrade/degrade.h"

#include <gtest/gtest.h>

#include <cmath>

#include "rephoto/core/error.h"
#include "rephoto/degrade/simplex_noise.h"
#include "rephoto/io/image_io.h"
#include "rephoto/testing/testing.h"

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

bool SameValues(const Image& a, const Image& b) {
  return a.SameSize(b) && a.channels() == b.channels() &&
         std::equal(a.data(), a.data() + a.size(), b.data());
}

// A unit quad in z = 0 whose texture coordinates are its (x, y): texel (i, j) of a w x h texture
// has its centre at u = (i + 0.5) / w, v = 1 - (j + 0.5) / h, i.e. at the surface point
// (u, v, 0). Wedge texture coordinates, one material with the given texture.
mesh::Mesh TexturedQuad(const std::filesystem::path& texture) {
  mesh::Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  m.wedge_texcoords = {{0, 0}, {1, 0}, {1, 1}, {0, 0}, {1, 1}, {0, 1}};
  m.materials.push_back({.name = "quad", .diffuse_texture = texture});
  return m;
}

TEST(Degrade, TexelNoiseOffsetsEachTexelByTheNoiseAtItsSurfacePoint) {
  const auto dir = testing::MakeTempDir();
  const int w = 40, h = 24;
  Image grey(w, h, 3);
  std::fill(grey.data(), grey.data() + grey.size(), 0.5f);
  io::WritePng(dir / "albedo.png", grey);
  const mesh::Mesh quad = TexturedQuad(dir / "albedo.png");

  DegradeOptions options;
  options.texture_noise = 0.2f;
  options.noise_frequency = 3;
  options.seed = 11;
  options.texture_dir = dir / "out";
  const mesh::Mesh noisy = Degrade(quad, options);
  ASSERT_EQ(noisy.materials.size(), 1u);
  EXPECT_EQ(noisy.materials[0].diffuse_texture, dir / "out" / "degraded_quad.png");
  EXPECT_EQ(noisy.positions, quad.positions);  // only colours change
  const Image result = io::ReadImage(noisy.materials[0].diffuse_texture);
  ASSERT_EQ(result.width(), w);
  ASSERT_EQ(result.height(), h);

  // Independent expectation: the bounding-box diagonal of the quad is sqrt(2), so the noise
  // is evaluated at (u, v, 0) * 3 / sqrt(2), channel c with seed 4 * 11 + 1 + c.
  const SimplexNoise noise[3] = {SimplexNoise(45), SimplexNoise(46), SimplexNoise(47)};
  const float to_noise = 3.f / std::sqrt(2.f);
  const float base = 128.f / 255.f;  // 0.5 as stored in the 8-bit PNG
  double largest_offset = 0;
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      const Eigen::Vector3f p((i + 0.5f) / w, 1.f - (j + 0.5f) / h, 0.f);
      for (int c = 0; c < 3; ++c) {
        const float expected = std::clamp(base + 0.2f * noise[c].Noise(p * to_noise), 0.f, 1.f);
        const float actual = result.at(i, j, c);
        // The texture was written at 8 bits.
        ASSERT_NEAR(actual, expected, 0.5 / 255 + 1e-6) << i << "," << j << " channel " << c;
        largest_offset = std::max(largest_offset, std::abs(double(actual) - base));
      }
    }
  }
  EXPECT_LE(largest_offset, 0.2 + 0.5 / 255);
  EXPECT_GT(largest_offset, 0.05);  // the noise is really there

  // Deterministic for a seed; another seed gives another texture.
  options.texture_prefix = "again";
  EXPECT_TRUE(
      SameValues(io::ReadImage(Degrade(quad, options).materials[0].diffuse_texture), result));
  options.seed = 12;
  options.texture_prefix = "other";
  EXPECT_FALSE(
      SameValues(io::ReadImage(Degrade(quad, options).materials[0].diffuse_texture), result));

  // Texel noise needs a folder to write to.
  options.texture_dir.clear();
  EXPECT_THROW(Degrade(quad, options), Error);
}

TEST(Degrade, SimplificationKeepsWedgeTexcoordsAndMaterials) {
  // Grid whose texture coordinate is the position, given per wedge, with the left half
  // (x < 0.5) material 0 and the right half material 1.
  mesh::Mesh grid = Grid(61);
  grid.colors.clear();
  for (size_t f = 0; f < grid.faces.size(); ++f) {
    Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3f& p = grid.positions[grid.faces[f][c]];
      grid.wedge_texcoords.emplace_back(p.x(), p.y());
      centroid += p / 3;
    }
    grid.face_materials.push_back(centroid.x() < 0.5f ? 0 : 1);
  }
  grid.materials = {{.name = "left"}, {.name = "right"}};
  DegradeOptions options;
  options.simplify = 0.8f;
  DegradeReport report;
  const mesh::Mesh simple = Degrade(grid, options, &report);
  simple.Validate("simplified");
  EXPECT_NEAR(double(simple.faces.size()) / double(grid.faces.size()), 0.2, 0.02);
  ASSERT_EQ(simple.face_materials.size(), simple.faces.size());
  ASSERT_EQ(simple.vertex_texcoords.size(), simple.positions.size());
  EXPECT_TRUE(simple.wedge_texcoords.empty());
  size_t left = 0, right = 0;
  for (size_t f = 0; f < simple.faces.size(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3f& p = simple.positions[simple.faces[f][c]];
      // Texture coordinates travel with their vertices.
      EXPECT_EQ(simple.Texcoord(f, c), Eigen::Vector2f(p.x(), p.y()));
      // A face keeps its material, so it stays on its half.
      if (simple.face_materials[f] == 0) {
        EXPECT_LE(p.x(), 0.5f);
      } else {
        EXPECT_GE(p.x(), 0.5f - 1e-6f);
      }
    }
    (simple.face_materials[f] == 0 ? left : right)++;
  }
  EXPECT_GT(left, 0u);
  EXPECT_GT(right, 0u);
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
