// Mipmapped RGB textures for rendering textured meshes.
//
// Texels are stored as 8-bit RGBA (texture files are 8-bit in practice; 16-bit/float textures
// are quantized to 8 bits), with a box-filtered mip pyramid down to 1x1 (odd sizes: the last
// row/column is clamped). Lookups are trilinear: bilinear within the two mip levels around the
// requested level of detail, with texel centres at (i + 0.5) / size, u/v repeating outside
// [0,1] (GL_REPEAT) and v = 0 at the bottom row of the image (OpenGL/OBJ convention).
//
// Thread safety: a Texture is immutable after construction; Sample/SampleLevel may be called from
// several threads at once.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "rephoto/core/image.h"

namespace rephoto::render {

class Texture {
 public:
  Texture() = default;
  // From an image with 1 to 4 channels, values in [0,1] (grey is replicated to RGB).
  explicit Texture(const Image& image);
  // Reads the image file (rephoto::io::ReadImage); throws Error naming the file.
  static Texture Read(const std::filesystem::path& path);

  int width() const { return levels_.empty() ? 0 : levels_[0].width; }
  int height() const { return levels_.empty() ? 0 : levels_[0].height; }
  int level_count() const { return static_cast<int>(levels_.size()); }

  // RGB in [0,1] at texture coordinates (u, v) and level of detail `lod` (0 = full resolution,
  // 1 = half, fractional values blend two levels; clamped to the available levels).
  Eigen::Vector3f Sample(float u, float v, float lod) const;
  // Bilinear lookup in one level.
  Eigen::Vector3f SampleLevel(int level, float u, float v) const;

 private:
  struct Level {
    int width = 0;
    int height = 0;
    std::vector<uint32_t> texels;  // RGBA8, row 0 = top row of the image
  };
  std::vector<Level> levels_;
};

}  // namespace rephoto::render
