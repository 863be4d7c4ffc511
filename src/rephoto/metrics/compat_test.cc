#include "rephoto/metrics/compat.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "rephoto/core/error.h"
#include "rephoto/metrics/metrics.h"

namespace rephoto::metrics {
namespace {

Image RandomImage(int width, int height, int channels, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uniform(0.f, 1.f);
  Image image(width, height, channels);
  for (size_t i = 0; i < image.size(); ++i) image.data()[i] = uniform(rng);
  return image;
}

// Direct 2D SSIM of one position (no separable filter), the padding done by index mapping.
double DirectSsim(CompatPreset preset, const Image& a, const Image& b, int x, int y, int c) {
  double w1[11], sum = 0;
  for (int k = 0; k < 11; ++k) sum += (w1[k] = std::exp(-(k - 5) * (k - 5) / 4.5));
  double m[5] = {0, 0, 0, 0, 0};
  for (int dy = -5; dy <= 5; ++dy) {
    for (int dx = -5; dx <= 5; ++dx) {
      int sx = x + dx, sy = y + dy;
      if (preset == CompatPreset::kNerfstudio) {
        sx = sx < 0 ? -sx : (sx >= a.width() ? 2 * (a.width() - 1) - sx : sx);
        sy = sy < 0 ? -sy : (sy >= a.height() ? 2 * (a.height() - 1) - sy : sy);
      } else if (sx < 0 || sy < 0 || sx >= a.width() || sy >= a.height()) {
        continue;
      }
      const double w = w1[dx + 5] * w1[dy + 5] / (sum * sum);
      const double p = a.at(sx, sy, c), q = b.at(sx, sy, c);
      m[0] += w * p, m[1] += w * q, m[2] += w * p * p, m[3] += w * q * q, m[4] += w * p * q;
    }
  }
  double vx = m[2] - m[0] * m[0], vy = m[3] - m[1] * m[1];
  if (preset == CompatPreset::kNerfstudio) vx = std::max(vx, 0.0), vy = std::max(vy, 0.0);
  const double cov = m[4] - m[0] * m[1];
  return ((2 * m[0] * m[1] + 1e-4) * (2 * cov + 9e-4)) /
         ((m[0] * m[0] + m[1] * m[1] + 1e-4) * (vx + vy + 9e-4));
}

TEST(CompatTest, ParsesPresetNames) {
  EXPECT_EQ(ParseCompatPreset("3DGS"), CompatPreset::k3dgs);
  EXPECT_EQ(ParseCompatPreset("nerfstudio"), CompatPreset::kNerfstudio);
  EXPECT_FALSE(ParseCompatPreset("mipnerf").has_value());
}

TEST(CompatTest, MatchesDirectWindowSumsIncludingBorders) {
  const Image a = RandomImage(37, 70, 3, 1), b = RandomImage(37, 70, 4, 2);
  for (CompatPreset preset : {CompatPreset::k3dgs, CompatPreset::kNerfstudio}) {
    Image map;
    const CompatResult r = ComputeCompatMetrics(preset, a, b, nullptr, &map);
    double total = 0, se = 0;
    for (int y = 0; y < a.height(); ++y) {
      for (int x = 0; x < a.width(); ++x) {
        double pixel = 0;
        for (int c = 0; c < 3; ++c) {
          pixel += DirectSsim(preset, a, b, x, y, c);
          se += std::pow(double(a.at(x, y, c)) - b.at(x, y, c), 2);
        }
        total += pixel;
        EXPECT_NEAR(map.at(x, y), pixel / 3, 1e-6) << x << "," << y;
      }
    }
    EXPECT_NEAR(r.ssim, total / (a.pixel_count() * 3), 1e-12);
    EXPECT_NEAR(r.psnr, 10 * std::log10(a.pixel_count() * 3 / se), 1e-10);
  }
}

TEST(CompatTest, NerfstudioInteriorEqualsCroppedGaussianSsimOfMetrics) {
  // Away from the border both presets and rephoto's own Gaussian SSIM see the same windows.
  const Image a = RandomImage(40, 30, 3, 3), b = RandomImage(40, 30, 3, 4);
  Image zero_padded, reflected;
  ComputeCompatMetrics(CompatPreset::k3dgs, a, b, nullptr, &zero_padded);
  ComputeCompatMetrics(CompatPreset::kNerfstudio, a, b, nullptr, &reflected);
  const MetricResult own = ComputeMetric(Metric::kSsim, a, b, Mask());
  for (int y = 5; y < 25; ++y) {
    for (int x = 5; x < 35; ++x) {
      EXPECT_NEAR(zero_padded.at(x, y), reflected.at(x, y), 1e-6);
      EXPECT_NEAR(own.error.at(x, y), reflected.at(x, y), 1e-4);
    }
  }
  EXPECT_NE(zero_padded.at(0, 0), reflected.at(0, 0));
}

TEST(CompatTest, IdenticalImagesAndCompositing) {
  const Image a = RandomImage(16, 9, 3, 5);
  const CompatResult r = ComputeCompatMetrics(CompatPreset::k3dgs, a, a);
  EXPECT_TRUE(std::isinf(r.psnr));
  EXPECT_NEAR(r.ssim, 1.0, 1e-12);
  Image rgba(1, 1, 4);
  rgba.at(0, 0, 0) = 1, rgba.at(0, 0, 1) = 0.5f, rgba.at(0, 0, 2) = 0, rgba.at(0, 0, 3) = 0.25f;
  const Image rgb = CompositeOverBackground(rgba, {1, 1, 1});
  EXPECT_FLOAT_EQ(rgb.at(0, 0, 0), 1.0f);
  EXPECT_FLOAT_EQ(rgb.at(0, 0, 1), 0.875f);
  EXPECT_FLOAT_EQ(rgb.at(0, 0, 2), 0.75f);
}

TEST(CompatTest, RejectsMismatchesAndTinyImagesForReflectPadding) {
  EXPECT_THROW(ComputeCompatMetrics(CompatPreset::k3dgs, Image(4, 4, 3), Image(5, 4, 3)), Error);
  EXPECT_THROW(ComputeCompatMetrics(CompatPreset::kNerfstudio, Image(5, 9, 3), Image(5, 9, 3)),
               Error);
}

}  // namespace
}  // namespace rephoto::metrics
