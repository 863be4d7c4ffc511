// SSIM, DSSIM and PSNR against scikit-image (reference values written by
// testdata/make_skimage_reference.py; see there for the cases), and the iCID colour space
// against skimage.color.rgb2lab.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "rephoto/metrics/icid.h"
#include "rephoto/metrics/kernels.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/testing/testing.h"
#if REPHOTO_HAVE_IO
#include "rephoto/io/image_io.h"
#endif

namespace rephoto::metrics {
namespace {

using nlohmann::json;

json LoadReference() {
  const auto path = testing::SourceDir() / "src/rephoto/metrics/testdata/skimage_reference.json";
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  return json::parse(in);
}

// Same closed forms as synthetic() / perturb() / mask_for() in the script.
void SyntheticPair(int width, int height, int variant, Image* photo, Image* rephoto) {
  *photo = Image(width, height, 3);
  *rephoto = Image(width, height, 3);
  const double v = variant;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const double p = 0.5 + 0.35 * std::sin(0.21 * x + 0.13 * y + 1.1 * c + v) *
                                   std::cos(0.07 * x - 0.19 * y + 0.3 * c);
        const double q = 0.8 * p + 0.1 + 0.08 * std::sin(0.9 * x + 0.5 * y + 2.0 * c + 0.7 * v);
        photo->at(x, y, c) = static_cast<float>(std::clamp(p, 0.0, 1.0));
        rephoto->at(x, y, c) = static_cast<float>(std::clamp(q, 0.0, 1.0));
      }
    }
  }
}

Image Perturb(const Image& photo) {
  Image out(photo.width(), photo.height(), 3);
  for (int y = 0; y < photo.height(); ++y) {
    for (int x = 0; x < photo.width(); ++x) {
      for (int c = 0; c < 3; ++c) {
        const double v = 0.85 * photo.at(x, y, c) + 0.05 + 0.04 * std::sin(0.37 * x + 0.23 * y + c);
        out.at(x, y, c) = static_cast<float>(std::clamp(v, 0.0, 1.0));
      }
    }
  }
  return out;
}

Mask ReferenceMask(int width, int height) {
  Mask m(width, height, 1, 1);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const int dx = x - width / 3, dy = y - height / 2, rr = height / 5;
      if (dx * dx + dy * dy < rr * rr || (x * 7 + y * 3) % 389 == 0) m.at(x, y) = 0;
    }
  }
  return m;
}

// Gaussian SSIM (the default; float32 filters against scikit-image's float64) agrees to
// kGaussianSsimTolerance and DSSIM = (1 - SSIM) / 2 to half that. Measured on these cases: at
// most 1.7e-7 (SSIM) with the five-quantity kernel and 2.1e-7 with the fused one (kermit,
// masked; 1.5e-8 or less on the other cases, where the fused kernel is the closer one). The
// uniform 7x7 window with sample covariance is further off (up to 6.1e-7 and 5.5e-7: the float
// box weights 1/49 sum to 1 + 4.5e-8).
constexpr double kGaussianSsimTolerance = 3e-7;
constexpr double kUniformTolerance = 2e-6;

void ExpectMatchesReferenceWithKernel(const Image& photo, const Image& rephoto, const json& ref) {
  MetricOptions gaussian;  // defaults: 11x11 Gaussian, sigma 1.5, population covariance
  MetricOptions uniform;   // scikit-image's defaults
  uniform.ssim_gaussian = false;
  uniform.ssim_window = 7;
  const std::vector<Metric> set = {Metric::kSsim, Metric::kDssim, Metric::kPsnr};
  const auto g = ComputeMetrics(photo, rephoto, {}, set, gaussian);
  const auto u = ComputeMetrics(photo, rephoto, {}, {Metric::kSsim}, uniform);
  EXPECT_NEAR(g[0].mean, ref["ssim_gaussian"].get<double>(), kGaussianSsimTolerance);
  EXPECT_NEAR(g[1].mean, ref["dssim_gaussian"].get<double>(), kGaussianSsimTolerance / 2);
  EXPECT_NEAR(g[2].mean, ref["psnr"].get<double>(), 1e-4);
  EXPECT_NEAR(u[0].mean, ref["ssim_skimage_default"].get<double>(), kUniformTolerance);

  const Mask valid = ReferenceMask(photo.width(), photo.height());
  const auto gm = ComputeMetrics(photo, rephoto, valid, set, gaussian);
  const auto um = ComputeMetrics(photo, rephoto, valid, {Metric::kSsim}, uniform);
  EXPECT_EQ(gm[0].evaluated, ref["masked_count_gaussian"].get<size_t>());
  EXPECT_EQ(um[0].evaluated, ref["masked_count_skimage_default"].get<size_t>());
  EXPECT_NEAR(gm[0].mean, ref["masked_ssim_gaussian"].get<double>(), kGaussianSsimTolerance);
  EXPECT_NEAR(um[0].mean, ref["masked_ssim_skimage_default"].get<double>(), kUniformTolerance);
  EXPECT_NEAR(gm[2].mean, ref["masked_psnr"].get<double>(), 1e-4);
}

// With both SSIM kernels (the fused default and the earlier five-quantity one).
void ExpectMatchesReference(const Image& photo, const Image& rephoto, const json& ref) {
  for (const auto kernel : {internal::SsimKernel::kFused, internal::SsimKernel::kFiveQuantities}) {
    SCOPED_TRACE(kernel == internal::SsimKernel::kFused ? "fused kernel" : "five-quantity kernel");
    internal::SetSsimKernel(kernel);
    ExpectMatchesReferenceWithKernel(photo, rephoto, ref);
  }
  internal::SetSsimKernel(internal::SsimKernel::kFused);
}

TEST(MetricsSkimage, SyntheticPairs) {
  const json ref = LoadReference();
  for (const char* name : {"synthetic_64x48", "synthetic_97x61"}) {
    SCOPED_TRACE(name);
    const json& c = ref["cases"][name];
    Image photo, rephoto;
    SyntheticPair(c["width"], c["height"], c["variant"], &photo, &rephoto);
    ExpectMatchesReference(photo, rephoto, c);
  }
}

TEST(MetricsSkimage, LabMatchesRgb2lab) {
  const json reference = LoadReference();
  for (const json& item : reference["lab"]) {
    double lab[3];
    SrgbToLab(item["rgb"][0], item["rgb"][1], item["rgb"][2], lab);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(lab[i], item["lab"][i].get<double>(), 1e-4) << item;
  }
}

#if REPHOTO_HAVE_IO
// Verifies that our decoder produced the same 8-bit values as PIL did for the reference.
void ExpectChecksum(const Image& img, const json& checksum) {
  int64_t sum = 0, weighted = 0;
  for (size_t i = 0; i < img.size(); ++i) {
    const int64_t v = std::lround(img.data()[i] * 255.0f);
    sum += v;
    weighted += v * static_cast<int64_t>(i % 251 + 1);
  }
  EXPECT_EQ(sum, checksum["sum"].get<int64_t>());
  EXPECT_EQ(weighted, checksum["weighted_sum"].get<int64_t>());
}

Image Crop(const Image& img, const json& crop) {
  const int x0 = crop["x"], y0 = crop["y"], w = crop["width"], h = crop["height"];
  Image out(w, h, 3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) out.at(x, y, c) = img.at(x0 + x, y0 + y, c);
    }
  }
  return out;
}

TEST(MetricsSkimage, RealJpegPhotos) {
  REPHOTO_REQUIRE_DATA("bundler_kermit");
  const json c = LoadReference()["cases"]["kermit_jpeg"];
  const Image photo = io::ReadImage(testing::SharedDataDir() / c["photo"].get<std::string>());
  const Image rephoto = io::ReadImage(testing::SharedDataDir() / c["rephoto"].get<std::string>());
  ExpectChecksum(photo, c["photo_checksum"]);
  ExpectChecksum(rephoto, c["rephoto_checksum"]);
  ExpectMatchesReference(Crop(photo, c["crop"]), Crop(rephoto, c["crop"]), c);
}

TEST(MetricsSkimage, RealPngPhotoAgainstPerturbation) {
  REPHOTO_REQUIRE_DATA("middlebury_temple_dino");
  const json c = LoadReference()["cases"]["temple_png"];
  const Image photo = io::ReadImage(testing::SharedDataDir() / c["photo"].get<std::string>());
  ExpectChecksum(photo, c["photo_checksum"]);
  const Image crop = Crop(photo, c["crop"]);
  ExpectMatchesReference(crop, Perturb(crop), c);
}
#else
TEST(MetricsSkimage, RealPhotos) { GTEST_SKIP() << "built without rephoto_io"; }
#endif

}  // namespace
}  // namespace rephoto::metrics
