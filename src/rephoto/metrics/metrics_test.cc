#include "rephoto/metrics/metrics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
#include "rephoto/core/parallel.h"
#include "rephoto/metrics/icid.h"
#include "rephoto/metrics/kernels.h"
#include "rephoto/testing/testing.h"

namespace rephoto::metrics {
namespace {

Image RandomImage(std::mt19937_64& rng, int w, int h, bool quantized = false) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::uniform_int_distribution<int> q(0, 255);
  Image img(w, h, 3);
  for (size_t i = 0; i < img.size(); ++i) {
    img.data()[i] = quantized ? static_cast<float>(q(rng)) / 255.0f : u(rng);
  }
  return img;
}

// A smooth image plus noise, so windows have a realistic mix of flat and textured content.
Image SmoothImage(std::mt19937_64& rng, int w, int h, float noise) {
  std::normal_distribution<float> n(0.0f, noise);
  Image img(w, h, 3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float v = 0.5f + 0.3f * std::sin(0.2f * x + 0.7f * c) * std::cos(0.15f * y) + n(rng);
        img.at(x, y, c) = std::clamp(v, 0.0f, 1.0f);
      }
    }
  }
  return img;
}

Mask RandomMask(std::mt19937_64& rng, int w, int h, double keep) {
  std::bernoulli_distribution b(keep);
  Mask m(w, h, 1);
  for (size_t i = 0; i < m.size(); ++i) m.data()[i] = b(rng);
  return m;
}

// ---- Naive references: one plain loop per window, everything in double. ----

using WindowFn = std::function<double(const Image&, const Image&, int x, int y, int r)>;

// Expected error image of a window metric: NaN where the window leaves the image or touches an
// invalid pixel.
std::vector<double> NaiveWindowMetric(const Image& p, const Image& q, const Mask& valid, int window,
                                      const WindowFn& fn) {
  const int r = window / 2;
  std::vector<double> out(p.pixel_count(), std::nan(""));
  for (int y = r; y < p.height() - r; ++y) {
    for (int x = r; x < p.width() - r; ++x) {
      bool ok = true;
      for (int dy = -r; dy <= r; ++dy) {
        for (int dx = -r; dx <= r; ++dx) ok = ok && (valid.empty() || valid.at(x + dx, y + dy));
      }
      if (ok) out[static_cast<size_t>(y) * p.width() + x] = fn(p, q, x, y, r);
    }
  }
  return out;
}

double NaiveNcc(const Image& p, const Image& q, int x, int y, int r) {
  const double n = (2 * r + 1) * (2 * r + 1);
  double num = 0, dp = 0, dq = 0;
  for (int c = 0; c < 3; ++c) {
    double mp = 0, mq = 0;
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        mp += p.at(x + dx, y + dy, c) / n;
        mq += q.at(x + dx, y + dy, c) / n;
      }
    }
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const double a = p.at(x + dx, y + dy, c) - mp, b = q.at(x + dx, y + dy, c) - mq;
        num += a * b;
        dp += a * a;
        dq += b * b;
      }
    }
  }
  const double flat = MetricOptions().ncc_flat_threshold;
  if (dp <= flat && dq <= flat) return 0;
  if (dp <= flat || dq <= flat) return 1;
  return 1 - num / std::sqrt(dp * dq);
}

double NaiveZssd(const Image& p, const Image& q, int x, int y, int r) {
  const double n = (2 * r + 1) * (2 * r + 1);
  double total = 0;
  for (int c = 0; c < 3; ++c) {
    double mp = 0, mq = 0;
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        mp += p.at(x + dx, y + dy, c) / n;
        mq += q.at(x + dx, y + dy, c) / n;
      }
    }
    double s = 0;
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const double d = (p.at(x + dx, y + dy, c) - mp) - (q.at(x + dx, y + dy, c) - mq);
        s += d * d;
      }
    }
    total += s / n;
  }
  return total / 3;
}

// kernels.h CensusKey: luma in fixed point, floor((255000 Y + 0.5) / 4) with 255000 Y clamped
// to [0, 255000], in the float arithmetic the definition states for float inputs (for 8-bit
// values it is the integer rule, CensusKeysOfEveryEightBitColour).
long CensusLevel(const Image& img, int x, int y) {
  const float r = img.at(x, y, 0), g = img.at(x, y, 1), b = img.at(x, y, 2);
  float t = 76245.f * r + 149685.f * g + 29070.f * b;
  if (!(t >= 0.f)) t = 0.f;
  if (t > 255000.f) t = 255000.f;
  return static_cast<long>(std::floor((t + 0.5f) * 0.25f));
}
double NaiveCensus(const Image& p, const Image& q, int x, int y, int r) {
  int differ = 0;
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      if (dx == 0 && dy == 0) continue;
      const bool bp = CensusLevel(p, x + dx, y + dy) < CensusLevel(p, x, y);
      const bool bq = CensusLevel(q, x + dx, y + dy) < CensusLevel(q, x, y);
      differ += bp != bq;
    }
  }
  const int n = (2 * r + 1) * (2 * r + 1);
  return static_cast<double>(differ) / (n - 1);
}

// SSIM averaged over channels; weights either Gaussian (population covariance) or uniform
// (sample covariance), like scikit-image.
double NaiveSsim(const Image& p, const Image& q, int x, int y, int r, bool gaussian, double sigma) {
  std::vector<double> w(2 * r + 1);
  double total = 0;
  for (int k = -r; k <= r; ++k)
    total += w[k + r] = gaussian ? std::exp(-k * k / (2 * sigma * sigma)) : 1.0;
  for (double& v : w) v /= total;
  const double n = (2.0 * r + 1) * (2.0 * r + 1);
  const double norm = gaussian ? 1.0 : n / (n - 1);
  double ssim = 0;
  for (int c = 0; c < 3; ++c) {
    double mx = 0, my = 0, mxx = 0, myy = 0, mxy = 0;
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const double wt = w[dx + r] * w[dy + r];
        const double a = p.at(x + dx, y + dy, c), b = q.at(x + dx, y + dy, c);
        mx += wt * a;
        my += wt * b;
        mxx += wt * a * a;
        myy += wt * b * b;
        mxy += wt * a * b;
      }
    }
    const double vx = norm * (mxx - mx * mx), vy = norm * (myy - my * my);
    const double vxy = norm * (mxy - mx * my);
    const double c1 = 1e-4, c2 = 9e-4;
    ssim += (2 * mx * my + c1) * (2 * vxy + c2) / ((mx * mx + my * my + c1) * (vx + vy + c2)) / 3;
  }
  return ssim;
}

// iCID per window, straight from the formulas in icid.h (CIELAB from SrgbToLab, whose values
// are checked against scikit-image separately).
double NaiveIcid(const Image& p, const Image& q, int x, int y, int r) {
  const double sigma = 2.0;
  std::vector<double> w(2 * r + 1);
  double total = 0;
  for (int k = -r; k <= r; ++k) total += w[k + r] = std::exp(-k * k / (2 * sigma * sigma));
  for (double& v : w) v /= total;
  double m[11] = {};
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      const double wt = w[dx + r] * w[dy + r];
      double a[3], b[3];
      SrgbToLab(p.at(x + dx, y + dy, 0), p.at(x + dx, y + dy, 1), p.at(x + dx, y + dy, 2), a);
      SrgbToLab(q.at(x + dx, y + dy, 0), q.at(x + dx, y + dy, 1), q.at(x + dx, y + dy, 2), b);
      const double ca = std::hypot(a[1], a[2]), cb = std::hypot(b[1], b[2]);
      const double dh2 =
          (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]) - (ca - cb) * (ca - cb);
      const double v[11] = {a[0],
                            b[0],
                            ca,
                            cb,
                            a[0] * a[0],
                            b[0] * b[0],
                            ca * ca,
                            cb * cb,
                            a[0] * b[0],
                            ca * cb,
                            std::sqrt(std::max(0.0, dh2))};
      for (int i = 0; i < 11; ++i) m[i] += wt * v[i];
    }
  }
  const double sl1 = std::max(0.0, m[4] - m[0] * m[0]), sl2 = std::max(0.0, m[5] - m[1] * m[1]);
  const double sc1 = std::max(0.0, m[6] - m[2] * m[2]), sc2 = std::max(0.0, m[7] - m[3] * m[3]);
  const double sl12 = m[8] - m[0] * m[1], sc12 = m[9] - m[2] * m[3];
  const double dl = m[0] - m[1], dc = m[2] - m[3], dh = m[10];
  const double t1 = 1 / (0.002 * dl * dl + 1);
  const double t2 = (10 + 2 * std::sqrt(sl1) * std::sqrt(sl2)) / (10 + sl1 + sl2);
  const double t3 = (10 + std::abs(sl12)) / (10 + std::sqrt(sl1) * std::sqrt(sl2));
  const double t4 = 1 / (0.002 * dc * dc + 1);
  const double t5 = 1 / (0.002 * dh * dh + 1);
  const double t6 = (10 + 2 * std::sqrt(sc1) * std::sqrt(sc2)) / (10 + sc1 + sc2);
  const double t7 = (10 + std::abs(sc12)) / (10 + std::sqrt(sc1) * std::sqrt(sc2));
  return 1 - t1 * t2 * t3 * t3 * t3 * t4 * t5 * t6 * t7;
}

void ExpectMatches(const MetricResult& got, const std::vector<double>& expected, double tol,
                   const char* what) {
  double sum = 0;
  size_t n = 0;
  double worst = 0;
  for (size_t i = 0; i < expected.size(); ++i) {
    const float g = got.error.data()[i];
    if (std::isnan(expected[i])) {
      ASSERT_TRUE(std::isnan(g)) << what << " pixel " << i << " should not be evaluated";
      continue;
    }
    ASSERT_FALSE(std::isnan(g)) << what << " pixel " << i << " should be evaluated";
    worst = std::max(worst, std::abs(g - expected[i]));
    sum += expected[i];
    ++n;
  }
  EXPECT_LE(worst, tol) << what;
  ASSERT_EQ(got.evaluated, n) << what;
  ASSERT_GT(n, 0u) << what;
  EXPECT_NEAR(got.mean, sum / n, tol) << what;
}

struct Case {
  const char* name;
  Image photo, rephoto;
  Mask valid;
};

std::vector<Case> RandomCases(std::mt19937_64& rng) {
  std::vector<Case> cases;
  cases.push_back({"random", RandomImage(rng, 41, 27), RandomImage(rng, 41, 27), {}});
  cases.push_back({"random masked", RandomImage(rng, 41, 27), RandomImage(rng, 41, 27),
                   RandomMask(rng, 41, 27, 0.99)});
  Image smooth = SmoothImage(rng, 53, 31, 0.01f);
  Image smooth2 = SmoothImage(rng, 53, 31, 0.03f);
  cases.push_back({"smooth masked", smooth, smooth2, RandomMask(rng, 53, 31, 0.995)});
  return cases;
}

TEST(Metrics, WindowMetricsMatchNaiveLoops) {
  auto rng = testing::MakeRng();
  for (const Case& c : RandomCases(rng)) {
    SCOPED_TRACE(c.name);
    MetricOptions options;
    for (int window : {3, 9}) {
      options.window = window;
      const auto results =
          ComputeMetrics(c.photo, c.rephoto, c.valid,
                         {Metric::kOneMinusNcc, Metric::kZssd, Metric::kCensus}, options);
      ExpectMatches(results[0], NaiveWindowMetric(c.photo, c.rephoto, c.valid, window, NaiveNcc),
                    1e-5, "1-ncc");
      ExpectMatches(results[1], NaiveWindowMetric(c.photo, c.rephoto, c.valid, window, NaiveZssd),
                    1e-6, "zssd");
      ExpectMatches(results[2], NaiveWindowMetric(c.photo, c.rephoto, c.valid, window, NaiveCensus),
                    1e-7, "census");
      // Census alone takes a different path through the shared window pass.
      const MetricResult alone =
          ComputeMetric(Metric::kCensus, c.photo, c.rephoto, c.valid, options);
      ExpectMatches(alone, NaiveWindowMetric(c.photo, c.rephoto, c.valid, window, NaiveCensus),
                    1e-7, "census alone");
    }
  }
}

TEST(Metrics, SsimMatchesNaiveLoops) {
  auto rng = testing::MakeRng();
  for (const Case& c : RandomCases(rng)) {
    SCOPED_TRACE(c.name);
    for (bool gaussian : {true, false}) {
      MetricOptions options;
      options.ssim_gaussian = gaussian;
      options.ssim_window = gaussian ? 11 : 7;
      const auto results =
          ComputeMetrics(c.photo, c.rephoto, c.valid, {Metric::kSsim, Metric::kDssim}, options);
      const auto expected =
          NaiveWindowMetric(c.photo, c.rephoto, c.valid, options.ssim_window,
                            [&](const Image& p, const Image& q, int x, int y, int r) {
                              return NaiveSsim(p, q, x, y, r, gaussian, options.ssim_sigma);
                            });
      std::vector<double> dssim(expected.size());
      for (size_t i = 0; i < expected.size(); ++i) dssim[i] = (1 - expected[i]) / 2;
      ExpectMatches(results[0], expected, 2e-5, gaussian ? "ssim gaussian" : "ssim uniform");
      ExpectMatches(results[1], dssim, 1e-5, gaussian ? "dssim gaussian" : "dssim uniform");
    }
  }
}

TEST(Metrics, IcidMatchesNaiveLoop) {
  auto rng = testing::MakeRng();
  for (const Case& c : RandomCases(rng)) {
    SCOPED_TRACE(c.name);
    const MetricResult got = ComputeMetric(Metric::kIcid, c.photo, c.rephoto, c.valid);
    ExpectMatches(got, NaiveWindowMetric(c.photo, c.rephoto, c.valid, 11, NaiveIcid), 1e-6, "icid");
  }
}

// Wider than the column strips of the SSIM (256 pixels) and iCID (128 pixels) passes, with a
// partial last strip, and wider than the 16-pixel vectors of census: every strip boundary and
// vector tail against the naive loops.
TEST(Metrics, WideImagesMatchNaiveLoopsAcrossStripsAndVectorTails) {
  auto rng = testing::MakeRng();
  const int w = 301, h = 15;
  const Image photo = SmoothImage(rng, w, h, 0.02f);
  const Image rephoto = SmoothImage(rng, w, h, 0.03f);
  const Mask valid = RandomMask(rng, w, h, 0.995);
  const auto results =
      ComputeMetrics(photo, rephoto, valid, {Metric::kSsim, Metric::kIcid, Metric::kCensus}, {});
  MetricOptions defaults;
  ExpectMatches(results[0],
                NaiveWindowMetric(photo, rephoto, valid, defaults.ssim_window,
                                  [&](const Image& p, const Image& q, int x, int y, int r) {
                                    return NaiveSsim(p, q, x, y, r, true, defaults.ssim_sigma);
                                  }),
                2e-5, "ssim");
  ExpectMatches(results[1], NaiveWindowMetric(photo, rephoto, valid, 11, NaiveIcid), 1e-6, "icid");
  ExpectMatches(results[2], NaiveWindowMetric(photo, rephoto, valid, defaults.window, NaiveCensus),
                1e-7, "census");
}

TEST(Metrics, PixelMetricsMatchDefinitions) {
  auto rng = testing::MakeRng();
  for (const Case& c : RandomCases(rng)) {
    SCOPED_TRACE(c.name);
    const auto results =
        ComputeMetrics(c.photo, c.rephoto, c.valid, {Metric::kCbCr, Metric::kPsnr});
    std::vector<double> cbcr(c.photo.pixel_count(), std::nan("")), sq = cbcr;
    double mse = 0;
    size_t n = 0;
    for (int y = 0; y < c.photo.height(); ++y) {
      for (int x = 0; x < c.photo.width(); ++x) {
        if (!c.valid.empty() && !c.valid.at(x, y)) continue;
        // JPEG's full-range YCbCr of each image, then the difference.
        auto ycbcr = [](const Image& img, int x, int y, double out[3]) {
          const double r = img.at(x, y, 0), g = img.at(x, y, 1), b = img.at(x, y, 2);
          out[0] = 0.299 * r + 0.587 * g + 0.114 * b;
          out[1] = 0.5 - 0.168736 * r - 0.331264 * g + 0.5 * b;
          out[2] = 0.5 + 0.5 * r - 0.418688 * g - 0.081312 * b;
        };
        double a[3], b[3];
        ycbcr(c.photo, x, y, a);
        ycbcr(c.rephoto, x, y, b);
        const size_t i = static_cast<size_t>(y) * c.photo.width() + x;
        cbcr[i] = std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]);
        double e = 0;
        for (int ch = 0; ch < 3; ++ch) {
          const double d = static_cast<double>(c.photo.at(x, y, ch)) - c.rephoto.at(x, y, ch);
          e += d * d / 3;
        }
        sq[i] = e;
        mse += e;
        ++n;
      }
    }
    ExpectMatches(results[0], cbcr, 1e-6, "cb+cr");
    ASSERT_EQ(results[1].evaluated, n);
    EXPECT_NEAR(results[1].mean, 10 * std::log10(n / mse), 1e-9);
    for (size_t i = 0; i < sq.size(); ++i) {
      if (std::isnan(sq[i])) {
        EXPECT_TRUE(std::isnan(results[1].error.data()[i]));
      } else {
        EXPECT_NEAR(results[1].error.data()[i], sq[i], 1e-7);
      }
    }
  }
}

TEST(Metrics, IdenticalImagesGiveExactlyZero) {
  auto rng = testing::MakeRng();
  const Image img = SmoothImage(rng, 48, 40, 0.02f);
  const Mask mask = RandomMask(rng, 48, 40, 0.995);
  for (const MetricResult& res : ComputeMetrics(img, img, mask, AllMetrics())) {
    SCOPED_TRACE(std::string(MetricName(res.metric)));
    ASSERT_GT(res.evaluated, 0u);
    if (res.metric == Metric::kPsnr) {
      EXPECT_TRUE(std::isinf(res.mean) && res.mean > 0);
    } else if (res.metric == Metric::kSsim) {
      EXPECT_EQ(res.mean, 1.0);
    } else {
      EXPECT_EQ(res.mean, 0.0);
    }
    for (size_t i = 0; i < res.error.size(); ++i) {
      const float v = res.error.data()[i];
      if (!std::isnan(v)) {
        ASSERT_EQ(v, res.metric == Metric::kSsim ? 1.0f : 0.0f) << i;
      }
    }
  }
}

// Regression: iCID's contrast terms once rounded 10 + a + b twice and gave 2e-16 instead of 0 on
// identical dark, noisy 8-bit content (like the near-black parts of a photo).
// iCID's float CIELAB (icid.h): the cube root within 1 ulp of the correctly rounded one
// (std::cbrt in double, rounded to float) on every 97th float of [2^-7, 2^2) and on a sweep up to
// 2^40; L*, a* and b* of every 8-bit colour within 1e-4 of SrgbToLab's double formulas (a* and b*
// are 500 and 200 times a difference of two cube roots of ~1: 6e-8 each in float; measured 7.2e-5).
TEST(Metrics, IcidFloatLabFollowsTheDoubleFormulas) {
  int worst_ulps = 0;
  auto check = [&](float x) {
    const float got = internal::CubeRootFloat(x);
    const float want = static_cast<float>(std::cbrt(static_cast<double>(x)));
    int32_t a, b;
    std::memcpy(&a, &got, 4);
    std::memcpy(&b, &want, 4);
    worst_ulps = std::max(worst_ulps, std::abs(a - b));
  };
  for (float x = 0x1p-7f; x < 4.f; x = std::nextafter(x, 8.f)) {
    check(x);
    for (int k = 0; k < 96; ++k) x = std::nextafter(x, 8.f);
  }
  for (float x = 0x1p-7f; x < 0x1p40f; x *= 1.0001f) check(x);
  EXPECT_LE(worst_ulps, 1);

  auto decode = [](double c) {  // IEC 61966-2-1, written out here
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
  };
  const int w = 256 * 256;
  std::vector<double> linear(3 * w);
  std::vector<float> lab(3 * w);
  double worst = 0;
  for (int r = 0; r < 256; ++r) {
    for (int g = 0; g < 256; ++g) {
      for (int b = 0; b < 256; ++b) {
        const int x = 256 * g + b;
        linear[x] = decode(static_cast<float>(r) / 255.f);
        linear[w + x] = decode(static_cast<float>(g) / 255.f);
        linear[2 * w + x] = decode(static_cast<float>(b) / 255.f);
      }
    }
    internal::LinearRgbToLabFloat(linear.data(), w, lab.data());
    for (int g = 0; g < 256; ++g) {
      for (int b = 0; b < 256; ++b) {
        const int x = 256 * g + b;
        double want[3];
        SrgbToLab(static_cast<float>(r) / 255.f, static_cast<float>(g) / 255.f,
                  static_cast<float>(b) / 255.f, want);
        for (int c = 0; c < 3; ++c) {
          worst = std::max(worst, std::abs(lab[static_cast<size_t>(c) * w + x] - want[c]));
        }
      }
    }
  }
  EXPECT_LT(worst, 1e-4);
  std::printf("float CIELAB: cube root within %d ulp, L*a*b* within %.3g of the double formulas\n",
              worst_ulps, worst);
}

TEST(Metrics, IcidIsExactlyZeroOnIdenticalDarkNoisyImages) {
  auto rng = testing::MakeRng();
  std::uniform_int_distribution<int> level(0, 6);
  Image img(64, 48, 3);
  for (size_t i = 0; i < img.size(); ++i) img.data()[i] = static_cast<float>(level(rng)) / 255.f;
  const MetricResult res = ComputeMetric(Metric::kIcid, img, img, {});
  ASSERT_GT(res.evaluated, 0u);
  EXPECT_EQ(res.mean, 0.0);
}

// Grey 8-bit values (R = G = B = k / 255): two different lumas are at least 1/255 apart, so
// after a gain of 0.6 still far more than census's key step (1/63750) apart.
Image RandomGreyImage(std::mt19937_64& rng, int w, int h) {
  std::uniform_int_distribution<int> q(0, 255);
  Image img(w, h, 3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float v = static_cast<float>(q(rng)) / 255.0f;
      for (int c = 0; c < 3; ++c) img.at(x, y, c) = v;
    }
  }
  return img;
}

TEST(Metrics, NccAndCensusInvariantUnderGainAndOffset) {
  auto rng = testing::MakeRng();
  // 8-bit values, so no two different lumas are closer than the rounding of gain * v + offset
  // (census: nor closer than its key step, see RandomGreyImage).
  const Image photo = RandomGreyImage(rng, 40, 30);
  const Image rephoto = RandomGreyImage(rng, 40, 30);
  Image changed = rephoto;
  for (size_t i = 0; i < changed.size(); ++i) changed.data()[i] = 0.6f * changed.data()[i] + 0.3f;
  const std::vector<Metric> set = {Metric::kOneMinusNcc, Metric::kCensus, Metric::kZssd};
  const auto before = ComputeMetrics(photo, rephoto, {}, set);
  const auto after = ComputeMetrics(photo, changed, {}, set);
  for (int m = 0; m < 2; ++m) {
    for (size_t i = 0; i < before[m].error.size(); ++i) {
      const float a = before[m].error.data()[i], b = after[m].error.data()[i];
      if (std::isnan(a)) {
        ASSERT_TRUE(std::isnan(b));
      } else {
        ASSERT_NEAR(a, b, 1e-6) << MetricName(set[m]) << " at " << i;
      }
    }
  }
  // ZSSD: offset only.
  Image shifted = rephoto;
  for (size_t i = 0; i < shifted.size(); ++i) shifted.data()[i] += 0.25f;
  const MetricResult z0 = ComputeMetric(Metric::kZssd, photo, rephoto, {});
  const MetricResult z1 = ComputeMetric(Metric::kZssd, photo, shifted, {});
  EXPECT_NEAR(z0.mean, z1.mean, 1e-6);
  for (size_t i = 0; i < z0.error.size(); ++i) {
    if (!std::isnan(z0.error.data()[i])) {
      ASSERT_NEAR(z0.error.data()[i], z1.error.data()[i], 1e-6);
    }
  }
}

// Every 8-bit colour: the key of its floats k / 255.f (the census path of float images) is the
// integer luma (299 R + 587 G + 114 B) >> 2 (the path of 8-bit images), so that an 8-bit image
// and its float conversion give the same census.
TEST(Metrics, CensusKeysOfEveryEightBitColour) {
  size_t differ = 0, differ_bytes = 0;
  for (int r = 0; r < 256; ++r) {
    for (int g = 0; g < 256; ++g) {
      for (int b = 0; b < 256; ++b) {
        const long exact = (299L * r + 587L * g + 114L * b) >> 2;
        const int key = internal::CensusKey(static_cast<float>(r) / 255.f,
                                            static_cast<float>(g) / 255.f,
                                            static_cast<float>(b) / 255.f) + 32768;
        const int key_of_bytes = internal::CensusKeyOfBytes(static_cast<uint8_t>(r),
                                                            static_cast<uint8_t>(g),
                                                            static_cast<uint8_t>(b)) + 32768;
        differ += key != exact;
        differ_bytes += key_of_bytes != exact;
      }
    }
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_EQ(differ_bytes, 0u);
}

// Census's keys (kernels.h CensusKey): lumas that share a key compare equal, lumas two key steps
// apart do not, and luma outside [0, 1] compares as its clamped value.
TEST(Metrics, CensusComparesLumaRoundedTo16Bits) {
  const int w = 15, h = 15;
  auto grey = [&](float centre, float others) {
    Image img(w, h, 3);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const float v = (x == 7 && y == 7) ? centre : others;
        for (int c = 0; c < 3; ++c) img.at(x, y, c) = v;
      }
    }
    return img;
  };
  MetricOptions options;
  options.window = 3;
  auto census_at_centre = [&](const Image& p, const Image& q) {
    const MetricResult res = ComputeMetric(Metric::kCensus, p, q, {}, options);
    return res.error.at(7, 7, 0);
  };
  const Image flat = grey(0.5f, 0.5f);
  // 255000 * 0.5 = 127500, key 31875; 1e-6 above: 127500.255, the same key.
  EXPECT_EQ(census_at_centre(grey(0.5f, 0.5f + 1e-6f), flat), 0.0f);
  // Neighbours darker than the centre by two key steps: all 8 bits differ from the flat image.
  EXPECT_EQ(census_at_centre(grey(0.5f, 0.5f - 8.f / 255000.f), flat), 1.0f);
  // Above 1 is 1: a centre at 1.5 among neighbours at 1 ties with them, as a centre at 1 would.
  EXPECT_EQ(census_at_centre(grey(1.5f, 1.0f), flat), 0.0f);
  EXPECT_EQ(census_at_centre(grey(1.0f, 0.9f), flat), 1.0f);
}

TEST(Metrics, InvertedPatchGivesNccErrorTwo) {
  auto rng = testing::MakeRng();
  const Image photo = RandomImage(rng, 20, 20);
  Image inverted = photo;
  for (size_t i = 0; i < inverted.size(); ++i) inverted.data()[i] = 1.0f - photo.data()[i];
  const MetricResult res = ComputeMetric(Metric::kOneMinusNcc, photo, inverted, {});
  EXPECT_EQ(res.evaluated, 12u * 12u);
  EXPECT_NEAR(res.mean, 2.0, 1e-6);
}

TEST(Metrics, CbCrIgnoresLumaChanges) {
  auto rng = testing::MakeRng();
  std::uniform_real_distribution<float> u(0.3f, 0.7f), chroma(-0.1f, 0.1f), dy(-0.2f, 0.2f);
  Image photo(30, 20, 3), rephoto(30, 20, 3);
  for (int y = 0; y < 20; ++y) {
    for (int x = 0; x < 30; ++x) {
      const double luma = u(rng), cb = chroma(rng), cr = chroma(rng), luma2 = luma + dy(rng);
      // Inverse full-range BT.601 with the +0.5 offsets removed.
      auto set = [&](Image& img, double yy) {
        img.at(x, y, 0) = static_cast<float>(yy + 1.402 * cr);
        img.at(x, y, 1) = static_cast<float>(yy - 0.344136 * cb - 0.714136 * cr);
        img.at(x, y, 2) = static_cast<float>(yy + 1.772 * cb);
      };
      set(photo, luma);
      set(rephoto, luma2);
    }
  }
  const MetricResult res = ComputeMetric(Metric::kCbCr, photo, rephoto, {});
  EXPECT_EQ(res.evaluated, 600u);
  EXPECT_LT(res.mean, 2e-6);
  const MetricResult control = ComputeMetric(Metric::kOneMinusNcc, photo, rephoto, {});
  EXPECT_GT(control.mean, 0.01);  // the images do differ
}

TEST(Metrics, ResultsDoNotDependOnThreadCount) {
  auto rng = testing::MakeRng();
  const Image p = SmoothImage(rng, 200, 150, 0.05f), q = SmoothImage(rng, 200, 150, 0.05f);
  const auto all = ComputeMetrics(p, q, {}, AllMetrics());
  std::vector<MetricResult> one;
  {
    ThreadLimit limit(1);
    one = ComputeMetrics(p, q, {}, AllMetrics());
  }
  for (size_t m = 0; m < all.size(); ++m) EXPECT_EQ(all[m].mean, one[m].mean) << m;
}

TEST(Metrics, NonFinitePixelsAreInvalid) {
  auto rng = testing::MakeRng();
  const Image photo = RandomImage(rng, 40, 30), rephoto = RandomImage(rng, 40, 30);
  Image broken = rephoto;
  broken.at(20, 15, 1) = std::numeric_limits<float>::quiet_NaN();
  broken.at(3, 27, 0) = std::numeric_limits<float>::infinity();
  Mask valid(40, 30, 1, 1);
  valid.at(20, 15) = 0;
  valid.at(3, 27) = 0;
  const auto expected = ComputeMetrics(photo, rephoto, valid, AllMetrics());
  const auto got = ComputeMetrics(photo, broken, {}, AllMetrics());
  for (size_t m = 0; m < got.size(); ++m) {
    SCOPED_TRACE(std::string(MetricName(got[m].metric)));
    EXPECT_EQ(got[m].evaluated, expected[m].evaluated);
    EXPECT_NEAR(got[m].mean, expected[m].mean, 1e-6);
  }
}

// Error images gathered from ComputeMetricsInBands' sink, one per metric.
std::vector<MetricResult> ComputeInBands(const RgbView& photo, const RgbView& rephoto,
                                         const Mask& valid, const std::vector<Metric>& metrics,
                                         const MetricOptions& options = {}) {
  const int w = photo.width(), h = photo.height();
  std::vector<Image> errors(metrics.size(), Image(w, h, 1, -7.0f));
  int next_row = 0;
  std::vector<MetricResult> results;
  ComputeMetricsInBands(
      photo, rephoto, valid, metrics, options,
      [&](int y0, int y1, std::span<const float* const> rows) {
        EXPECT_EQ(y0, next_row);  // consecutive bands, top to bottom
        next_row = y1;
        for (size_t m = 0; m < rows.size(); ++m) {
          std::copy(rows[m], rows[m] + static_cast<size_t>(y1 - y0) * w, errors[m].row(y0));
        }
      },
      &results);
  EXPECT_EQ(next_row, h);
  for (size_t m = 0; m < results.size(); ++m) {
    EXPECT_TRUE(results[m].error.empty());
    results[m].error = std::move(errors[m]);
  }
  return results;
}

void ExpectSameResults(const std::vector<MetricResult>& got,
                       const std::vector<MetricResult>& expected) {
  ASSERT_EQ(got.size(), expected.size());
  for (size_t m = 0; m < got.size(); ++m) {
    SCOPED_TRACE(std::string(MetricName(got[m].metric)));
    EXPECT_EQ(got[m].metric, expected[m].metric);
    EXPECT_EQ(got[m].evaluated, expected[m].evaluated);
    // Bit-identical means (NaN compares by its bits).
    EXPECT_EQ(std::memcmp(&got[m].mean, &expected[m].mean, sizeof(double)), 0)
        << got[m].mean << " vs " << expected[m].mean;
    ASSERT_EQ(got[m].error.size(), expected[m].error.size());
    EXPECT_EQ(std::memcmp(got[m].error.data(), expected[m].error.data(),
                          expected[m].error.size() * sizeof(float)),
              0);
  }
}

TEST(Metrics, BandsAndEightBitInputsGiveIdenticalResults) {
  auto rng = testing::MakeRng();
  // Taller than one sink band (256 rows), with a partial last band.
  const int w = 97, h = 601;
  Image8 photo8(w, h, 3), rephoto8(w, h, 4);
  std::uniform_int_distribution<int> byte(0, 255);
  for (size_t i = 0; i < photo8.size(); ++i) photo8.data()[i] = static_cast<uint8_t>(byte(rng));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        // Correlated with the photo so that the windows are not all noise.
        const int v = photo8.at(x, y, c) / 2 + byte(rng) / 2;
        rephoto8.at(x, y, c) = static_cast<uint8_t>(v);
      }
      rephoto8.at(x, y, 3) = static_cast<uint8_t>(byte(rng));
    }
  }
  Image photo(w, h, 3), rephoto(w, h, 3), rephoto_rgba(w, h, 4);
  for (size_t i = 0; i < photo.size(); ++i) photo.data()[i] = photo8.data()[i] / 255.f;
  for (size_t i = 0; i < rephoto_rgba.size(); ++i) {
    rephoto_rgba.data()[i] = rephoto8.data()[i] / 255.f;
  }
  for (size_t i = 0; i < rephoto.pixel_count(); ++i) {
    for (int c = 0; c < 3; ++c) rephoto.data()[3 * i + c] = rephoto_rgba.data()[4 * i + c];
  }
  const Mask valid = RandomMask(rng, w, h, 0.995);
  for (const MetricOptions& options :
       {MetricOptions{}, MetricOptions{.window = 5, .ssim_gaussian = false, .ssim_window = 7}}) {
    const auto expected = ComputeMetrics(photo, rephoto, valid, AllMetrics(), options);
    ExpectSameResults(ComputeInBands(photo, rephoto, valid, AllMetrics(), options), expected);
    ExpectSameResults(ComputeInBands(photo8, rephoto8, valid, AllMetrics(), options), expected);
    ExpectSameResults(ComputeInBands(photo, rephoto_rgba, valid, AllMetrics(), options), expected);
  }
  // Without a sink: the same means and counts.
  {
    std::vector<MetricResult> means_only;
    ComputeMetricsInBands(photo8, rephoto8, valid, AllMetrics(), {}, nullptr, &means_only);
    const auto expected = ComputeMetrics(photo, rephoto, valid, AllMetrics());
    for (size_t m = 0; m < means_only.size(); ++m) {
      EXPECT_EQ(std::memcmp(&means_only[m].mean, &expected[m].mean, sizeof(double)), 0);
      EXPECT_EQ(means_only[m].evaluated, expected[m].evaluated);
    }
  }
  // A subset in another order, and no mask.
  const std::vector<Metric> some = {Metric::kPsnr, Metric::kCensus, Metric::kDssim};
  ExpectSameResults(ComputeInBands(photo8, rephoto8, {}, some),
                    ComputeMetrics(photo, rephoto, {}, some));
  // iCID alone reads the 8-bit rows without float rows (RgbRows::Load with floats = false),
  // also with one image 8-bit and the other float.
  const std::vector<Metric> icid = {Metric::kIcid};
  ExpectSameResults(ComputeInBands(photo8, rephoto8, valid, icid),
                    ComputeMetrics(photo, rephoto, valid, icid));
  ExpectSameResults(ComputeInBands(photo8, rephoto_rgba, valid, icid),
                    ComputeMetrics(photo, rephoto, valid, icid));
  // So do census alone and 1-NCC + ZSSD on their exact path (both images 8-bit); with one image
  // float and not of 8-bit values, the window pass falls back to the double path, which reads
  // the float rows of the 8-bit image too.
  for (const std::vector<Metric>& byte_readers :
       {std::vector<Metric>{Metric::kCensus},
        std::vector<Metric>{Metric::kOneMinusNcc, Metric::kZssd, Metric::kCensus, Metric::kIcid}}) {
    ExpectSameResults(ComputeInBands(photo8, rephoto8, valid, byte_readers),
                      ComputeMetrics(photo, rephoto, valid, byte_readers));
    ExpectSameResults(ComputeInBands(photo8, rephoto_rgba, valid, byte_readers),
                      ComputeMetrics(photo, rephoto, valid, byte_readers));
    Image off_grid = rephoto;
    for (size_t i = 0; i < off_grid.size(); i += 7) off_grid.data()[i] *= 0.999f;
    ExpectSameResults(ComputeInBands(photo8, off_grid, valid, byte_readers),
                      ComputeMetrics(photo, off_grid, valid, byte_readers));
  }
}

// 1-NCC and ZSSD of 8-bit values from exact statistics: a reference written from the SPEC's
// formulas over the integers k (sums in int64, exact), the formula in long double. The exact
// path (windows up to 10, every value k / 255.f) rounds only the formula (dx dy, the square root,
// the division, in double) and the result to float, so it gives float(reference) up to the rare
// value within 1e-15 of a rounding boundary; the double path (window 11 and up) agrees within 1e-6.
// Flat patches (constant blocks) exercise the flat rule.
long double ExactNccOrZssd(const Image8& p, const Image8& q, int x, int y, int r, bool ncc) {
  const int64_t n = (2 * r + 1) * (2 * r + 1);
  int64_t sxx = 0, syy = 0, sxy = 0, sx[3] = {}, sy[3] = {};
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      for (int c = 0; c < 3; ++c) {
        const int64_t a = p.at(x + dx, y + dy, c), b = q.at(x + dx, y + dy, c);
        sx[c] += a;
        sy[c] += b;
        sxx += a * a;
        syy += b * b;
        sxy += a * b;
      }
    }
  }
  // n x the summed (co)deviations from the per-channel means, in units of k.
  int64_t dx = n * sxx, dy = n * syy, dxy = n * sxy;
  for (int c = 0; c < 3; ++c) {
    dx -= sx[c] * sx[c];
    dy -= sy[c] * sy[c];
    dxy -= sx[c] * sy[c];
  }
  if (!ncc) return static_cast<long double>(dx + dy - 2 * dxy) / (n * n * 255.0L * 255.0L * 3);
  // The flat rule in units of [0, 1]: summed squared deviation = dx / (n 255^2).
  const long double flat = MetricOptions().ncc_flat_threshold;
  const bool fx = dx / (n * 255.0L * 255.0L) <= flat, fy = dy / (n * 255.0L * 255.0L) <= flat;
  if (fx || fy) return fx && fy ? 0.0L : 1.0L;
  const long double e = 1.0L - dxy / std::sqrt(static_cast<long double>(dx) * dy);
  return std::clamp(e, 0.0L, 2.0L);
}

TEST(Metrics, EightBitWindowsGiveTheirExactStatistics) {
  auto rng = testing::MakeRng();
  const int w = 83, h = 71;
  Image8 photo8(w, h, 3), rephoto8(w, h, 3);
  std::uniform_int_distribution<int> byte(0, 255), noise(-20, 20);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        // Constant 12 x 12 blocks on a diagonal (flat patches), noise elsewhere; the rendering
        // correlated with the photo, flat where the photo is, and flat on its own elsewhere.
        const bool flat = (x / 12 == y / 12) && x < 72;
        const bool own_flat = (x / 12 == y / 12 + 2) && x < 72;
        const int a = flat ? 40 + 30 * c : byte(rng);
        const int b = flat || own_flat ? 200 - 20 * c : std::clamp(a + noise(rng), 0, 255);
        photo8.at(x, y, c) = static_cast<uint8_t>(a);
        rephoto8.at(x, y, c) = static_cast<uint8_t>(b);
      }
    }
  }
  Image photo(w, h, 3), rephoto(w, h, 3);
  for (size_t i = 0; i < photo.size(); ++i) {
    photo.data()[i] = photo8.data()[i] / 255.f;
    rephoto.data()[i] = rephoto8.data()[i] / 255.f;
  }
  const Mask valid = RandomMask(rng, w, h, 0.998);
  for (int window : {3, 5, 7, 9, 11}) {
    SCOPED_TRACE(window);
    MetricOptions options;
    options.window = window;
    const int r = window / 2;
    const auto from_floats =
        ComputeMetrics(photo, rephoto, valid, {Metric::kOneMinusNcc, Metric::kZssd}, options);
    const auto from_bytes =
        ComputeInBands(photo8, rephoto8, valid, {Metric::kOneMinusNcc, Metric::kZssd}, options);
    ExpectSameResults(from_bytes, from_floats);
    for (int m = 0; m < 2; ++m) {
      size_t evaluated = 0, rounded_otherwise = 0, flat_patches = 0;
      double worst = 0;
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          const float got = from_floats[m].error.at(x, y, 0);
          if (std::isnan(got)) continue;
          ++evaluated;
          const long double expected = ExactNccOrZssd(photo8, rephoto8, x, y, r, m == 0);
          if (m == 0 && (expected == 0.0L || expected == 1.0L)) ++flat_patches;
          worst = std::max(worst, static_cast<double>(std::abs(got - expected)));
          rounded_otherwise += got != static_cast<float>(expected);
        }
      }
      ASSERT_GT(evaluated, 2000u);
      if (window <= 9) {
        // float(reference) everywhere but perhaps one value in 10^4, and then by one ulp.
        EXPECT_LE(rounded_otherwise, evaluated / 10000) << (m == 0 ? "1-ncc" : "zssd");
        EXPECT_LE(worst, m == 0 ? 2.4e-7 : 1e-7) << (m == 0 ? "1-ncc" : "zssd");
      } else {
        EXPECT_LE(worst, 1e-6) << (m == 0 ? "1-ncc" : "zssd");
      }
      if (m == 0 && window <= 9) {
        EXPECT_GT(flat_patches, 10u);
      }
    }
  }
}

// A float image whose values are k / 255.f except in one band: that band's windows take the
// double path (the others the exact one); each window still matches the naive loops.
TEST(Metrics, FloatsThatAreNotBytesTakeTheDoublePath) {
  auto rng = testing::MakeRng();
  const int w = 45, h = 150;
  Image photo = RandomImage(rng, w, h, true), rephoto = RandomImage(rng, w, h, true);
  photo.at(7, 70, 1) = 0.123456f;  // not k / 255.f
  for (int window : {3, 9}) {
    MetricOptions options;
    options.window = window;
    const auto results =
        ComputeMetrics(photo, rephoto, {}, {Metric::kOneMinusNcc, Metric::kZssd}, options);
    ExpectMatches(results[0], NaiveWindowMetric(photo, rephoto, {}, window, NaiveNcc), 1e-5,
                  "1-ncc");
    ExpectMatches(results[1], NaiveWindowMetric(photo, rephoto, {}, window, NaiveZssd), 1e-6,
                  "zssd");
  }
}

// Every 8-bit value, as the band pass converts it, equals v / 255.f (io::ReadImage's value).
TEST(Metrics, EightBitRowsConvertToTheFloatsOfReadImage) {
  // Every byte value, as RGB and as RGBA rows of a width that is not a vector multiple, on every
  // instruction-set path: Load's rows are the division k / 255.f itself (the reference here;
  // the kernels multiply, kernels.h ByteToUnitFloat).
  const int w = 259;
  for (int channels : {3, 4}) {
    Image8 bytes(w, 1, channels);
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < channels; ++c) {
        bytes.at(x, 0, c) = static_cast<uint8_t>((x + 85 * c) % 256);
      }
    }
    for (core::Isa isa : core::SupportedIsas()) {
      core::ScopedIsa scoped(isa);
      SCOPED_TRACE(std::string(core::IsaName(isa)) + " channels " + std::to_string(channels));
      internal::RgbRows rows;
      std::vector<float> scratch;
      rows.Load(bytes, 0, 1, &scratch);
      for (int x = 0; x < w; ++x) {
        for (int c = 0; c < 3; ++c) {
          ASSERT_EQ(rows.row(0)[3 * x + c], static_cast<float>(bytes.at(x, 0, c)) / 255.f) << x;
        }
      }
    }
  }
}

TEST(Metrics, ByteToUnitFloatIsTheDivisionForEveryByte) {
  for (int k = 0; k < 256; ++k) {
    ASSERT_EQ(internal::ByteToUnitFloat(static_cast<float>(k)), static_cast<float>(k) / 255.f) << k;
  }
}

TEST(Metrics, BandsTreatNonFinitePixelsAsComputeMetricsDoes) {
  auto rng = testing::MakeRng();
  const Image photo = RandomImage(rng, 40, 300);
  Image broken = RandomImage(rng, 40, 300);
  broken.at(20, 15, 1) = std::numeric_limits<float>::quiet_NaN();
  broken.at(3, 270, 0) = std::numeric_limits<float>::infinity();
  ExpectSameResults(ComputeInBands(photo, broken, {}, AllMetrics()),
                    ComputeMetrics(photo, broken, {}, AllMetrics()));
}

TEST(Metrics, SmallImagesAndBadInput) {
  const Image tiny(5, 5, 3, 0.5f);
  const MetricResult res = ComputeMetric(Metric::kOneMinusNcc, tiny, tiny, {});
  EXPECT_EQ(res.evaluated, 0u);
  EXPECT_TRUE(std::isnan(res.mean));
  EXPECT_THROW(ComputeMetric(Metric::kZssd, tiny, Image(5, 4, 3), {}), Error);
  EXPECT_THROW(ComputeMetric(Metric::kZssd, tiny, Image(5, 5, 4), {}), Error);
  EXPECT_THROW(ComputeMetric(Metric::kZssd, tiny, tiny, Mask(4, 5, 1)), Error);
  MetricOptions even;
  even.window = 8;
  EXPECT_THROW(ComputeMetric(Metric::kZssd, tiny, tiny, {}, even), Error);
}

TEST(Metrics, NamesAndLists) {
  for (Metric m : AllMetrics()) EXPECT_EQ(ParseMetric(MetricName(m)), m);
  EXPECT_EQ(ParseMetric("1-NCC"), Metric::kOneMinusNcc);
  EXPECT_FALSE(ParseMetric("mse"));
  EXPECT_EQ(ParseMetricList("psnr, 1-ncc").size(), 2u);
  EXPECT_EQ(ParseMetricList("all"), AllMetrics());
  EXPECT_THROW(ParseMetricList("1-ncc,bogus"), Error);
  EXPECT_THROW(ParseMetricList(""), Error);
  EXPECT_TRUE(HigherIsBetter(Metric::kPsnr));
  EXPECT_FALSE(HigherIsBetter(Metric::kCensus));
}

}  // namespace
}  // namespace rephoto::metrics
