#include "rephoto/compare/resample.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"

namespace rephoto::compare {
namespace {

// The source pixels and weights of each output pixel along one axis.
struct AxisWeights {
  std::vector<int> first;     // per output pixel: index into `source`/`weight`
  std::vector<int> count;     // per output pixel: number of contributing source pixels
  std::vector<int> source;    // source pixel indices
  std::vector<float> weight;  // their weights (sum 1 per output pixel)
};

AxisWeights ComputeAxisWeights(int source_size, int target_size) {
  AxisWeights w;
  w.first.resize(target_size);
  w.count.resize(target_size);
  const double scale = static_cast<double>(source_size) / target_size;
  auto add = [&](int index, double weight) {
    if (weight <= 0) return;
    w.source.push_back(std::clamp(index, 0, source_size - 1));
    w.weight.push_back(static_cast<float>(weight));
  };
  for (int o = 0; o < target_size; ++o) {
    w.first[o] = static_cast<int>(w.source.size());
    if (source_size == target_size) {
      add(o, 1.0);
    } else if (scale > 1) {
      // Footprint [o, o + 1) * scale in source coordinates; weight = covered fraction.
      const double begin = o * scale, end = (o + 1) * scale;
      const int i0 = static_cast<int>(std::floor(begin));
      const int i1 = std::min(source_size - 1, static_cast<int>(std::ceil(end)) - 1);
      for (int i = i0; i <= i1; ++i) {
        add(i, (std::min<double>(end, i + 1) - std::max<double>(begin, i)) / scale);
      }
    } else {
      const double centre = (o + 0.5) * scale - 0.5;
      const int i0 = static_cast<int>(std::floor(centre));
      const double t = centre - i0;
      if (i0 < 0) {
        add(0, 1.0);
      } else if (i0 >= source_size - 1) {
        add(source_size - 1, 1.0);
      } else {
        add(i0, 1.0 - t);
        add(i0 + 1, t);
      }
    }
    w.count[o] = static_cast<int>(w.source.size()) - w.first[o];
  }
  return w;
}

// One row of the horizontal pass: out[x * C + c] = 0 + sum over the output pixel's sources, in
// their order, of weight * in[source * C + c].
template <int C>
void HorizontalRow(const float* __restrict in, const AxisWeights& wx, int width,
                   float* __restrict out) {
  const int* __restrict first = wx.first.data();
  const int* __restrict count = wx.count.data();
  const int* __restrict source = wx.source.data();
  const float* __restrict weight = wx.weight.data();
  for (int x = 0; x < width; ++x) {
    float acc[C];
    for (int c = 0; c < C; ++c) acc[c] = 0.f;
    for (int k = first[x]; k < first[x] + count[x]; ++k) {
      const float* px = in + static_cast<size_t>(source[k]) * C;
      for (int c = 0; c < C; ++c) acc[c] += weight[k] * px[c];
    }
    for (int c = 0; c < C; ++c) out[x * C + c] = acc[c];
  }
}

void HorizontalRowAny(const float* in, const AxisWeights& wx, int width, int channels,
                      float* out) {
  for (int x = 0; x < width; ++x) {
    for (int c = 0; c < channels; ++c) out[x * channels + c] = 0.f;
    for (int k = wx.first[x]; k < wx.first[x] + wx.count[x]; ++k) {
      const float* px = in + static_cast<size_t>(wx.source[k]) * channels;
      for (int c = 0; c < channels; ++c) out[x * channels + c] += wx.weight[k] * px[c];
    }
  }
}

void CheckTargetSize(int width, int height) {
  REPHOTO_CHECK(width > 0 && height > 0, "cannot resize to {}x{}", width, height);
}

}  // namespace

void ResizeImage(const Image& source, int width, int height, Image* target) {
  CheckTargetSize(width, height);
  REPHOTO_CHECK(!source.empty(), "cannot resize an empty image");
  const int channels = source.channels();
  const AxisWeights wx = ComputeAxisWeights(source.width(), width);
  const AxisWeights wy = ComputeAxisWeights(source.height(), height);
  // Horizontal pass over every source row, then vertical pass.
  Image rows(width, source.height(), channels);
  ParallelFor(0, source.height(), 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      const float* in = source.row(static_cast<int>(y));
      float* out = rows.row(static_cast<int>(y));
      switch (channels) {  // the channel loop unrolled for the common counts; same sums
        case 1:
          HorizontalRow<1>(in, wx, width, out);
          break;
        case 2:
          HorizontalRow<2>(in, wx, width, out);
          break;
        case 3:
          HorizontalRow<3>(in, wx, width, out);
          break;
        case 4:
          HorizontalRow<4>(in, wx, width, out);
          break;
        default:
          HorizontalRowAny(in, wx, width, channels, out);
      }
    }
  });
  target->Resize(width, height, channels);
  const size_t row_values = static_cast<size_t>(width) * channels;
  ParallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      float* out = target->row(static_cast<int>(y));
      std::fill(out, out + row_values, 0.f);
      for (int k = wy.first[y]; k < wy.first[y] + wy.count[y]; ++k) {
        const float* in = rows.row(wy.source[k]);
        const float weight = wy.weight[k];
        for (size_t i = 0; i < row_values; ++i) out[i] += weight * in[i];
      }
    }
  });
}

void ResizeMask(const Mask& source, int width, int height, Mask* target) {
  CheckTargetSize(width, height);
  REPHOTO_CHECK(!source.empty(), "cannot resize an empty mask");
  const AxisWeights wx = ComputeAxisWeights(source.width(), width);
  const AxisWeights wy = ComputeAxisWeights(source.height(), height);
  const int channels = source.channels();  // only the first channel is used
  Mask rows(width, source.height(), 1);
  ParallelFor(0, source.height(), 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      const uint8_t* in = source.row(static_cast<int>(y));
      uint8_t* out = rows.row(static_cast<int>(y));
      for (int x = 0; x < width; ++x) {
        uint8_t valid = 1;
        for (int k = wx.first[x]; k < wx.first[x] + wx.count[x]; ++k) {
          if (in[static_cast<size_t>(wx.source[k]) * channels] == 0) valid = 0;
        }
        out[x] = valid;
      }
    }
  });
  target->Resize(width, height, 1);
  ParallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      uint8_t* out = target->row(static_cast<int>(y));
      std::fill(out, out + width, uint8_t{1});
      for (int k = wy.first[y]; k < wy.first[y] + wy.count[y]; ++k) {
        const uint8_t* in = rows.row(wy.source[k]);
        for (int x = 0; x < width; ++x) out[x] &= in[x];
      }
    }
  });
}

}  // namespace rephoto::compare
