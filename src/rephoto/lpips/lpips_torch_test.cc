// LPIPS against an independent PyTorch implementation of the lpips package's forward pass
// (lpips_reference.py, Debian python3-torch / python3-torchvision): random-weight AlexNet and
// VGG16 with lin layers in the lpips layout, saved by torch.save under the original file names
// (two files in the zip format, two in the legacy format), several image pairs including odd
// sizes. Whole-image value, masked value (spatial map over a mask) and the all-pixel spatial
// mean: <= 1e-5 absolute. Skipped, with the reason, when torch cannot be imported.
#include "rephoto/lpips/lpips.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/isa.h"
#include "rephoto/core/limits.h"
#include "rephoto/core/parallel.h"
#include "rephoto/testing/testing.h"

namespace rephoto::lpips {
namespace {
namespace fs = std::filesystem;

constexpr double kTolerance = 1e-5;

class LpipsTorch : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() /
                        ("rephoto_lpips_test_" + std::to_string(::getpid())));
    fs::create_directories(*dir_);
    const std::string script =
        (testing::SourceDir() / "src/rephoto/lpips/lpips_reference.py").string();
    const testing::ShellOutcome outcome =
        testing::RunShell("/usr/bin/python3 " + script + " " + dir_->string());
    if (outcome.exit_code == 77) {
      skip_ = new std::string("python3-torch/python3-torchvision not installed: " + outcome.err);
      return;
    }
    ASSERT_EQ(outcome.exit_code, 0) << outcome.err;
    reference_ = new nlohmann::json(nlohmann::json::parse(ReadFileToString(*dir_ / "reference.json")));
  }
  static void TearDownTestSuite() {
    if (dir_) fs::remove_all(*dir_);
  }
  void SetUp() override {
    if (skip_) GTEST_SKIP() << *skip_;
  }

  static Image ReadPair(const std::string& prefix, int index, int width, int height) {
    Image image(width, height, 3);
    std::ifstream in(*dir_ / fmt::format("{}_{}.f32", prefix, index), std::ios::binary);
    in.read(reinterpret_cast<char*>(image.data()),
            static_cast<std::streamsize>(image.size() * sizeof(float)));
    EXPECT_TRUE(in.good());
    return image;
  }
  static Mask ReadMask(int index, int width, int height) {
    Mask mask(width, height, 1);
    std::ifstream in(*dir_ / fmt::format("m_{}.u8", index), std::ios::binary);
    in.read(reinterpret_cast<char*>(mask.data()), static_cast<std::streamsize>(mask.size()));
    EXPECT_TRUE(in.good());
    return mask;
  }

  void CheckNet(LpipsNet net) {
    const auto model = LpipsModel::Load(*dir_, net);
    int checked = 0;
    for (const nlohmann::json& pair : (*reference_)["pairs"]) {
      const std::string name(LpipsNetName(net));
      if (!pair.contains(name)) continue;
      const int i = pair["index"], w = pair["width"], h = pair["height"];
      const Image a = ReadPair("a", i, w, h), b = ReadPair("b", i, w, h);
      const Mask mask = ReadMask(i, w, h);
      const LpipsValue masked = model->Compute(a, b, &mask);
      const LpipsValue all = model->Compute(a, b, nullptr);
      const nlohmann::json& ref = pair[name];
      SCOPED_TRACE(fmt::format("{} pair {} ({}x{})", name, i, w, h));
      EXPECT_NEAR(masked.whole, ref["whole"].get<double>(), kTolerance);
      EXPECT_NEAR(masked.masked, ref["masked"].get<double>(), kTolerance);
      EXPECT_NEAR(all.masked, ref["spatial_mean"].get<double>(), kTolerance);
      EXPECT_EQ(all.whole, masked.whole);
      size_t count = 0;
      for (size_t k = 0; k < mask.size(); ++k) count += mask.data()[k] != 0;
      EXPECT_EQ(masked.masked_pixels, count);
      EXPECT_EQ(all.masked_pixels, static_cast<size_t>(w) * h);
      EXPECT_GT(masked.whole, 1e-4);  // not a trivial agreement at 0
      ++checked;
    }
    EXPECT_GE(checked, 3);
  }

  static fs::path* dir_;
  static nlohmann::json* reference_;
  static std::string* skip_;
};
fs::path* LpipsTorch::dir_ = nullptr;
nlohmann::json* LpipsTorch::reference_ = nullptr;
std::string* LpipsTorch::skip_ = nullptr;

TEST_F(LpipsTorch, AlexMatchesTorch) { CheckNet(LpipsNet::kAlex); }

TEST_F(LpipsTorch, VggMatchesTorch) { CheckNet(LpipsNet::kVgg); }

TEST_F(LpipsTorch, IdenticalImagesGiveZero) {
  const auto model = LpipsModel::LoadShared(*dir_, LpipsNet::kAlex);
  const Image a = ReadPair("a", 1, 131, 97);
  const LpipsValue v = model->Compute(a, a, nullptr);
  EXPECT_EQ(v.whole, 0.0);
  EXPECT_EQ(v.masked, 0.0);
}

TEST_F(LpipsTorch, EightBitInputEqualsFloat) {
  const auto model = LpipsModel::LoadShared(*dir_, LpipsNet::kAlex);
  const Image a = ReadPair("a", 2, 200, 151), b = ReadPair("b", 2, 200, 151);
  Image8 a8(200, 151, 4);  // RGBA: alpha ignored
  for (size_t p = 0; p < a.pixel_count(); ++p) {
    for (int c = 0; c < 3; ++c) {
      a8.data()[4 * p + c] = static_cast<uint8_t>(std::lround(a.data()[3 * p + c] * 255.f));
    }
    a8.data()[4 * p + 3] = 7;
  }
  EXPECT_EQ(model->Compute(a8, b, nullptr).whole, model->Compute(a, b, nullptr).whole);
  // Whole-image only (--compat): the same whole value, no masked one.
  const LpipsValue whole_only = model->Compute(a, b, nullptr, nullptr, /*masked=*/false);
  EXPECT_EQ(whole_only.whole, model->Compute(a, b, nullptr).whole);
  EXPECT_TRUE(std::isnan(whole_only.masked));
  EXPECT_EQ(whole_only.masked_pixels, 0u);
}

// The same bits on every thread count and every REPHOTO_ISA path (oneDNN is capped at AVX2).
TEST_F(LpipsTorch, SameBitsOnEveryPathAndThreadCount) {
  const auto model = LpipsModel::LoadShared(*dir_, LpipsNet::kAlex);
  const Image a = ReadPair("a", 2, 200, 151), b = ReadPair("b", 2, 200, 151);
  const Mask mask = ReadMask(2, 200, 151);
  const LpipsValue first = model->Compute(a, b, &mask);
  for (core::Isa isa : core::SupportedIsas()) {
    core::ScopedIsa scoped(isa);
    for (int threads : {1, 2}) {
      ThreadLimit limit(threads);
      const LpipsValue v = model->Compute(a, b, &mask);
      EXPECT_EQ(v.whole, first.whole) << core::IsaName(isa) << " " << threads;
      EXPECT_EQ(v.masked, first.masked) << core::IsaName(isa) << " " << threads;
    }
  }
}

TEST_F(LpipsTorch, WrongShapesAndSmallImagesAreErrors) {
  const auto model = LpipsModel::LoadShared(*dir_, LpipsNet::kAlex);
  const Image a(30, 40, 3), b(30, 40, 3);
  EXPECT_NE(testing::ErrorOf([&] { model->Compute(a, b, nullptr); }).find("too small"),
            std::string::npos);
  // The lin file of VGG where AlexNet's is expected: a shape error naming file and tensor.
  const fs::path mixed = testing::MakeTempDir();
  fs::copy_file(*dir_ / "vgg.pth", mixed / "alex.pth");
  fs::create_symlink(*dir_ / "alexnet-owt-7be5be79.pth", mixed / "alexnet-owt-7be5be79.pth");
  const std::string error = testing::ErrorOf([&] { LpipsModel::Load(mixed, LpipsNet::kAlex); });
  EXPECT_NE(error.find("alex.pth: tensor 'lin1.model.1.weight' has shape [1, 128, 1, 1], "
                       "expected [1, 192, 1, 1]"),
            std::string::npos)
      << error;
}

// The activations' memory is checked before anything is allocated (core/limits.h).
TEST_F(LpipsTorch, MemoryLimitIsCheckedFirst) {
  const auto model = LpipsModel::LoadShared(*dir_, LpipsNet::kVgg);
  const Image a(200, 151, 3), b(200, 151, 3);
  const uint64_t before = MaxMemoryBytes();
  SetMaxMemoryBytes(uint64_t{1} << 20);
  const std::string error = testing::ErrorOf([&] { model->Compute(a, b, nullptr); });
  SetMaxMemoryBytes(before);
  EXPECT_NE(error.find("200x151 images through vgg"), std::string::npos) << error;
  EXPECT_NE(error.find("--max-memory"), std::string::npos) << error;
}

TEST(Lpips, MissingWeightsSayWhatAndHow) {
  const std::string error =
      testing::ErrorOf([] { LpipsModel::Load("/nonexistent/dir", LpipsNet::kAlex); });
  EXPECT_NE(error.find("alex.pth"), std::string::npos) << error;
  EXPECT_NE(error.find("alexnet-owt-7be5be79.pth"), std::string::npos);
  EXPECT_NE(error.find("/nonexistent/dir"), std::string::npos);
  EXPECT_NE(error.find("pip install lpips"), std::string::npos);
  EXPECT_NE(error.find("https://download.pytorch.org/models/alexnet-owt-7be5be79.pth"),
            std::string::npos);
  const std::string vgg = testing::ErrorOf([] { LpipsModel::Load("", LpipsNet::kVgg); });
  EXPECT_NE(vgg.find("vgg16-397923af.pth"), std::string::npos);
  EXPECT_NE(vgg.find("REPHOTO_LPIPS_WEIGHTS"), std::string::npos);
}

}  // namespace
}  // namespace rephoto::lpips
