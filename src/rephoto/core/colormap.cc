#include "rephoto/core/colormap.h"

#include <algorithm>
#include <cmath>

#include "rephoto/core/parallel.h"

namespace rephoto {

std::array<float, 3> JetColor(float t) {
  if (std::isnan(t)) return {0.f, 0.f, 0.f};
  t = std::clamp(t, 0.f, 1.f);
  // Piecewise-linear ramps of MATLAB's jet: each channel is a trapezoid.
  auto ramp = [t](float centre) {
    return std::clamp(1.5f - std::abs(4.f * t - centre), 0.f, 1.f);
  };
  return {ramp(3.f), ramp(2.f), ramp(1.f)};
}

Image ApplyJet(const Image& values, float low, float high) {
  Image out(values.width(), values.height(), 4);
  const float scale = high > low ? 1.f / (high - low) : 0.f;
  ParallelFor(0, values.height(), 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      const float* in = values.row(static_cast<int>(y));
      float* px = out.row(static_cast<int>(y));
      for (int x = 0; x < values.width(); ++x) {
        const float v = in[x * values.channels()];
        if (std::isnan(v)) {
          px[4 * x] = px[4 * x + 1] = px[4 * x + 2] = px[4 * x + 3] = 0.f;
          continue;
        }
        const auto c = JetColor((v - low) * scale);
        px[4 * x] = c[0];
        px[4 * x + 1] = c[1];
        px[4 * x + 2] = c[2];
        px[4 * x + 3] = 1.f;
      }
    }
  });
  return out;
}

}  // namespace rephoto
