// The metric kernels on every instruction-set path this CPU has (core/isa.h): every metric's
// mean, count and error image bit-identical between the AVX-512 and AVX2 paths, and within 1e-6
// relative (means) on the baseline path, whose SSIM filters have no FMA. Float and 8-bit inputs,
// masks, odd sizes (vector tails, strips), both SSIM modes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "rephoto/core/isa.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/testing/testing.h"

namespace rephoto::metrics {
namespace {

// A smooth pattern plus noise: flat and textured windows, as in photos.
Image Pattern(std::mt19937_64& rng, int w, int h, float phase, float noise) {
  std::normal_distribution<float> n(0.0f, noise);
  Image img(w, h, 3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float v =
            0.5f + 0.35f * std::sin(0.11f * x + phase + 0.7f * c) * std::cos(0.07f * y) + n(rng);
        img.at(x, y, c) = std::round(std::clamp(v, 0.0f, 1.0f) * 255.0f) / 255.0f;
      }
    }
  }
  return img;
}

Image8 ToBytes(const Image& image) {
  Image8 bytes(image.width(), image.height(), image.channels());
  for (size_t i = 0; i < image.size(); ++i) {
    bytes.data()[i] = static_cast<uint8_t>(std::lround(image.data()[i] * 255.0f));
  }
  return bytes;
}

struct Outcome {
  std::vector<double> means;
  std::vector<size_t> counts;
  std::vector<Image> errors;
};

Outcome RunAll(const Image& photo, const Image& rephoto, const Mask& valid, bool bytes,
               const MetricOptions& options) {
  std::vector<MetricResult> results;
  Outcome outcome;
  if (bytes) {
    const Image8 p = ToBytes(photo), r = ToBytes(rephoto);
    ComputeMetricsInBands(p, r, valid, AllMetrics(), options, nullptr, &results);
  } else {
    ComputeMetrics(photo, rephoto, valid, AllMetrics(), options, &results);
  }
  for (const MetricResult& result : results) {
    outcome.means.push_back(result.mean);
    outcome.counts.push_back(result.evaluated);
    outcome.errors.push_back(result.error);
  }
  return outcome;
}

TEST(CrossIsa, MetricsAgreeOnEveryPath) {
  const std::vector<core::Isa> isas = core::SupportedIsas();
  auto rng = testing::MakeRng();
  struct Size {
    int w, h;
  };
  for (const Size size : {Size{67, 45}, Size{301, 97}, Size{530, 41}}) {
    const Image photo = Pattern(rng, size.w, size.h, 0.0f, 0.03f);
    const Image rephoto = Pattern(rng, size.w, size.h, 0.3f, 0.05f);
    Mask valid(size.w, size.h, 1, 1);
    for (int y = 0; y < size.h; ++y) {
      // Two holes: a block and a thin diagonal band (windows that touch them are skipped).
      for (int x = 0; x < size.w; ++x) {
        const bool block = x >= 10 && x < 25 && y >= 5 && y < 17;
        const bool band = std::abs(x - 2 * y - 30) < 2;
        valid.at(x, y) = !(block || band);
      }
    }
    for (bool bytes : {false, true}) {
      // SSIM windows: 11 and 7 have compile-time kernels (radius 5 and 3), 9 a runtime radius;
      // each takes a different filter path on each ISA (ssim_fused.cc).
      for (const auto& [window, gaussian] : {std::pair{11, true}, {7, false}, {9, true}}) {
        MetricOptions options;
        options.ssim_gaussian = gaussian;
        options.ssim_window = window;
        SCOPED_TRACE(::testing::Message() << size.w << "x" << size.h << " bytes " << bytes
                                          << " window " << window << " gaussian " << gaussian);
        std::vector<Outcome> outcomes;
        for (core::Isa isa : isas) {
          core::ScopedIsa scoped(isa);
          outcomes.push_back(RunAll(photo, rephoto, valid, bytes, options));
        }
        const Outcome& best = outcomes.back();
        for (size_t i = 0; i + 1 < outcomes.size(); ++i) {
          const bool baseline = isas[i] == core::Isa::kBaseline;
          for (size_t m = 0; m < best.means.size(); ++m) {
            const std::string name(MetricName(AllMetrics()[m]));
            SCOPED_TRACE(std::string(core::IsaName(isas[i])) + " " + name);
            EXPECT_EQ(outcomes[i].counts[m], best.counts[m]);
            ASSERT_TRUE(std::isfinite(best.means[m]));
            if (baseline) {
              EXPECT_LE(std::abs(outcomes[i].means[m] - best.means[m]),
                        1e-6 * std::abs(best.means[m]));
            } else {
              EXPECT_EQ(outcomes[i].means[m], best.means[m]);
              const Image& a = outcomes[i].errors[m];
              const Image& b = best.errors[m];
              ASSERT_EQ(a.size(), b.size());
              EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(float)));
            }
          }
        }
      }
    }
  }
}

// 8-bit inputs stand for the floats v / 255.f (io::ReadImage's values), which the 8-bit paths
// make themselves (kernels.cc BytesToFloats, iCID's decoding table): images holding every
// 8-bit value in every channel (an RGB photo, an RGBA rendering) give, on every path, the same
// means and error images as the floats v / 255.f. (A conversion by multiplication with 1/255.f
// fails here: it differs from the division for 126 of the 256 values.)
TEST(CrossIsa, BytesGiveTheResultsOfTheirFloats) {
  const int w = 256, h = 37;
  Image8 photo8(w, h, 3), rephoto8(w, h, 4);
  Image photo(w, h, 3), rephoto(w, h, 3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        const int p = (x + 91 * c + 7 * y) % 256, q = (x * 3 + 17 * c + 11 * y) % 256;
        photo8.data()[(static_cast<size_t>(y) * w + x) * 3 + c] = static_cast<uint8_t>(p);
        rephoto8.data()[(static_cast<size_t>(y) * w + x) * 4 + c] = static_cast<uint8_t>(q);
        photo.at(x, y, c) = static_cast<float>(p) / 255.f;
        rephoto.at(x, y, c) = static_cast<float>(q) / 255.f;
      }
      rephoto8.data()[(static_cast<size_t>(y) * w + x) * 4 + 3] = 255;
    }
  }
  const Mask valid;
  for (core::Isa isa : core::SupportedIsas()) {
    core::ScopedIsa scoped(isa);
    std::vector<MetricResult> from_floats, from_bytes;
    ComputeMetrics(photo, rephoto, valid, AllMetrics(), MetricOptions(), &from_floats);
    std::vector<Image> band_errors(AllMetrics().size(), Image(w, h, 1));
    const ErrorBandSink sink = [&](int y0, int y1, std::span<const float* const> errors) {
      for (size_t m = 0; m < errors.size(); ++m) {
        std::memcpy(band_errors[m].data() + static_cast<size_t>(y0) * w, errors[m],
                    static_cast<size_t>(y1 - y0) * w * sizeof(float));
      }
    };
    ComputeMetricsInBands(photo8, rephoto8, valid, AllMetrics(), MetricOptions(), sink,
                          &from_bytes);
    ASSERT_EQ(from_floats.size(), from_bytes.size());
    for (size_t m = 0; m < from_floats.size(); ++m) {
      SCOPED_TRACE(std::string(core::IsaName(isa)) + " " +
                   std::string(MetricName(AllMetrics()[m])));
      EXPECT_EQ(from_floats[m].mean, from_bytes[m].mean);
      const Image& a = from_floats[m].error;
      const Image& b = band_errors[m];
      ASSERT_EQ(a.size(), b.size());
      EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(float)));
    }
  }
}

}  // namespace
}  // namespace rephoto::metrics
