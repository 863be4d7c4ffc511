#include "rephoto/core/file.h"

#include <gtest/gtest.h>

#include "rephoto/core/error.h"
#include "rephoto/testing/testing.h"

namespace rephoto {
namespace {

TEST(File, AtomicWriteCreatesFoldersAndLeavesNoTemporary) {
  const auto dir = testing::MakeTempDir();
  const auto path = dir / "a" / "b.txt";
  WriteTextFileAtomically(path, "hello");
  EXPECT_EQ(ReadFileToString(path), "hello");
  int files = 0;
  for (auto& entry : std::filesystem::directory_iterator(dir / "a")) {
    (void)entry;
    ++files;
  }
  EXPECT_EQ(files, 1);
}

TEST(File, FailedWriteKeepsTheOldFile) {
  const auto path = testing::MakeTempDir() / "keep.txt";
  WriteTextFileAtomically(path, "old");
  EXPECT_THROW(WriteFileAtomically(path, [](const std::filesystem::path&) { ThrowError("boom"); }),
               Error);
  EXPECT_EQ(ReadFileToString(path), "old");
}

TEST(File, MissingFileNamesThePath) {
  try {
    ReadFileToString("/nonexistent/file.txt");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/file.txt"), std::string::npos);
  }
}

}  // namespace
}  // namespace rephoto
