#include "rephoto/compare/compare.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>

#include "rephoto/compare/error_images.h"
#include "rephoto/core/colormap.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/csv.h"
#include "rephoto/io/image_io.h"
#include "rephoto/run/run_folder.h"
#include "rephoto/testing/testing.h"

namespace rephoto::compare {
namespace {

namespace fs = std::filesystem;
using metrics::Metric;
using ::testing::HasSubstr;

constexpr int kWidth = 24;
constexpr int kHeight = 20;

// Random 8-bit values in [10, 245] / 255: exactly representable in a PNG, never ill-exposed.
Image RandomImage(std::mt19937_64& rng, int width = kWidth, int height = kHeight) {
  std::uniform_int_distribution<int> value(10, 245);
  Image image(width, height, 3);
  for (size_t i = 0; i < image.size(); ++i) image.data()[i] = value(rng) / 255.f;
  return image;
}

Image Constant(int r, int g, int b, int width = kWidth, int height = kHeight) {
  Image image(width, height, 3);
  for (size_t i = 0; i < image.pixel_count(); ++i) {
    image.data()[3 * i] = r / 255.f;
    image.data()[3 * i + 1] = g / 255.f;
    image.data()[3 * i + 2] = b / 255.f;
  }
  return image;
}

struct Folders {
  fs::path root, photos, renders, out;
};

Folders MakeFolders() {
  Folders f;
  f.root = testing::MakeTempDir();
  f.photos = f.root / "photos";
  f.renders = f.root / "renders";
  f.out = f.root / "run";
  fs::create_directories(f.photos);
  fs::create_directories(f.renders);
  return f;
}

CompareOptions Options(const Folders& f) {
  CompareOptions options;
  options.photos = f.photos;
  options.renders = f.renders;
  options.out = f.out;
  return options;
}

// Runs `fn`, expects an Error and returns its message.
template <typename Fn>
std::string ErrorMessage(Fn&& fn) {
  try {
    fn();
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error";
  return "";
}

// Nothing but the expected entries in the run folder: no staging leftovers.
std::vector<std::string> FolderEntries(const fs::path& folder) {
  std::vector<std::string> names;
  if (!fs::exists(folder)) return names;
  for (const auto& entry : fs::directory_iterator(folder)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

nlohmann::json ReadJson(const fs::path& path) {
  return nlohmann::json::parse(ReadFileToString(path));
}

size_t Column(const std::vector<std::string>& header, const std::string& name) {
  const auto it = std::find(header.begin(), header.end(), name);
  EXPECT_NE(it, header.end()) << name;
  return static_cast<size_t>(it - header.begin());
}

TEST(Compare, IdenticalFoldersGiveZeroErrorAndFullCompleteness) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  for (const char* name : {"a", "b", "c"}) {
    const Image image = RandomImage(rng);
    io::WritePng(f.photos / (std::string(name) + ".png"), image);
    io::WritePng(f.renders / (std::string(name) + ".png"), image);
  }
  const CompareResult result = RunCompare(Options(f));
  EXPECT_EQ(result.exit_code(), ExitCode::kOk);
  ASSERT_EQ(result.images.size(), 3u);
  EXPECT_TRUE(result.missing.empty());
  for (const ImageResult& image : result.images) {
    EXPECT_EQ(image.completeness.value, 1.0);
    EXPECT_EQ(image.completeness.valid_photo, static_cast<size_t>((kWidth - 8) * (kHeight - 8)));
    ASSERT_EQ(image.metrics.size(), metrics::AllMetrics().size());
    for (size_t k = 0; k < image.metrics.size(); ++k) {
      const Metric metric = metrics::AllMetrics()[k];
      const double mean = image.metrics[k].mean;
      EXPECT_GT(image.metrics[k].evaluated, 0u) << metrics::MetricName(metric);
      if (metric == Metric::kPsnr) {
        EXPECT_EQ(mean, std::numeric_limits<double>::infinity());
      } else if (metric == Metric::kSsim) {
        EXPECT_EQ(mean, 1.0);
      } else {
        EXPECT_EQ(mean, 0.0) << metrics::MetricName(metric);
      }
    }
  }
  // Outputs: no staging folder left, an EXR and a PNG per image and metric.
  EXPECT_EQ(FolderEntries(f.out),
            (std::vector<std::string>{".rephoto-run", "errors", "per_image.csv", "summary.json"}));
  EXPECT_EQ(FolderEntries(f.out / "errors").size(), 3 * metrics::AllMetrics().size() * 2);
  const Image error = io::ReadImage(f.out / "errors" / "b.1-ncc.exr");
  ASSERT_EQ(error.channels(), 1);
  ASSERT_EQ(error.width(), kWidth);
  EXPECT_TRUE(std::isnan(error.at(0, 0)));  // the window leaves the image
  EXPECT_EQ(error.at(12, 10), 0.f);
  const Image png = io::ReadImage(f.out / "errors" / "b.1-ncc.png");
  ASSERT_EQ(png.channels(), 4);
  EXPECT_EQ(png.at(0, 0, 3), 0.f);  // transparent where not evaluated
  EXPECT_EQ(png.at(12, 10, 3), 1.f);
  const auto blue = JetColor(0.f);
  EXPECT_EQ(png.at(12, 10, 2), std::round(blue[2] * 255.f) / 255.f);

  const nlohmann::json summary = ReadJson(f.out / "summary.json");
  EXPECT_EQ(summary["schema"], "rephoto.compare/1");
  EXPECT_EQ(summary["counts"]["compared"], 3);
  EXPECT_EQ(summary["counts"]["missing"], 0);
  EXPECT_EQ(summary["completeness"]["median"], 1.0);
  EXPECT_EQ(summary["metrics"]["1-ncc"]["max"], 0.0);
  EXPECT_EQ(summary["metrics"]["psnr"]["mean"], "inf");
  EXPECT_EQ(summary["metrics"]["ssim"]["min"], 1.0);
}

TEST(Compare, MissingCounterpartsAreReportedAndCounted) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  for (const char* name : {"a", "b", "c"}) {
    io::WritePng(f.photos / (std::string(name) + ".png"), RandomImage(rng));
  }
  for (const char* name : {"a", "b", "d"}) {
    io::WritePng(f.renders / (std::string(name) + ".png"), RandomImage(rng));
  }
  CompareOptions options = Options(f);
  options.metrics = {Metric::kCbCr};
  const CompareResult result = RunCompare(options);
  EXPECT_EQ(result.exit_code(), ExitCode::kIncomplete);
  ASSERT_EQ(result.images.size(), 2u);
  ASSERT_EQ(result.missing.size(), 2u);
  EXPECT_EQ(result.missing[0].name, "c");
  EXPECT_EQ(result.missing[0].missing, Missing::kRender);
  EXPECT_EQ(result.missing[1].name, "d");
  EXPECT_EQ(result.missing[1].missing, Missing::kPhoto);

  const auto rows = io::ReadCsvFile(f.out / "per_image.csv");
  ASSERT_EQ(rows.size(), 5u);
  const size_t status = Column(rows[0], "status");
  EXPECT_EQ(rows[1][0], "a");
  EXPECT_EQ(rows[1][status], "ok");
  EXPECT_EQ(rows[3][0], "c");
  EXPECT_EQ(rows[3][status], "missing_render");
  EXPECT_EQ(rows[3][Column(rows[0], "photo")], (f.photos / "c.png").string());
  EXPECT_EQ(rows[3][Column(rows[0], "cb+cr")], "");
  EXPECT_EQ(rows[4][0], "d");
  EXPECT_EQ(rows[4][status], "missing_photo");
  EXPECT_EQ(rows[4][Column(rows[0], "render")], (f.renders / "d.png").string());
  for (const auto& row : rows) EXPECT_EQ(row.size(), rows[0].size());

  const nlohmann::json summary = ReadJson(f.out / "summary.json");
  EXPECT_EQ(summary["counts"]["missing"], 2);
  EXPECT_EQ(summary["counts"]["missing_render"], 1);
  EXPECT_EQ(summary["counts"]["missing_photo"], 1);
  ASSERT_EQ(summary["missing"].size(), 2u);
  EXPECT_EQ(summary["missing"][0]["name"], "c");
  EXPECT_EQ(summary["missing"][0]["missing"], "render");
  EXPECT_EQ(summary["missing"][1]["missing"], "photo");
}

TEST(Compare, NoPairOrEmptyFolderIsAnError) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  EXPECT_THAT(ErrorMessage([&] { RunCompare(Options(f)); }),
              ::testing::StartsWith(f.photos.string() + ": no images"));
  io::WritePng(f.photos / "a.png", RandomImage(rng));
  EXPECT_THAT(ErrorMessage([&] { RunCompare(Options(f)); }),
              ::testing::StartsWith(f.renders.string() + ": no images"));
  io::WritePng(f.renders / "b.png", RandomImage(rng));
  EXPECT_THAT(ErrorMessage([&] { RunCompare(Options(f)); }), HasSubstr("no photo has a rendering"));
  EXPECT_FALSE(fs::exists(f.out / "summary.json"));
}

TEST(Compare, SizeMismatchNamesBothFilesUnlessResizing) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  const Image photo = RandomImage(rng);
  io::WritePng(f.photos / "a.png", photo);
  Image half;
  {
    // The rendering at half resolution: 2x2 block means of the photo.
    half = Image(kWidth / 2, kHeight / 2, 3);
    for (int y = 0; y < kHeight / 2; ++y) {
      for (int x = 0; x < kWidth / 2; ++x) {
        for (int c = 0; c < 3; ++c) {
          half.at(x, y, c) = (photo.at(2 * x, 2 * y, c) + photo.at(2 * x + 1, 2 * y, c) +
                              photo.at(2 * x, 2 * y + 1, c) + photo.at(2 * x + 1, 2 * y + 1, c)) /
                             4;
        }
      }
    }
  }
  io::WriteExr(f.renders / "a.exr", half);
  CompareOptions options = Options(f);
  const std::string message = ErrorMessage([&] { RunCompare(options); });
  EXPECT_THAT(message, HasSubstr((f.renders / "a.exr").string()));
  EXPECT_THAT(message, HasSubstr((f.photos / "a.png").string()));
  EXPECT_THAT(message, HasSubstr("12x10"));
  EXPECT_THAT(message, HasSubstr("24x20"));
  EXPECT_TRUE(FolderEntries(f.out).empty());

  options.resize = true;
  options.metrics = {Metric::kCbCr, Metric::kOneMinusNcc};
  const CompareResult result = RunCompare(options);
  ASSERT_EQ(result.images.size(), 1u);
  EXPECT_TRUE(result.images[0].resized);
  EXPECT_EQ(result.images[0].width, kWidth);
  EXPECT_EQ(result.images[0].completeness.value, 1.0);
  EXPECT_GT(result.images[0].metrics[0].mean, 0.0);
  EXPECT_EQ(ReadJson(f.out / "summary.json")["counts"]["resized"], 1);
}

TEST(Compare, CorruptFileIsNamedAndLeavesPreviousResultsIntact) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  for (const char* name : {"a", "b", "c"}) {
    const Image image = RandomImage(rng);
    io::WritePng(f.photos / (std::string(name) + ".png"), image);
    io::WritePng(f.renders / (std::string(name) + ".png"), image);
  }
  CompareOptions options = Options(f);
  options.metrics = {Metric::kCbCr};
  RunCompare(options);
  const std::string summary = ReadFileToString(f.out / "summary.json");
  const std::string csv = ReadFileToString(f.out / "per_image.csv");

  // Truncate c's rendering inside its pixel data: the header still reads, decoding fails
  // after a and b were compared and their error images staged.
  const std::string png = ReadFileToString(f.renders / "c.png");
  WriteTextFileAtomically(f.renders / "c.png", png.substr(0, png.size() - 40));
  options.metrics = {Metric::kCbCr, Metric::kCensus};
  const std::string message = ErrorMessage([&] { RunCompare(options); });
  EXPECT_THAT(message, ::testing::StartsWith((f.renders / "c.png").string() + ": "));
  EXPECT_EQ(message.find('\n'), std::string::npos);
  EXPECT_EQ(ReadFileToString(f.out / "summary.json"), summary);
  EXPECT_EQ(ReadFileToString(f.out / "per_image.csv"), csv);
  EXPECT_EQ(FolderEntries(f.out),
            (std::vector<std::string>{".rephoto-run", "errors", "per_image.csv", "summary.json"}));
  EXPECT_FALSE(fs::exists(f.out / "errors" / "a.census.exr"));

  // A file that is not an image at all is named too, before any pair is compared.
  WriteTextFileAtomically(f.photos / "b.png", "not a png");
  EXPECT_THAT(ErrorMessage([&] { RunCompare(options); }),
              ::testing::StartsWith((f.photos / "b.png").string() + ": "));
}

// Windows of side 9 fully inside [x0, x1) x [0, kHeight), as the centre count.
size_t WindowsInside(int x0, int x1) {
  const int xs = std::max(0, (x1 - x0) - 8), ys = kHeight - 8;
  return static_cast<size_t>(xs) * ys;
}

TEST(Compare, AlphaBlackAndMaskFoldersDecideValidity) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  const Image photo = RandomImage(rng);
  for (const char* name : {"alpha", "black", "masked"}) {
    io::WritePng(f.photos / (std::string(name) + ".png"), photo);
  }
  // alpha: RGBA copy of the photo, transparent for x < 8.
  Image rgba(kWidth, kHeight, 4);
  // black: the photo with x < 8 pure black (no alpha channel).
  Image black = photo;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      for (int c = 0; c < 3; ++c) rgba.at(x, y, c) = photo.at(x, y, c);
      rgba.at(x, y, 3) = x < 8 ? 0.f : 1.f;
      if (x < 8) black.at(x, y, 0) = black.at(x, y, 1) = black.at(x, y, 2) = 0.f;
    }
  }
  io::WritePng(f.renders / "alpha.png", rgba);
  io::WritePng(f.renders / "black.png", black);
  io::WritePng(f.renders / "masked.png", black);

  const size_t photo_windows = WindowsInside(0, kWidth);     // 16 x 12
  const size_t rendered_windows = WindowsInside(8, kWidth);  // 8 x 12
  CompareOptions options = Options(f);
  options.metrics = {Metric::kCbCr, Metric::kOneMinusNcc};
  {
    const CompareResult result = RunCompare(options);
    for (const ImageResult& image : result.images) {
      EXPECT_EQ(image.completeness.valid_photo, photo_windows) << image.name;
      EXPECT_EQ(image.completeness.valid_both, rendered_windows) << image.name;
      EXPECT_DOUBLE_EQ(image.completeness.value, 0.5) << image.name;
      // cb+cr is a pixel metric: the 16 x 20 covered pixels; 1-ncc: the valid windows.
      EXPECT_EQ(image.metrics[0].evaluated, 16u * kHeight) << image.name;
      EXPECT_EQ(image.metrics[0].mean, 0.0) << image.name;
      EXPECT_EQ(image.metrics[1].evaluated, rendered_windows) << image.name;
    }
  }
  // A render mask folder overrides black: all valid for "masked", x >= 12 for the others.
  const fs::path masks = f.root / "render_masks";
  Mask all(kWidth, kHeight, 1, 1), right(kWidth, kHeight, 1, 0);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 12; x < kWidth; ++x) right.at(x, y) = 1;
  }
  io::WritePng(masks / "masked.png", all);
  io::WritePng(masks / "alpha.png", right);
  options.render_masks = masks;
  EXPECT_THAT(ErrorMessage([&] { RunCompare(options); }),
              ::testing::AllOf(HasSubstr("no mask named 'black'"), HasSubstr(masks.string())));
  io::WritePng(masks / "black.png", right);
  {
    const CompareResult result = RunCompare(options);
    ASSERT_EQ(result.images.size(), 3u);
    EXPECT_EQ(result.images[0].name, "alpha");
    EXPECT_EQ(result.images[0].completeness.valid_both, WindowsInside(12, kWidth));
    EXPECT_EQ(result.images[1].completeness.valid_both, WindowsInside(12, kWidth));
    EXPECT_EQ(result.images[2].name, "masked");
    EXPECT_EQ(result.images[2].completeness.value, 1.0);
    // The black pixels are now compared against the photo: a nonzero error.
    EXPECT_GT(result.images[2].metrics[0].mean, 0.0);
  }
}

TEST(Compare, PhotoExposureAndPhotoMasks) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  Image photo = RandomImage(rng);
  for (int y = 0; y < kHeight; ++y) photo.at(kWidth - 1, y, 1) = 1.f;  // saturated column
  io::WritePng(f.photos / "p.png", photo);
  io::WritePng(f.renders / "p.png", photo);
  CompareOptions options = Options(f);
  options.metrics = {Metric::kCbCr};
  CompareResult result = RunCompare(options);
  // Saturated pixels are invalid in the photo: windows must end before the last column.
  EXPECT_EQ(result.images[0].completeness.valid_photo, WindowsInside(0, kWidth - 1));
  EXPECT_EQ(result.images[0].metrics[0].evaluated, static_cast<size_t>((kWidth - 1) * kHeight));
  options.exposure.saturated_threshold = 1.5f;  // exposure test off
  result = RunCompare(options);
  EXPECT_EQ(result.images[0].completeness.valid_photo, WindowsInside(0, kWidth));

  // A user photo mask (x < 4 ignored) removes those pixels from both counts.
  Mask mask(kWidth, kHeight, 1, 1);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < 4; ++x) mask.at(x, y) = 0;
  }
  io::WritePng(f.root / "photo_masks" / "p.png", mask);
  options.photo_masks = f.root / "photo_masks";
  result = RunCompare(options);
  EXPECT_EQ(result.images[0].completeness.valid_photo, WindowsInside(4, kWidth));
  EXPECT_EQ(result.images[0].completeness.value, 1.0);
  EXPECT_EQ(result.images[0].metrics[0].evaluated, static_cast<size_t>((kWidth - 4) * kHeight));
}

// Full-range BT.601 (JPEG) chroma of an 8-bit colour, in [0,1] units.
double Cb(double r, double g, double b) { return (-0.168736 * r - 0.331264 * g + 0.5 * b) / 255; }
double Cr(double r, double g, double b) { return (0.5 * r - 0.418688 * g - 0.081312 * b) / 255; }

TEST(Compare, HandComputedCbCrAndPsnrInCsvAndJson) {
  const Folders f = MakeFolders();
  // Two uniform pairs: every pixel has the same error, so the means are the pixel values.
  io::WritePng(f.photos / "one.png", Constant(100, 150, 200));
  io::WritePng(f.renders / "one.png", Constant(110, 140, 190));
  io::WritePng(f.photos / "two.png", Constant(60, 60, 60));
  io::WritePng(f.renders / "two.png", Constant(60, 90, 30));
  const double cbcr_one = std::abs(Cb(100, 150, 200) - Cb(110, 140, 190)) +
                          std::abs(Cr(100, 150, 200) - Cr(110, 140, 190));
  const double cbcr_two =
      std::abs(Cb(60, 60, 60) - Cb(60, 90, 30)) + std::abs(Cr(60, 60, 60) - Cr(60, 90, 30));
  const double mse_one = (10.0 * 10 + 10 * 10 + 10 * 10) / 3 / (255.0 * 255);
  const double mse_two = (0.0 + 30 * 30 + 30 * 30) / 3 / (255.0 * 255);
  const double psnr_one = 10 * std::log10(1 / mse_one), psnr_two = 10 * std::log10(1 / mse_two);

  CompareOptions options = Options(f);
  options.metrics = {Metric::kCbCr, Metric::kPsnr};
  const CompareResult result = RunCompare(options);
  ASSERT_EQ(result.images.size(), 2u);
  EXPECT_NEAR(result.images[0].metrics[0].mean, cbcr_one, 1e-6);
  EXPECT_NEAR(result.images[1].metrics[0].mean, cbcr_two, 1e-6);
  EXPECT_NEAR(result.images[0].metrics[1].mean, psnr_one, 1e-4);
  EXPECT_NEAR(result.images[1].metrics[1].mean, psnr_two, 1e-4);

  const auto rows = io::ReadCsvFile(f.out / "per_image.csv");
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"name", "status", "photo", "render", "width",
                                               "height", "resized", "completeness",
                                               "valid_photo_windows", "valid_both_windows", "cb+cr",
                                               "cb+cr_evaluated", "psnr", "psnr_evaluated"}));
  EXPECT_EQ(rows[1][0], "one");
  EXPECT_EQ(rows[1][4], "24");
  EXPECT_EQ(rows[1][5], "20");
  EXPECT_EQ(rows[1][7], "1");
  EXPECT_NEAR(std::stod(rows[1][10]), cbcr_one, 1e-6);
  EXPECT_EQ(rows[1][11], std::to_string(kWidth * kHeight));
  EXPECT_NEAR(std::stod(rows[2][12]), psnr_two, 1e-4);
  // The CSV holds the exact doubles of the result.
  EXPECT_EQ(std::stod(rows[2][10]), result.images[1].metrics[0].mean);

  const nlohmann::json summary = ReadJson(f.out / "summary.json");
  const auto& cbcr = summary["metrics"]["cb+cr"];
  EXPECT_NEAR(cbcr["mean"].get<double>(), (cbcr_one + cbcr_two) / 2, 1e-6);
  EXPECT_NEAR(cbcr["min"].get<double>(), std::min(cbcr_one, cbcr_two), 1e-6);
  EXPECT_NEAR(cbcr["max"].get<double>(), std::max(cbcr_one, cbcr_two), 1e-6);
  // numpy type-7 quantiles of two values: q1 = a + (b - a) / 4.
  EXPECT_NEAR(cbcr["q1"].get<double>(),
              std::min(cbcr_one, cbcr_two) + std::abs(cbcr_one - cbcr_two) / 4, 1e-6);
  EXPECT_NEAR(cbcr["median"].get<double>(), (cbcr_one + cbcr_two) / 2, 1e-6);
  EXPECT_EQ(cbcr["images"], 2);
  EXPECT_EQ(cbcr["evaluated"], 2 * kWidth * kHeight);
  EXPECT_EQ(cbcr["higher_is_better"], false);
  EXPECT_EQ(cbcr["error_png_range"][1], 0.25);
  // Equal pixel counts: pooled cb+cr = mean; pooled PSNR = PSNR of the mean MSE.
  EXPECT_NEAR(cbcr["pooled"].get<double>(), (cbcr_one + cbcr_two) / 2, 1e-6);
  EXPECT_NEAR(summary["metrics"]["psnr"]["pooled"].get<double>(),
              10 * std::log10(2 / (mse_one + mse_two)), 1e-4);
  EXPECT_EQ(summary["metrics"]["psnr"]["higher_is_better"], true);
  EXPECT_EQ(summary["parameters"]["metrics"], (nlohmann::json{"cb+cr", "psnr"}));
  EXPECT_EQ(summary["parameters"]["window"], 9);
  EXPECT_EQ(summary["tool"]["version"], ToolVersion());

  // Error images: the value everywhere, the jet colour of value / 0.25 in the PNG.
  const Image error = io::ReadImage(f.out / "errors" / "one.cb+cr.exr");
  EXPECT_NEAR(error.at(3, 7), cbcr_one, 1e-6);
  const Image png = io::ReadImage(f.out / "errors" / "one.cb+cr.png");
  const auto colour = JetColor(static_cast<float>(error.at(3, 7) / 0.25));
  for (int c = 0; c < 3; ++c) EXPECT_EQ(png.at(3, 7, c), std::round(colour[c] * 255.f) / 255.f);
}

TEST(Compare, GreyPhotoAgainstRgbRendering) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  Image grey(kWidth, kHeight, 1);
  Image rgb(kWidth, kHeight, 3);
  std::uniform_int_distribution<int> value(10, 245);
  for (size_t i = 0; i < grey.size(); ++i) {
    grey.data()[i] = value(rng) / 255.f;
    for (int c = 0; c < 3; ++c) rgb.data()[3 * i + c] = grey.data()[i];
  }
  io::WritePng(f.photos / "g.png", grey);
  io::WritePng(f.renders / "g.png", rgb);
  CompareOptions options = Options(f);
  options.metrics = {Metric::kZssd, Metric::kCbCr};
  const CompareResult result = RunCompare(options);
  EXPECT_EQ(result.images[0].metrics[0].mean, 0.0);
  EXPECT_EQ(result.images[0].metrics[1].mean, 0.0);
}

TEST(Compare, PrefetchDoesNotChangeResultsAndRerunReplacesErrorImages) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  for (int i = 0; i < 4; ++i) {
    io::WritePng(f.photos / fmt::format("v{}.png", i), RandomImage(rng));
    io::WritePng(f.renders / fmt::format("v{}.png", i), RandomImage(rng));
  }
  CompareOptions options = Options(f);
  options.metrics = {Metric::kOneMinusNcc, Metric::kCensus};
  options.prefetch = false;
  const CompareResult serial = RunCompare(options);
  const std::string serial_csv = ReadFileToString(f.out / "per_image.csv");
  options.prefetch = true;
  const CompareResult overlapped = RunCompare(options);
  EXPECT_EQ(ReadFileToString(f.out / "per_image.csv"), serial_csv);
  ASSERT_EQ(serial.images.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(serial.images[i].metrics[0].mean, overlapped.images[i].metrics[0].mean);
  }
  EXPECT_TRUE(fs::exists(f.out / "errors" / "v3.census.png"));

  options.metrics = {Metric::kCbCr};
  RunCompare(options);
  EXPECT_FALSE(fs::exists(f.out / "errors" / "v3.census.png"));
  EXPECT_TRUE(fs::exists(f.out / "errors" / "v3.cb+cr.png"));
  options.write_error_images = false;
  RunCompare(options);
  EXPECT_EQ(FolderEntries(f.out),
            (std::vector<std::string>{".rephoto-run", "per_image.csv", "summary.json"}));
}

// The in-memory entry point (the Python package's) is RunCompare's per-pair function: same
// values bit for bit, and the error images equal the EXR files, here with a resized RGBA
// rendering and 8-bit as well as float inputs.
TEST(Compare, InMemoryEqualsRunCompareAndItsErrorImages) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  Image render = RandomImage(rng, kWidth / 2, kHeight / 2);
  Image rgba(render.width(), render.height(), 4);
  for (size_t i = 0; i < render.pixel_count(); ++i) {
    for (int c = 0; c < 3; ++c) rgba.data()[4 * i + c] = render.data()[3 * i + c];
    rgba.data()[4 * i + 3] = i % 7 == 3 ? 0.f : 1.f;  // a few pixels not covered
  }
  io::WritePng(f.photos / "a.png", RandomImage(rng));
  io::WritePng(f.renders / "a.png", rgba);
  CompareOptions options = Options(f);
  options.resize = true;
  const CompareResult run = RunCompare(options);
  ASSERT_EQ(run.images.size(), 1u);
  const ImageResult& expected = run.images[0];
  ASSERT_TRUE(expected.resized);

  Image8 photo8, render8;
  Image photo_float, render_float;
  ASSERT_TRUE(io::ReadImage8(f.photos / "a.png", &photo8, &photo_float));
  ASSERT_TRUE(io::ReadImage8(f.renders / "a.png", &render8, &render_float));
  photo_float = io::ReadImage(f.photos / "a.png");
  render_float = io::ReadImage(f.renders / "a.png");
  CompareWorkspace workspace;
  std::vector<Image> errors;
  options.write_error_images = true;  // ignored: nothing is written
  const ImageResult bytes =
      CompareInMemory(options, photo8, render8, nullptr, nullptr, &errors, &workspace);
  const ImageResult floats =
      CompareInMemory(options, photo_float, render_float, nullptr, nullptr, nullptr, &workspace);
  for (const ImageResult* result : {&bytes, &floats}) {
    EXPECT_TRUE(result->resized);
    EXPECT_EQ(result->completeness.valid_both, expected.completeness.valid_both);
    ASSERT_EQ(result->metrics.size(), options.metrics.size());
    for (size_t i = 0; i < options.metrics.size(); ++i) {
      EXPECT_EQ(result->metrics[i].evaluated, expected.metrics[i].evaluated);
      const double a = result->metrics[i].mean, b = expected.metrics[i].mean;
      EXPECT_TRUE(a == b || (std::isnan(a) && std::isnan(b)))
          << metrics::MetricName(options.metrics[i]) << " " << a << " vs " << b;
    }
  }
  ASSERT_EQ(errors.size(), options.metrics.size());
  for (size_t i = 0; i < options.metrics.size(); ++i) {
    const Image exr = io::ReadImage(
        f.out / "errors" / fmt::format("a.{}.exr", metrics::MetricName(options.metrics[i])));
    ASSERT_TRUE(exr.SameSize(errors[i]));
    for (size_t p = 0; p < exr.size(); ++p) {
      const float a = errors[i].data()[p], b = exr.data()[p];
      ASSERT_TRUE(a == b || (std::isnan(a) && std::isnan(b))) << p;
    }
  }
  EXPECT_EQ(FolderEntries(f.out / "errors").size(), 2 * options.metrics.size());
  EXPECT_FALSE(fs::exists(fs::current_path() / ".psnr.exr"));  // nothing written in memory mode

  options.metrics = {Metric::kPsnr, Metric::kPsnr};
  try {
    CompareInMemory(options, photo8, render8, nullptr, nullptr, nullptr, &workspace);
    ADD_FAILURE() << "no error";
  } catch (const UsageError& e) {
    EXPECT_STREQ(e.what(), "metric 'psnr' is listed twice");
  }
}

// issue 18: evaluate compares a view and writes its error images later, in a background
// writer: ComparePhotoAndRender with `error_images` writes nothing, and WriteErrorImages then
// writes the very files (bytes) and the same result the streaming path gives.
TEST(Compare, ErrorImagesReturnedAndWrittenLaterAreTheStreamedFiles) {
  auto rng = testing::MakeRng();
  const fs::path dir = testing::MakeTempDir();
  for (const fs::path sub : {"streamed", "later"}) fs::create_directories(dir / sub);
  Image photo = RandomImage(rng, 70, 45);
  Image render(70, 45, 4);
  for (size_t i = 0; i < render.pixel_count(); ++i) {
    for (int c = 0; c < 3; ++c) {
      render.data()[4 * i + c] = std::clamp(photo.data()[3 * i + c] + 0.1f * (c - 1), 0.f, 1.f);
    }
    render.data()[4 * i + 3] = i % 11 == 5 ? 0.f : 1.f;
  }
  CompareOptions options;
  options.metrics = metrics::AllMetrics();
  CompareWorkspace workspace;
  const ImageResult streamed =
      ComparePhotoAndRender(options, "v", "p.png", "r.png", photo, render, nullptr, nullptr,
                            dir / "streamed", &workspace);
  std::vector<Image> errors;
  const ImageResult later =
      ComparePhotoAndRender(options, "v", "p.png", "r.png", photo, render, nullptr, nullptr,
                            dir / "later", &workspace, &errors);
  EXPECT_TRUE(FolderEntries(dir / "later").empty());
  EXPECT_EQ(later.name, streamed.name);
  EXPECT_EQ(later.completeness.valid_both, streamed.completeness.valid_both);
  ASSERT_EQ(later.metrics.size(), streamed.metrics.size());
  for (size_t i = 0; i < later.metrics.size(); ++i) {
    const double a = later.metrics[i].mean, b = streamed.metrics[i].mean;
    EXPECT_TRUE(a == b || (std::isnan(a) && std::isnan(b))) << i;
  }
  std::vector<uint8_t> rgba;
  WriteErrorImages(errors, options.metrics, dir / "later", "v", &rgba);
  const std::vector<std::string> files = FolderEntries(dir / "streamed");
  EXPECT_EQ(files.size(), 2 * options.metrics.size());
  EXPECT_EQ(FolderEntries(dir / "later"), files);
  for (const std::string& file : files) {
    EXPECT_EQ(ReadFileToString(dir / "later" / file), ReadFileToString(dir / "streamed" / file))
        << file;
  }
  EXPECT_THROW(WriteErrorImages(errors, {Metric::kPsnr}, dir / "later", "v", &rgba), Error);
  fs::remove_all(dir);
}

// Error images of some metrics only: the other metrics are computed all the same, and the files
// written are those of the full run for the chosen metrics, byte for byte.
TEST(Compare, ErrorImageMetricsWriteOnlyTheirFiles) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  io::WritePng(f.photos / "a.png", RandomImage(rng));
  io::WritePng(f.renders / "a.png", RandomImage(rng));
  const CompareOptions all = Options(f);
  const CompareResult full = RunCompare(all);
  CompareOptions some = all;
  some.out = f.root / "some";
  some.error_image_metrics = {Metric::kDssim, Metric::kCensus};
  const CompareResult part = RunCompare(some);
  EXPECT_EQ(
      FolderEntries(some.out / "errors"),
      (std::vector<std::string>{"a.census.exr", "a.census.png", "a.dssim.exr", "a.dssim.png"}));
  for (const std::string& file : FolderEntries(some.out / "errors")) {
    EXPECT_EQ(ReadFileToString(some.out / "errors" / file),
              ReadFileToString(all.out / "errors" / file))
        << file;
  }
  ASSERT_EQ(part.images.size(), 1u);
  for (size_t i = 0; i < all.metrics.size(); ++i) {
    const double a = part.images[0].metrics[i].mean, b = full.images[0].metrics[i].mean;
    EXPECT_TRUE(a == b || (std::isnan(a) && std::isnan(b))) << i;
  }
  EXPECT_TRUE(WritesErrorImage(some, Metric::kDssim));
  EXPECT_FALSE(WritesErrorImage(some, Metric::kOneMinusNcc));
  EXPECT_TRUE(WritesErrorImage(all, Metric::kOneMinusNcc));
}

// issue 14: compare --out never destroys a folder it did not make, has one writer, and a
// failure leaves no empty folder behind.
TEST(Compare, RefusesAFolderItDidNotMakeAndLeavesItUntouched) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  const Image image = RandomImage(rng);
  io::WritePng(f.photos / "a.png", image);
  io::WritePng(f.renders / "a.png", image);
  fs::create_directories(f.out / "errors");
  WriteTextFileAtomically(f.out / "errors" / "notes.txt", "mine");
  WriteTextFileAtomically(f.out / "per_image.csv", "my table");
  CompareOptions options = Options(f);
  EXPECT_EQ(ErrorMessage([&] { RunCompare(options); }),
            f.out.string() +
                ": the folder is not empty and holds no rephoto compare run; use an empty or "
                "new --out");
  EXPECT_EQ(ReadFileToString(f.out / "errors" / "notes.txt"), "mine");
  EXPECT_EQ(ReadFileToString(f.out / "per_image.csv"), "my table");
  EXPECT_EQ(FolderEntries(f.out), (std::vector<std::string>{"errors", "per_image.csv"}));

  // Its own folder is replaced as a whole on a rerun.
  options.out = f.root / "own";
  RunCompare(options);
  const std::string csv = ReadFileToString(options.out / "per_image.csv");
  RunCompare(options);
  EXPECT_EQ(ReadFileToString(options.out / "per_image.csv"), csv);

  // A second writer at the same time is refused at once.
  run::RunFolder writer = run::OpenRunFolder(options.out, "compare");
  EXPECT_THAT(ErrorMessage([&] { RunCompare(options); }),
              HasSubstr("another rephoto compare (pid "));
}

TEST(Compare, ADecodeErrorLeavesNoOutputFolder) {
  const Folders f = MakeFolders();
  WriteTextFileAtomically(f.photos / "a.png", "not a png");
  WriteTextFileAtomically(f.renders / "a.png", "not a png either");
  CompareOptions options = Options(f);
  EXPECT_THAT(ErrorMessage([&] { RunCompare(options); }),
              ::testing::StartsWith((f.photos / "a.png").string() + ": "));
  EXPECT_FALSE(fs::exists(f.out));
}

TEST(Compare, InvalidOptionsAreRejected) {
  const Folders f = MakeFolders();
  CompareOptions options = Options(f);
  options.metric_options.window = 4;
  EXPECT_THAT(ErrorMessage([&] { options.Check(); }), HasSubstr("odd"));
  options = Options(f);
  options.metrics = {Metric::kCbCr, Metric::kCbCr};
  EXPECT_THAT(ErrorMessage([&] { options.Check(); }), HasSubstr("twice"));
  options = Options(f);
  options.exposure.dark_threshold = 0.9f;
  options.exposure.saturated_threshold = 0.5f;
  EXPECT_THAT(ErrorMessage([&] { options.Check(); }), HasSubstr("dark threshold"));
  options = Options(f);
  options.min_alpha = 1.5;
  EXPECT_THAT(ErrorMessage([&] { options.Check(); }), HasSubstr("minimum alpha must be in [0, 1]"));
  options.min_alpha = 0.5;
  options.compat = metrics::CompatPreset::k3dgs;
  EXPECT_THAT(ErrorMessage([&] { options.Check(); }), HasSubstr("compat"));
}

// issue 30: min_alpha, the coverage rule `rephoto evaluate` applies to Gaussian renderings,
// owned by compare. Alpha by column band: x < 4: 0.25, 4 <= x < 8: 0.5, 8 <= x < 12: 0.75,
// x >= 12: 1. With the 9x9 window the photo has 16 x 12 windows; a threshold that drops the
// bands left of x0 leaves WindowsInside(x0, 24) = (24 - x0 - 8) x 12 of them, so completeness
// is exactly 1, 12/16, 8/16, 4/16 for min_alpha 0 (alpha > 0), 0.5, 0.75, 1.
float BandAlpha(int x) { return x < 4 ? 0.25f : x < 8 ? 0.5f : x < 12 ? 0.75f : 1.f; }

TEST(Compare, MinAlphaCountsPixelsWhoseAlphaReachesIt) {
  auto rng = testing::MakeRng();
  const Image photo = RandomImage(rng);
  Image render(kWidth, kHeight, 4);
  // In a PNG: 8-bit alphas 63, 128, 192, 255 (v / 255 = 0.247, 0.502, 0.753, 1), on the same
  // sides of 0.5, 0.75 and 1 as the exact values of the in-memory rendering below.
  Image render_png(kWidth, kHeight, 4);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      for (int c = 0; c < 3; ++c) render.at(x, y, c) = render_png.at(x, y, c) = photo.at(x, y, c);
      render.at(x, y, 3) = BandAlpha(x);
      render_png.at(x, y, 3) = std::array<float, 4>{63, 128, 192, 255}[x < 4    ? 0
                                                                       : x < 8  ? 1
                                                                       : x < 12 ? 2
                                                                                : 3] /
                               255.f;
    }
  }
  const Folders f = MakeFolders();
  io::WritePng(f.photos / "a.png", photo);
  io::WritePng(f.renders / "a.png", render_png);
  const size_t photo_windows = WindowsInside(0, kWidth);
  ASSERT_EQ(photo_windows, 16u * 12u);
  const std::vector<std::pair<double, int>> cases = {{0, 0}, {0.5, 4}, {0.75, 8}, {1, 12}};
  for (const auto& [min_alpha, first_covered] : cases) {
    SCOPED_TRACE(min_alpha);
    CompareOptions options = Options(f);
    options.metrics = {Metric::kCbCr};
    options.min_alpha = min_alpha;
    const double expected = static_cast<double>(WindowsInside(first_covered, kWidth)) /
                            static_cast<double>(photo_windows);
    // RunCompare on the PNG (8-bit samples).
    const CompareResult run = RunCompare(options);
    ASSERT_EQ(run.images.size(), 1u);
    EXPECT_EQ(run.images[0].completeness.valid_photo, photo_windows);
    EXPECT_EQ(run.images[0].completeness.valid_both, WindowsInside(first_covered, kWidth));
    EXPECT_EQ(run.images[0].completeness.value, expected);
    EXPECT_EQ(run.images[0].metrics[0].evaluated,
              static_cast<size_t>((kWidth - first_covered) * kHeight));
    const nlohmann::json parameters = ReadJson(f.out / "summary.json")["parameters"];
    if (min_alpha > 0) {
      EXPECT_EQ(parameters["min_alpha"], min_alpha);
    } else {
      EXPECT_FALSE(parameters.contains("min_alpha"));  // runs without it stay as they were
    }
    // In memory on the float rendering: exact alphas 0.5, 0.75, 1 reach their threshold.
    CompareWorkspace workspace;
    const ImageResult in_memory =
        CompareInMemory(options, photo, render, nullptr, nullptr, nullptr, &workspace);
    EXPECT_EQ(in_memory.completeness.value, expected);
    // An explicit rendering mask still overrides alpha.
    Mask all(kWidth, kHeight, 1);
    std::fill(all.data(), all.data() + all.size(), uint8_t{1});
    EXPECT_EQ(CompareInMemory(options, photo, render, nullptr, &all, nullptr, &workspace)
                  .completeness.value,
              1.0);
  }
}

// issue 30: image_list compares only the listed images, by stem; unlisted ones are neither
// compared nor missing.
TEST(Compare, ImageListSelectsImagesByStem) {
  auto rng = testing::MakeRng();
  const Folders f = MakeFolders();
  for (const char* name : {"a", "b", "c", "d"}) {
    io::WritePng(f.photos / (std::string(name) + ".png"), RandomImage(rng));
  }
  for (const char* name : {"a", "b", "c", "e"}) {
    io::WritePng(f.renders / (std::string(name) + ".png"), RandomImage(rng));
  }
  const fs::path list = f.root / "test.txt";
  CompareOptions options = Options(f);
  options.metrics = {Metric::kCbCr};
  options.image_list = list;
  // Names as a split writes them (scene names with their extension and folders).
  WriteTextFileAtomically(list, "# test views\nimages/b.JPG\n\n./c.jpg\n");
  {
    const CompareResult result = RunCompare(options);
    EXPECT_EQ(result.exit_code(), ExitCode::kOk);
    ASSERT_EQ(result.images.size(), 2u);
    EXPECT_EQ(result.images[0].name, "b");
    EXPECT_EQ(result.images[1].name, "c");
    EXPECT_TRUE(result.missing.empty());
    EXPECT_EQ(result.photo_count, 2u);
    EXPECT_EQ(result.render_count, 2u);
    const auto rows = io::ReadCsvFile(f.out / "per_image.csv");
    ASSERT_EQ(rows.size(), 3u);
    EXPECT_EQ(rows[1][0], "b");
    EXPECT_EQ(rows[2][0], "c");
    EXPECT_EQ(ReadJson(f.out / "summary.json")["parameters"]["image_list"], list.string());
  }
  // A listed image without its rendering is missing as without a list.
  WriteTextFileAtomically(list, "a\nd\n");
  {
    const CompareResult result = RunCompare(options);
    EXPECT_EQ(result.exit_code(), ExitCode::kIncomplete);
    ASSERT_EQ(result.images.size(), 1u);
    ASSERT_EQ(result.missing.size(), 1u);
    EXPECT_EQ(result.missing[0].name, "d");
    EXPECT_EQ(result.missing[0].missing, Missing::kRender);
    EXPECT_EQ(io::ReadCsvFile(f.out / "per_image.csv").size(), 3u);
  }
  // Hostile or mistaken lists: one Error naming the file and line; nothing written.
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"a\n../b.png\n", ":2: image name '../b.png' contains '..'"},
      {"a\n" + f.photos.string() + "/b.png\n",
       ":2: image name '" + f.photos.string() + "/b.png' is an absolute path"},
      {"b.png\nsub/b.jpg\n",
       ":2: image 'sub/b.jpg' is already listed at " + list.string() + ":1 as 'b.png'"},
      {"a\n\nz.png\n", ":3: image 'z.png' has neither a photo in " + f.photos.string() +
                           " nor a rendering in " + f.renders.string()},
      {"# nothing\n", ": the image list names no image"}};
  for (const auto& [text, message] : bad) {
    SCOPED_TRACE(text);
    fs::remove_all(f.out);
    WriteTextFileAtomically(list, text);
    EXPECT_THAT(ErrorMessage([&] { RunCompare(options); }),
                ::testing::StartsWith(list.string() + message));
    EXPECT_FALSE(fs::exists(f.out));
  }
}

}  // namespace
}  // namespace rephoto::compare
