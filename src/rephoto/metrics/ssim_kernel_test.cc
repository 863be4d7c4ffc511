// The fused SSIM kernel (the default) against the earlier five-quantity kernel it replaced
// (internal::SsimKernel): the same error images up to float rounding, NaN at the same pixels,
// exactly 1 for identical images, on random images of sizes around the vector widths and the
// strip width, for the radii with a compile-time kernel (3, 5) and others, and on real photos.
// Agreement with scikit-image is checked in metrics_skimage_test.cc.
//
// The two kernels round differently, and float32 moments lose most where a window is nearly
// flat (sigma^2 ~ 1e-6 next to c2 = 9e-4): there one pixel's SSIM may differ by ~1e-4. The fused
// kernel shifts each strip's values by their mean (ssim.cc), the earlier one by 0.5, so over
// large flat regions (sky) the earlier one's mean drifts. Measured (AVX-512 and AVX2 builds
// alike): random images up to 2e-5 per pixel and 3.1e-6 in the mean; Sceaux 00005 against 00006
// 1.4e-4 and 1.7e-6, against its shifted copy 1.8e-4 and 5.5e-7. scikit-image in float64
// (/usr/bin/python3 structural_similarity, gaussian_weights, sigma 1.5, population covariance,
// on the same float32 values) gives DSSIM 0.2004737393 and 0.0419631722 for these two pairs:
// the fused kernel is off by 2.7e-9 and 1.4e-8, the earlier one by 8.5e-7 and 2.9e-7. The
// bounds below are a few times the measured differences.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "rephoto/metrics/kernels.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/testing/testing.h"
#if REPHOTO_HAVE_IO
#include "rephoto/io/image_io.h"
#endif

namespace rephoto::metrics {
namespace {

using internal::SsimKernel;

std::vector<MetricResult> WithKernel(SsimKernel kernel, const Image& p, const Image& q,
                                     const Mask& valid, const MetricOptions& options) {
  internal::SetSsimKernel(kernel);
  auto results = ComputeMetrics(p, q, valid, {Metric::kSsim, Metric::kDssim}, options);
  internal::SetSsimKernel(SsimKernel::kFused);
  return results;
}

struct Difference {
  double max_pixel = 0;                   // largest |fused - five-quantity| of an error-image pixel
  double mean = 0;                        // |difference| of the means
  double fused_dssim = 0, old_dssim = 0;  // the DSSIM means (the last compared)
};

// Compares the SSIM and DSSIM results of both kernels; NaN pixels must coincide.
Difference CompareKernels(const Image& p, const Image& q, const Mask& valid,
                          const MetricOptions& options) {
  const auto fused = WithKernel(SsimKernel::kFused, p, q, valid, options);
  const auto old = WithKernel(SsimKernel::kFiveQuantities, p, q, valid, options);
  Difference d;
  d.fused_dssim = fused[1].mean;
  d.old_dssim = old[1].mean;
  for (size_t m = 0; m < fused.size(); ++m) {
    EXPECT_EQ(fused[m].evaluated, old[m].evaluated);
    d.mean = std::max(d.mean, std::abs(fused[m].mean - old[m].mean));
    const float* a = fused[m].error.data();
    const float* b = old[m].error.data();
    for (size_t i = 0; i < fused[m].error.size(); ++i) {
      EXPECT_EQ(std::isnan(a[i]), std::isnan(b[i])) << "pixel " << i;
      if (!std::isnan(a[i]) && !std::isnan(b[i])) {
        d.max_pixel = std::max(d.max_pixel, static_cast<double>(std::abs(a[i] - b[i])));
      }
    }
  }
  return d;
}

Image RandomImage(int w, int h, std::mt19937_64& rng, float smooth) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Image img(w, h, 3);
  const float phase = u(rng) * 6.0f;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float s = 0.5f + 0.4f * std::sin(0.11f * x + 0.07f * y + phase + c);
        img.at(x, y, c) = std::clamp(smooth * s + (1 - smooth) * u(rng), 0.0f, 1.0f);
      }
    }
  }
  return img;
}

MetricOptions Options(int window, bool gaussian, double sigma) {
  MetricOptions o;
  o.ssim_window = window;
  o.ssim_gaussian = gaussian;
  o.ssim_sigma = sigma;
  return o;
}

const std::vector<MetricOptions>& AllOptions() {
  static const std::vector<MetricOptions> all = {
      Options(11, true, 1.5),  // default: radius 5, compile-time kernel
      Options(7, false, 0),    // scikit-image's default: radius 3, compile-time kernel
      Options(9, true, 1.2),   // radius 4: runtime radius
      Options(3, false, 0),    // radius 1
      Options(13, true, 2.0),  // radius 6
  };
  return all;
}

TEST(SsimKernel, FusedAgreesWithFiveQuantityKernelOnRandomImages) {
  std::mt19937_64 rng = testing::MakeRng();
  // Widths around the vector widths (8, 16 values = 2.7, 5.3 pixels), the 256-pixel strips and
  // the window; heights around the band (32 rows) and the vertical block (4 rows).
  const int sizes[][2] = {{3, 3},  {5, 9},    {11, 11},  {12, 40},  {17, 13}, {40, 23},
                          {64, 5}, {257, 37}, {300, 70}, {531, 45}, {20, 129}};
  Difference worst;
  for (const auto& size : sizes) {
    const int w = size[0], h = size[1];
    for (const float smooth : {0.0f, 0.9f}) {
      const Image p = RandomImage(w, h, rng, smooth);
      Image q = RandomImage(w, h, rng, smooth);
      for (size_t i = 0; i < q.size(); ++i) q.data()[i] = 0.5f * q.data()[i] + 0.5f * p.data()[i];
      Mask valid(w, h, 1, 1);
      std::bernoulli_distribution drop(0.02);
      for (size_t i = 0; i < valid.size(); ++i) valid.data()[i] = drop(rng) ? 0 : 1;
      for (const MetricOptions& o : AllOptions()) {
        SCOPED_TRACE(::testing::Message()
                     << w << "x" << h << " window " << o.ssim_window << " smooth " << smooth);
        for (const Mask* m :
             {static_cast<const Mask*>(&valid), static_cast<const Mask*>(nullptr)}) {
          const Difference d = CompareKernels(p, q, m ? *m : Mask(), o);
          EXPECT_LT(d.max_pixel, 5e-5);
          EXPECT_LT(d.mean, 1e-5);
          worst.max_pixel = std::max(worst.max_pixel, d.max_pixel);
          worst.mean = std::max(worst.mean, d.mean);
        }
      }
    }
  }
  std::printf("random images: largest |fused - five-quantity| pixel %.3g, mean %.3g\n",
              worst.max_pixel, worst.mean);
}

TEST(SsimKernel, IdenticalImagesGiveExactlyOne) {
  std::mt19937_64 rng = testing::MakeRng();
  for (const MetricOptions& o : AllOptions()) {
    const Image p = RandomImage(300, 41, rng, 0.5f);
    const auto r = WithKernel(SsimKernel::kFused, p, p, Mask(), o);
    ASSERT_GT(r[0].evaluated, 0u);
    for (size_t i = 0; i < r[0].error.size(); ++i) {
      if (std::isnan(r[0].error.data()[i])) continue;
      ASSERT_EQ(r[0].error.data()[i], 1.0f) << "window " << o.ssim_window << " pixel " << i;
      ASSERT_EQ(r[1].error.data()[i], 0.0f) << "window " << o.ssim_window << " pixel " << i;
    }
    EXPECT_EQ(r[0].mean, 1.0);
    EXPECT_EQ(r[1].mean, 0.0);
  }
}

#if REPHOTO_HAVE_IO
// Two photos of the Sceaux castle (2832x2128, neighbouring views: a dissimilar pair), and one
// photo against a 8-bit copy of itself darkened and shifted by a pixel (a similar pair).
TEST(SsimKernel, FusedAgreesWithFiveQuantityKernelOnRealPhotos) {
  REPHOTO_REQUIRE_DATA("openmvs_sceaux/images");
  const auto dir = testing::SharedDataDir() / "openmvs_sceaux/images";
  const Image a = io::ReadImage(dir / "00005.jpg");
  const Image b = io::ReadImage(dir / "00006.jpg");
  ASSERT_EQ(a.width(), b.width());
  ASSERT_EQ(a.height(), b.height());
  Image shifted(a.width(), a.height(), 3);
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      for (int c = 0; c < 3; ++c) {
        const float v = 0.9f * a.at(std::min(x + 1, a.width() - 1), y, c) + 0.02f;
        shifted.at(x, y, c) = std::round(v * 255.0f) / 255.0f;
      }
    }
  }
  const MetricOptions defaults;
  for (const Image* q : {&b, static_cast<const Image*>(&shifted)}) {
    const Difference d = CompareKernels(a, *q, Mask(), defaults);
    std::printf(
        "sceaux 00005 vs %s: largest |fused - five-quantity| pixel %.3g, mean %.3g; DSSIM "
        "fused %.10f five-quantity %.10f\n",
        q == &b ? "00006" : "its shifted copy", d.max_pixel, d.mean, d.fused_dssim, d.old_dssim);
    EXPECT_LT(d.max_pixel, 5e-4);
    EXPECT_LT(d.mean, 3e-5);
  }
}
#endif

}  // namespace
}  // namespace rephoto::metrics
