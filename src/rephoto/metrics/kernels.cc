#include "rephoto/metrics/kernels.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "rephoto/metrics/simd.h"

namespace rephoto::metrics::internal {

WindowValidityRows::WindowValidityRows(const Mask& valid, int width, int height, int radius)
    : valid_(valid),
      width_(width),
      height_(height),
      radius_(radius),
      column_invalid_(valid.empty() ? 0 : static_cast<size_t>(width), 0),
      row_(static_cast<size_t>(width), 0),
      span_(valid.empty() ? 0 : 2 * static_cast<size_t>(width), 0) {
  if (valid_.empty()) {
    std::fill(row_.begin() + std::min(radius, width),
              row_.begin() + std::max(std::min(radius, width), width - radius), 1);
  }
}

namespace {

[[gnu::always_inline]] inline void SlideCountsBody(const uint8_t* __restrict add,
                                                   const uint8_t* __restrict sub, int width,
                                                   int* __restrict counts) {
  for (int x = 0; x < width; ++x) counts[x] += (add[x] == 0) - (sub[x] == 0);
}
REPHOTO_ISA_DISPATCH(void, SlideCounts,
                     (const uint8_t* __restrict add, const uint8_t* __restrict sub, int width,
                      int* __restrict counts),
                     (add, sub, width, counts))

// out[x] for x in [r, width - r): 1 where counts[x - r .. x + r] are all 0. all[x] = 1 where
// columns [x, x + span) are all valid; the span doubles per pass and the window is the AND of
// two overlapping spans: log2(2r + 1) vectorised byte passes, ping-ponging between a and b.
[[gnu::always_inline]] inline void RowFromCountsBody(const int* __restrict counts, int width, int r,
                                                     uint8_t* __restrict a, uint8_t* __restrict b,
                                                     uint8_t* __restrict out) {
  const int window = 2 * r + 1;
  for (int x = 0; x < width; ++x) a[x] = counts[x] == 0;
  int span = 1;
  while (2 * span <= window) {
    for (int x = 0; x + 2 * span <= width; ++x) b[x] = a[x] & a[x + span];
    std::swap(a, b);
    span *= 2;
  }
  const int tail = window - span;
  for (int x = r; x < width - r; ++x) out[x] = a[x - r] & a[x - r + tail];
}
REPHOTO_ISA_DISPATCH(void, RowFromCounts,
                     (const int* __restrict counts, int width, int r, uint8_t* __restrict a,
                      uint8_t* __restrict b, uint8_t* __restrict out),
                     (counts, width, r, a, b, out))

}  // namespace

const uint8_t* WindowValidityRows::Row(int y) {
  if (valid_.empty()) return row_.data();
  const int r = radius_;
  if (y == last_y_ + 1) {
    SlideCounts(valid_.row(y + r), valid_.row(y - r - 1), width_, column_invalid_.data());
  } else {
    std::fill(column_invalid_.begin(), column_invalid_.end(), 0);
    for (int j = y - r; j <= y + r; ++j) {
      const uint8_t* row = valid_.row(j);
      for (int x = 0; x < width_; ++x) column_invalid_[x] += row[x] == 0;
    }
  }
  last_y_ = y;
  if (width_ < 2 * r + 1) return row_.data();
  RowFromCounts(column_invalid_.data(), width_, r, span_.data(), span_.data() + width_,
                row_.data());
  return row_.data();
}

namespace {

// The float io::ReadImage makes of each 8-bit value, k / 255.f: by ByteToUnitFloat's two
// products and a sum (the same bits as the division, kernels.h), which GCC vectorises at the
// width of each path.
[[gnu::always_inline]] inline void BytesToFloatsBody(const uint8_t* __restrict in, int n,
                                                     float* __restrict out) {
  for (int i = 0; i < n; ++i) out[i] = ByteToUnitFloat(static_cast<float>(in[i]));
}
REPHOTO_ISA_DISPATCH(void, BytesToFloats,
                     (const uint8_t* __restrict in, int n, float* __restrict out), (in, n, out))

// The same for RGBA pixels, alpha dropped.
[[gnu::always_inline]] inline void RgbaBytesToFloatsBody(const uint8_t* __restrict in, int w,
                                                         float* __restrict out) {
  for (int x = 0; x < w; ++x) {
    out[3 * x] = ByteToUnitFloat(static_cast<float>(in[4 * x]));
    out[3 * x + 1] = ByteToUnitFloat(static_cast<float>(in[4 * x + 1]));
    out[3 * x + 2] = ByteToUnitFloat(static_cast<float>(in[4 * x + 2]));
  }
}
REPHOTO_ISA_DISPATCH(void, RgbaBytesToFloats,
                     (const uint8_t* __restrict in, int w, float* __restrict out), (in, w, out))

}  // namespace

void RgbRows::Load(const RgbView& image, int first, int end, std::vector<float>* scratch,
                   bool floats) {
  const int w = image.width(), channels = image.channels();
  first = std::max(first, 0);
  end = std::min(end, image.height());
  bytes_ = image.bytes();
  byte_stride_ = static_cast<ptrdiff_t>(w) * channels;
  channels_ = channels;
  if (image.floats() && channels == 3) {
    base_ = image.floats();
    first_ = 0;
    stride_ = static_cast<ptrdiff_t>(3) * w;
    return;
  }
  if (!floats && image.bytes()) {
    base_ = nullptr;
    return;
  }
  const size_t values = static_cast<size_t>(std::max(0, end - first)) * 3 * w;
  if (scratch->size() < values) scratch->resize(values);
  float* out = scratch->data();
  if (image.bytes()) {
    for (int y = first; y < end; ++y) {
      const uint8_t* in = image.bytes() + static_cast<size_t>(y) * w * channels;
      float* o = out + static_cast<size_t>(y - first) * 3 * w;
      if (channels == 3) {
        BytesToFloats(in, 3 * w, o);
      } else {
        RgbaBytesToFloats(in, w, o);
      }
    }
  } else {
    for (int y = first; y < end; ++y) {
      const float* in = image.floats() + static_cast<size_t>(y) * w * channels;
      float* o = out + static_cast<size_t>(y - first) * 3 * w;
      for (int x = 0; x < w; ++x) {
        o[3 * x] = in[channels * x];
        o[3 * x + 1] = in[channels * x + 1];
        o[3 * x + 2] = in[channels * x + 2];
      }
    }
  }
  base_ = out;
  first_ = first;
  stride_ = static_cast<ptrdiff_t>(3) * w;
}

std::vector<float> FilterWeights(int radius, double sigma) {
  std::vector<double> w(static_cast<size_t>(2 * radius + 1));
  double total = 0;
  for (int k = -radius; k <= radius; ++k) {
    const double v = sigma > 0 ? std::exp(-0.5 * k * k / (sigma * sigma)) : 1.0;
    w[k + radius] = v;
    total += v;
  }
  std::vector<float> out(w.size());
  for (size_t i = 0; i < w.size(); ++i) out[i] = static_cast<float>(w[i] / total);
  return out;
}

namespace {

// Eight partial sums break the add latency chain; their order is fixed: acc[j] holds the
// values at x = begin + 8 i + j, with +0.0 added where ok is 0. The masked values go through a
// scratch row (`kept`, vectorised select) and are summed as two 4-wide double vectors
// (acc[0..3], acc[4..7]): the same additions as the scalar loop `acc[j] += ok ? double(v) : 0.0`
// it replaces, which GCC left scalar.
typedef double V4d __attribute__((vector_size(32)));
typedef float V4f __attribute__((vector_size(16)));
[[gnu::always_inline]] inline double MaskRangeKeptBody(const float* __restrict values,
                                                       const uint8_t* __restrict ok, int begin,
                                                       int end, float* __restrict out,
                                                       float* __restrict kept) {
  for (int x = begin; x < end; ++x) {
    out[x] = ok[x] ? values[x] : kNaN;
    kept[x] = ok[x] ? values[x] : 0.0f;
  }
  V4d acc0 = {}, acc1 = {};
  int x = begin;
  for (; x + 8 <= end; x += 8) {
    acc0 += __builtin_convertvector(REPHOTO_LOAD(V4f, kept + x), V4d);
    acc1 += __builtin_convertvector(REPHOTO_LOAD(V4f, kept + x + 4), V4d);
  }
  double acc[8] = {acc0[0], acc0[1], acc0[2], acc0[3], acc1[0], acc1[1], acc1[2], acc1[3]};
  for (; x < end; ++x) acc[0] += kept[x];
  return ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
}
REPHOTO_ISA_DISPATCH(double, MaskRangeKept,
                     (const float* __restrict values, const uint8_t* __restrict ok, int begin,
                      int end, float* __restrict out, float* __restrict kept),
                     (values, ok, begin, end, out, kept))

}  // namespace

double MaskRange(const float* values, const uint8_t* ok, int begin, int end, float* out) {
  thread_local std::vector<float> kept;
  return MaskRangeKept(values, ok, begin, end, out, Scratch(kept, static_cast<size_t>(end)));
}

void FillNaN(float* row, int width) { std::fill(row, row + width, kNaN); }

}  // namespace rephoto::metrics::internal
