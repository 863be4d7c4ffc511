#include "rephoto/ibr/image_ops.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"

namespace rephoto::ibr::internal {
namespace {

// Weights of the source samples covering output sample i of an axis shrunk from n to m.
struct AxisTap {
  int first = 0;
  std::vector<float> weights;
};

std::vector<AxisTap> AreaTaps(int n, int m) {
  std::vector<AxisTap> taps(m);
  const double scale = static_cast<double>(n) / m;
  for (int i = 0; i < m; ++i) {
    const double a = i * scale, b = (i + 1) * scale;
    const int first = static_cast<int>(std::floor(a));
    const int last = std::min(n - 1, static_cast<int>(std::ceil(b)) - 1);
    taps[i].first = first;
    for (int s = first; s <= last; ++s) {
      const double overlap = std::min<double>(b, s + 1) - std::max<double>(a, s);
      taps[i].weights.push_back(static_cast<float>(std::max(0.0, overlap) / scale));
    }
  }
  return taps;
}

}  // namespace

Image ShrinkArea(const Image& source, int width, int height) {
  REPHOTO_CHECK(width > 0 && height > 0 && width <= source.width() && height <= source.height(),
                "ShrinkArea: cannot shrink {}x{} to {}x{}", source.width(), source.height(), width,
                height);
  if (width == source.width() && height == source.height()) return source;
  const int c = source.channels();
  const std::vector<AxisTap> tx = AreaTaps(source.width(), width);
  const std::vector<AxisTap> ty = AreaTaps(source.height(), height);
  // Horizontal pass into a (width x source height) image, then vertical.
  Image horizontal(width, source.height(), c);
  ParallelFor(0, source.height(), 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      const float* in = source.row(static_cast<int>(y));
      float* out = horizontal.row(static_cast<int>(y));
      for (int x = 0; x < width; ++x) {
        for (int k = 0; k < c; ++k) out[x * c + k] = 0;
        const AxisTap& tap = tx[x];
        for (size_t s = 0; s < tap.weights.size(); ++s) {
          const float* p = in + static_cast<size_t>(tap.first + static_cast<int>(s)) * c;
          for (int k = 0; k < c; ++k) out[x * c + k] += tap.weights[s] * p[k];
        }
      }
    }
  });
  Image out(width, height, c);
  ParallelFor(0, height, 8, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      float* o = out.row(static_cast<int>(y));
      const AxisTap& tap = ty[y];
      for (size_t s = 0; s < tap.weights.size(); ++s) {
        const float* in = horizontal.row(tap.first + static_cast<int>(s));
        const float w = tap.weights[s];
        for (int i = 0; i < width * c; ++i) o[i] += w * in[i];
      }
    }
  });
  return out;
}

Image Luma(const Image& image) {
  Image grey(image.width(), image.height(), 1);
  const int c = image.channels();
  for (size_t i = 0; i < image.pixel_count(); ++i) {
    const float* p = image.data() + i * c;
    grey.data()[i] = c >= 3 ? 0.299f * p[0] + 0.587f * p[1] + 0.114f * p[2] : p[0];
  }
  return grey;
}

}  // namespace rephoto::ibr::internal
