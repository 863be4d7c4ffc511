#include "rephoto/render/texture.h"

#include <algorithm>
#include <cmath>

#include "rephoto/core/error.h"
#include "rephoto/io/image_io.h"

namespace rephoto::render {
namespace {

uint32_t Pack(float r, float g, float b) {
  auto q = [](float v) -> uint32_t {
    if (!(v > 0)) return 0;
    if (v >= 1) return 255;
    return static_cast<uint32_t>(std::lround(v * 255.0f));
  };
  return q(r) | (q(g) << 8) | (q(b) << 16) | (255u << 24);
}

inline void Unpack(uint32_t t, float* rgb) {
  rgb[0] = static_cast<float>(t & 255);
  rgb[1] = static_cast<float>((t >> 8) & 255);
  rgb[2] = static_cast<float>((t >> 16) & 255);
}

}  // namespace

Texture::Texture(const Image& image) {
  REPHOTO_CHECK(!image.empty() && image.channels() >= 1 && image.channels() <= 4,
                "texture: empty image or unsupported channel count {}", image.channels());
  Level base;
  base.width = image.width();
  base.height = image.height();
  base.texels.resize(image.pixel_count());
  const int c = image.channels();
  for (size_t i = 0; i < image.pixel_count(); ++i) {
    const float* p = image.data() + i * c;
    base.texels[i] = c >= 3 ? Pack(p[0], p[1], p[2]) : Pack(p[0], p[0], p[0]);
  }
  levels_.push_back(std::move(base));
  while (levels_.back().width > 1 || levels_.back().height > 1) {
    const Level& fine = levels_.back();
    Level coarse;
    coarse.width = std::max(1, fine.width / 2);
    coarse.height = std::max(1, fine.height / 2);
    coarse.texels.resize(static_cast<size_t>(coarse.width) * coarse.height);
    for (int y = 0; y < coarse.height; ++y) {
      const int y0 = std::min(2 * y, fine.height - 1), y1 = std::min(2 * y + 1, fine.height - 1);
      for (int x = 0; x < coarse.width; ++x) {
        const int x0 = std::min(2 * x, fine.width - 1), x1 = std::min(2 * x + 1, fine.width - 1);
        float sum[3] = {0, 0, 0}, rgb[3];
        for (uint32_t t : {fine.texels[static_cast<size_t>(y0) * fine.width + x0],
                           fine.texels[static_cast<size_t>(y0) * fine.width + x1],
                           fine.texels[static_cast<size_t>(y1) * fine.width + x0],
                           fine.texels[static_cast<size_t>(y1) * fine.width + x1]}) {
          Unpack(t, rgb);
          for (int k = 0; k < 3; ++k) sum[k] += rgb[k];
        }
        coarse.texels[static_cast<size_t>(y) * coarse.width + x] =
            Pack(sum[0] / 1020.0f, sum[1] / 1020.0f, sum[2] / 1020.0f);
      }
    }
    levels_.push_back(std::move(coarse));
  }
}

Texture Texture::Read(const std::filesystem::path& path) {
  const Image image = io::ReadImage(path);
  REPHOTO_CHECK(!image.empty(), "{}: empty texture image", path.string());
  return Texture(image);
}

Eigen::Vector3f Texture::SampleLevel(int level, float u, float v) const {
  const Level& l = levels_[level];
  // Texel space: x right from the left edge, y down from the top edge; centres at i + 0.5.
  const float x = (u - std::floor(u)) * l.width - 0.5f;
  const float y = ((1.0f - v) - std::floor(1.0f - v)) * l.height - 0.5f;
  const float fx = std::floor(x), fy = std::floor(y);
  const float ax = x - fx, ay = y - fy;
  auto wrap = [](int i, int n) { return i < 0 ? i + n : (i >= n ? i - n : i); };
  const int x0 = wrap(static_cast<int>(fx), l.width), x1 = wrap(static_cast<int>(fx) + 1, l.width);
  const int y0 = wrap(static_cast<int>(fy), l.height);
  const int y1 = wrap(static_cast<int>(fy) + 1, l.height);
  float a[3], b[3], c[3], d[3];
  Unpack(l.texels[static_cast<size_t>(y0) * l.width + x0], a);
  Unpack(l.texels[static_cast<size_t>(y0) * l.width + x1], b);
  Unpack(l.texels[static_cast<size_t>(y1) * l.width + x0], c);
  Unpack(l.texels[static_cast<size_t>(y1) * l.width + x1], d);
  Eigen::Vector3f out;
  for (int k = 0; k < 3; ++k) {
    const float top = a[k] + ax * (b[k] - a[k]);
    const float bottom = c[k] + ax * (d[k] - c[k]);
    out[k] = (top + ay * (bottom - top)) * (1.0f / 255.0f);
  }
  return out;
}

Eigen::Vector3f Texture::Sample(float u, float v, float lod) const {
  if (!std::isfinite(u) || !std::isfinite(v)) return Eigen::Vector3f::Zero();
  const int last = level_count() - 1;
  if (!(lod > 0)) return SampleLevel(0, u, v);
  if (lod >= last) return SampleLevel(last, u, v);
  const int level = static_cast<int>(lod);
  const float t = lod - level;
  return (1 - t) * SampleLevel(level, u, v) + t * SampleLevel(level + 1, u, v);
}

}  // namespace rephoto::render
