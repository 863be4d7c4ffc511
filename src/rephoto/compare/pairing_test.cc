#include "rephoto/compare/pairing.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::compare {
namespace {

namespace fs = std::filesystem;

void Touch(const fs::path& path) { WriteTextFileAtomically(path, "x"); }

TEST(Pairing, ListsImagesByStemIgnoringOtherFiles) {
  const fs::path dir = testing::MakeTempDir();
  Touch(dir / "b.JPG");
  Touch(dir / "a.png");
  Touch(dir / "A.png");  // stems are case-sensitive: a different image
  Touch(dir / "notes.txt");
  Touch(dir / ".hidden.png");
  fs::create_directories(dir / "sub.png");  // a folder, not a file
  Touch(dir / "a.depth.exr");               // `rephoto render`'s depth map of a.png
  const auto images = ListImages(dir, "photos");
  ASSERT_EQ(images.size(), 3u);
  EXPECT_EQ(images[0].stem, "A");
  EXPECT_EQ(images[1].stem, "a");
  EXPECT_EQ(images[2].stem, "b");
  EXPECT_EQ(images[2].path, dir / "b.JPG");
}

TEST(Pairing, DuplicateStemNamesBothFiles) {
  const fs::path dir = testing::MakeTempDir();
  Touch(dir / "view.png");
  Touch(dir / "view.jpg");
  try {
    ListImages(dir, "renderings");
    FAIL();
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("view.png"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("view.jpg"));
    EXPECT_THAT(e.what(), ::testing::StartsWith(dir.string()));
  }
}

TEST(Pairing, MissingFolderIsAnError) {
  const fs::path dir = testing::MakeTempDir() / "nope";
  EXPECT_THROW(ListImages(dir, "photos"), Error);
  const fs::path file = testing::MakeTempDir() / "file.png";
  Touch(file);
  EXPECT_THROW(ListImages(file, "photos"), Error);
}

TEST(Pairing, EveryImageIsPairedOrMissing) {
  const std::vector<ImageFile> photos = {{"a", "p/a.jpg"}, {"b", "p/b.jpg"}, {"d", "p/d.jpg"}};
  const std::vector<ImageFile> renders = {{"c", "r/c.png"}, {"b", "r/b.png"}, {"a", "r/a.png"}};
  const Pairing pairing = PairByStem(photos, renders);
  ASSERT_EQ(pairing.pairs.size(), 2u);
  EXPECT_EQ(pairing.pairs[0].name, "a");
  EXPECT_EQ(pairing.pairs[0].photo, "p/a.jpg");
  EXPECT_EQ(pairing.pairs[0].render, "r/a.png");
  EXPECT_EQ(pairing.pairs[1].name, "b");
  ASSERT_EQ(pairing.missing.size(), 2u);
  EXPECT_EQ(pairing.missing[0].name, "c");
  EXPECT_EQ(pairing.missing[0].missing, Missing::kPhoto);
  EXPECT_EQ(pairing.missing[0].present, "r/c.png");
  EXPECT_EQ(pairing.missing[1].name, "d");
  EXPECT_EQ(pairing.missing[1].missing, Missing::kRender);
}

}  // namespace
}  // namespace rephoto::compare
