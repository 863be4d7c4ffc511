// AddDataset: what is published, what stays secret, evaluation at a smaller size with masks,
// and refusals that leave nothing behind.
#include "rephoto/service/dataset.h"

#include <gtest/gtest.h>

#include "rephoto/service/submissions.h"
#include "rephoto/service/test_fixture.h"
#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"
#include "rephoto/testing/testing.h"

namespace rephoto::service {
namespace {
namespace fs = std::filesystem;

class DatasetTest : public ::testing::Test {
 protected:
  void SetUp() override {
    rng_ = rephoto::testing::MakeRng();
    base_ = rephoto::testing::MakeTempDir();
    testing::MakeTinyScene(base_ / "scene", 6, 64, 48, rng_);
    fs::create_directories(base_ / "root");
    options_.name = "tiny";
    options_.scene = base_ / "scene" / "sparse";
    options_.read_options.image_root = base_ / "scene" / "images";
    options_.scheme = "every:3";
    options_.metrics = metrics::ParseMetricList("1-ncc,psnr");
  }
  std::mt19937_64 rng_;
  fs::path base_;
  DatasetOptions options_;
};

TEST_F(DatasetTest, DownscalesTestPhotosMasksAndCamerasForEvalShortSide) {
  // Masks by stem: left half ignored.
  fs::create_directories(base_ / "masks");
  Mask mask(64, 48, 1, 0);
  for (int y = 0; y < 48; ++y) {
    for (int x = 32; x < 64; ++x) mask.at(x, y) = 1;
  }
  io::WritePng(base_ / "masks" / "00.png", mask);
  io::WritePng(base_ / "masks" / "03.png", mask);
  options_.eval_short_side = 24;
  options_.photo_masks = base_ / "masks";
  Store store(base_ / "root");
  AddDataset(store, options_);
  const DatasetRecord dataset = *store.FindDataset("tiny");
  EXPECT_EQ(dataset.info["settings"]["eval_short_side"], 24);
  EXPECT_EQ(dataset.info["settings"]["masks"], true);
  EXPECT_EQ(dataset.info["test_images"][0]["width"], 32);
  EXPECT_EQ(dataset.info["test_images"][0]["height"], 24);
  EXPECT_EQ(dataset.info["training_images"][0]["width"], 64);  // training photos as they are
  // Halving is a 2x2 box mean (area filter): check against the original's pixels by hand,
  // within 16-bit PNG quantisation.
  const Image original = io::ReadImage(base_ / "scene" / "images" / "03.png");
  const Image small = io::ReadImage(SecretPhotoFolder(base_ / "root", "tiny") / "03.png");
  ASSERT_EQ(small.width(), 32);
  ASSERT_EQ(small.height(), 24);
  for (const auto [x, y] : {std::pair{0, 0}, {5, 7}, {31, 23}}) {
    for (int c = 0; c < 3; ++c) {
      const double mean =
          (original.at(2 * x, 2 * y, c) + original.at(2 * x + 1, 2 * y, c) +
           original.at(2 * x, 2 * y + 1, c) + original.at(2 * x + 1, 2 * y + 1, c)) /
          4.0;
      EXPECT_NEAR(small.at(x, y, c), mean, 1.0 / 65535 + 1e-6) << x << "," << y << "," << c;
    }
  }
  const Mask small_mask = io::ReadMask(SecretMaskFolder(base_ / "root", "tiny") / "00.png");
  ASSERT_EQ(small_mask.width(), 32);
  EXPECT_EQ(small_mask.at(15, 10), 0);
  EXPECT_NE(small_mask.at(16, 10), 0);
  // The published test cameras are the scaled ones: fx 64 * 0.5.
  ASSERT_EQ(std::system(("mkdir -p '" + (base_ / "t").string() + "' && tar xf '" +
                         (base_ / "root/public/tiny/test-cameras.tar").string() + "' -C '" +
                         (base_ / "t").string() + "'")
                            .c_str()),
            0);
  EXPECT_NE(ReadFileToString(base_ / "t/sparse/cameras.txt").find("PINHOLE 32 24 32 32 16 12"),
            std::string::npos)
      << ReadFileToString(base_ / "t/sparse/cameras.txt");

  // A submission at the evaluation size is scored with the masks: renders equal to the
  // downscaled photos in the unmasked half and garbage in the masked half score zero error.
  SubmissionLimits limits;
  Submissions submissions(store, limits);
  std::vector<testing::TestEntry> entries;
  for (const std::string stem : {"00", "03"}) {
    const Image photo = io::ReadImage(SecretPhotoFolder(base_ / "root", "tiny") / (stem + ".png"));
    Image render(32, 24, 4, 1.0f);
    for (int y = 0; y < 24; ++y) {
      for (int x = 0; x < 32; ++x) {
        for (int c = 0; c < 3; ++c) render.at(x, y, c) = x < 16 ? 0.9f : photo.at(x, y, c);
      }
    }
    io::WritePng(base_ / (stem + ".png"), render, io::PngDepth::k16);
    entries.push_back({stem + ".png", ReadFileToString(base_ / (stem + ".png"))});
  }
  const ParticipantRecord participant{1, "p", false};
  store.AddParticipant("p");
  const std::string id = submissions.Submit(
      participant, "tiny", testing::MakeArchive(entries, testing::ArchiveFormat::kTar), "m", "");
  submissions.Score(id);
  const SubmissionRecord record = *store.FindSubmission(id);
  ASSERT_EQ(record.status, SubmissionStatus::kDone) << record.reason;
  EXPECT_NEAR(record.summary["metrics"]["1-ncc"]["mean"].get<double>(), 0.0, 1e-4);
  EXPECT_NE(record.summary["parameters"]["photo_masks"], nullptr);
  // The original size is refused.
  io::WritePng(base_ / "big.png", Image(64, 48, 4, 0.5f));
  EXPECT_EQ(rephoto::testing::ErrorOf([&] {
              submissions.Submit(
                  participant, "tiny",
                  testing::MakeArchive({{"00.png", ReadFileToString(base_ / "big.png")}},
                                       testing::ArchiveFormat::kTar),
                  "m", "");
            }),
            "render '00.png' is 64x48, test camera '00' is 32x24");
}

TEST_F(DatasetTest, RefusesBadSettingsAndPartialMasksLeavingNothingBehind) {
  Store store(base_ / "root");
  DatasetOptions bad = options_;
  bad.headline = "dssim";  // not among the metrics
  EXPECT_NE(rephoto::testing::ErrorOf([&] { AddDataset(store, bad); }).find("--headline 'dssim'"),
            std::string::npos);
  bad = options_;
  bad.scheme = "kfold:3";
  EXPECT_NE(rephoto::testing::ErrorOf([&] { AddDataset(store, bad); }).find("one fold"),
            std::string::npos);
  bad = options_;
  bad.name = "../evil";
  EXPECT_NE(rephoto::testing::ErrorOf([&] { AddDataset(store, bad); }).find("dataset name"),
            std::string::npos);
  bad = options_;
  fs::create_directories(base_ / "some_masks");
  io::WritePng(base_ / "some_masks" / "00.png", Mask(64, 48, 1, 1));
  bad.photo_masks = base_ / "some_masks";
  EXPECT_NE(rephoto::testing::ErrorOf([&] { AddDataset(store, bad); }).find("1 of 2 test photos"),
            std::string::npos);
  EXPECT_TRUE(store.Datasets().empty());
  // Only the database and the (empty) public/ and secret/: no staging folders, no half dataset.
  for (const auto& entry : fs::recursive_directory_iterator(base_ / "root")) {
    const std::string name = fs::relative(entry.path(), base_ / "root").string();
    EXPECT_TRUE(name.rfind("benchmark.sqlite", 0) == 0 || name == "public" || name == "secret")
        << name;
  }
  AddDataset(store, options_);  // the same name works after the failures
  EXPECT_EQ(store.Datasets().size(), 1u);
  EXPECT_NE(rephoto::testing::ErrorOf([&] { AddDataset(store, options_); }).find("exists already"),
            std::string::npos);
}

}  // namespace
}  // namespace rephoto::service
