// ExtractRenders against hostile archives: every refusal has its status and a one-line reason,
// and nothing is ever written outside the output folder.
#include "rephoto/service/archive.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include "rephoto/service/test_fixture.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::service {
namespace {
namespace fs = std::filesystem;
using testing::ArchiveFormat;
using testing::MakeArchive;
using testing::TestEntry;
using Type = TestEntry::Type;

const std::set<std::string> kStems = {"00", "03", "IMG_0001"};

struct Extraction {
  int status = 0;  // 0 = accepted
  std::string message;
  std::vector<ExtractedFile> files;
};

class ArchiveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    base_ = rephoto::testing::MakeTempDir();
    out_ = base_ / "sub" / "renders";
    fs::create_directories(out_);
  }
  Extraction Extract(const std::string& archive, ArchiveLimits limits = {}) {
    Extraction result;
    try {
      result.files = ExtractRenders(archive, kStems, limits, out_);
    } catch (const Refused& refused) {
      result.status = refused.status;
      result.message = refused.what();
    }
    return result;
  }
  // Every path below base_ that is not below out_: must stay {sub} (and what the test made).
  std::vector<std::string> OutsideOut() const {
    std::vector<std::string> outside;
    for (const auto& entry : fs::recursive_directory_iterator(base_)) {
      const std::string path = fs::relative(entry.path(), base_).generic_string();
      if (path != "sub" && path.rfind("sub/renders", 0) != 0) outside.push_back(path);
    }
    return outside;
  }
  fs::path base_, out_;
};

TEST_F(ArchiveTest, ExtractsRendersByStemFromTarZipAndTarGz) {
  for (ArchiveFormat format : {ArchiveFormat::kTar, ArchiveFormat::kZip, ArchiveFormat::kTarGz}) {
    fs::remove_all(out_);
    fs::create_directories(out_);
    const std::string archive = MakeArchive({{"renders", "", Type::kDirectory},
                                             {"renders/00.png", "png bytes"},
                                             {"./03.JPG", std::string(100000, 'x')},
                                             {"IMG_0001.exr", ""}},
                                            format);
    const Extraction result = Extract(archive);
    ASSERT_EQ(result.status, 0) << result.message;
    ASSERT_EQ(result.files.size(), 3u);
    EXPECT_EQ(result.files[0].stem, "00");
    EXPECT_EQ(result.files[0].path, out_ / "00.png");
    EXPECT_EQ(testing::ReadFile(out_ / "00.png"), "png bytes");
    EXPECT_EQ(result.files[1].path, out_ / "03.jpg");  // extension lower-cased
    EXPECT_EQ(result.files[1].size, 100000);
    EXPECT_EQ(result.files[2].path, out_ / "IMG_0001.exr");
    EXPECT_TRUE(OutsideOut().empty());
  }
}

TEST_F(ArchiveTest, RefusesTraversalAbsoluteAndBackslashNames) {
  for (const std::string name :
       {"../00.png", "renders/../../00.png", "/tmp/00.png", "..\\00.png", "a/../00.png"}) {
    for (ArchiveFormat format : {ArchiveFormat::kTar, ArchiveFormat::kZip}) {
      const Extraction result = Extract(MakeArchive({{name, "evil"}}, format));
      EXPECT_EQ(result.status, 400) << name;
      EXPECT_NE(result.message.find("image name"), std::string::npos) << result.message;
      EXPECT_EQ(result.message.find('\n'), std::string::npos);
    }
  }
  EXPECT_TRUE(OutsideOut().empty());
  EXPECT_FALSE(fs::exists("/tmp/00.png") && testing::ReadFile("/tmp/00.png") == "evil");
}

TEST_F(ArchiveTest, RefusesLinksDevicesAndFifos) {
  const std::vector<TestEntry> hostile = {
      {"00.png", "", Type::kSymlink, "/etc/passwd"},
      {"00.png", "", Type::kSymlink, "../../outside.png"},
      {"00.png", "", Type::kHardlink, "/etc/passwd"},
      {"00.png", "", Type::kCharDevice},
      {"00.png", "", Type::kFifo},
  };
  for (const TestEntry& entry : hostile) {
    const Extraction result = Extract(MakeArchive({entry}, ArchiveFormat::kTar));
    EXPECT_EQ(result.status, 400) << static_cast<int>(entry.type);
    EXPECT_NE(result.message.find("not a regular file"), std::string::npos) << result.message;
  }
  // A symlink followed by a file of the same name must not write through the link.
  const Extraction result =
      Extract(MakeArchive({{"03.png", "", Type::kSymlink, "../../outside.png"}, {"03.png", "data"}},
                          ArchiveFormat::kTar));
  EXPECT_EQ(result.status, 400);
  EXPECT_TRUE(fs::is_empty(out_));
  EXPECT_TRUE(OutsideOut().empty());
}

TEST_F(ArchiveTest, RefusesUnknownStemsWrongTypesAndDuplicates) {
  Extraction result = Extract(MakeArchive({{"99.png", "x"}}, ArchiveFormat::kTar));
  EXPECT_EQ(result.status, 400);
  EXPECT_NE(result.message.find("'99' is not a test image"), std::string::npos);
  result = Extract(MakeArchive({{"00.txt", "x"}}, ArchiveFormat::kTar));
  EXPECT_EQ(result.status, 400);
  fs::remove_all(out_);
  fs::create_directories(out_);
  result = Extract(MakeArchive({{"00.png", "x"}, {"a/00.jpg", "y"}}, ArchiveFormat::kTar));
  EXPECT_EQ(result.status, 400);
  EXPECT_NE(result.message.find("a second render of '00'"), std::string::npos);
}

TEST_F(ArchiveTest, StopsBombsAtTheByteLimitWhileExtracting) {
  // 64 MiB of zeros compress to about 64 KiB (zip deflate, tar.gz): the limit of 1 MiB must stop
  // the extraction after about 1 MiB written, whatever the archive declares.
  const std::string zeros(64 << 20, '\0');
  for (ArchiveFormat format : {ArchiveFormat::kZip, ArchiveFormat::kTarGz}) {
    fs::remove_all(out_);
    fs::create_directories(out_);
    const std::string bomb = MakeArchive({{"00.png", zeros}}, format);
    ASSERT_LT(bomb.size(), 1u << 20);
    const Extraction result = Extract(bomb, {.max_bytes = 1 << 20, .max_files = 10});
    EXPECT_EQ(result.status, 413);
    EXPECT_NE(result.message.find("exceed 1048576 bytes"), std::string::npos) << result.message;
    // What was written before the stop is at most the limit plus one block.
    EXPECT_LE(fs::file_size(out_ / "00.png"), (1u << 20) + (1u << 20));
  }
  // The total counts across entries.
  fs::remove_all(out_);
  fs::create_directories(out_);
  const Extraction result = Extract(
      MakeArchive({{"00.png", std::string(600000, 'a')}, {"03.png", std::string(600000, 'b')}},
                  ArchiveFormat::kTar),
      {.max_bytes = 1000000, .max_files = 10});
  EXPECT_EQ(result.status, 413);
}

TEST_F(ArchiveTest, RefusesMoreFilesThanTheLimit) {
  const Extraction result =
      Extract(MakeArchive({{"r", "", Type::kDirectory}, {"r/00.png", "a"}, {"r/03.png", "b"}},
                          ArchiveFormat::kZip),
              {.max_bytes = 1 << 20, .max_files = 2});
  EXPECT_EQ(result.status, 413);
  EXPECT_NE(result.message.find("more than 2 entries"), std::string::npos);
}

TEST_F(ArchiveTest, RefusesMalformedArchivesWithOneLine) {
  std::mt19937_64 rng = rephoto::testing::MakeRng();
  std::string noise(4096, '\0');
  for (char& c : noise) c = static_cast<char>(rng());
  const std::string tar = MakeArchive({{"00.png", std::string(5000, 'a')}}, ArchiveFormat::kTar);
  for (const std::string& bad :
       {std::string(), noise, tar.substr(0, 700), std::string("PK\x03\x04garbage", 11)}) {
    const Extraction result = Extract(bad);
    EXPECT_EQ(result.status, 400) << bad.size();
    EXPECT_FALSE(result.message.empty());
    EXPECT_EQ(result.message.find('\n'), std::string::npos) << result.message;
  }
}

TEST(WriteTarTest, WritesMembersThatReadBack) {
  const fs::path dir = rephoto::testing::MakeTempDir();
  WriteTextFileAtomically(dir / "a.txt", "alpha");
  WriteTextFileAtomically(dir / "b.bin", std::string(70000, 'b'));
  WriteTar(dir / "out.tar", {{"x/a.txt", dir / "a.txt"}, {"b.bin", dir / "b.bin"}});
  // Read back with the system's tar (an independent reader).
  ASSERT_EQ(std::system(("cd '" + dir.string() + "' && mkdir t && tar xf out.tar -C t").c_str()),
            0);
  EXPECT_EQ(testing::ReadFile(dir / "t" / "x" / "a.txt"), "alpha");
  EXPECT_EQ(testing::ReadFile(dir / "t" / "b.bin"), std::string(70000, 'b'));
}

// A zip whose entry libarchive refuses without an error string (archive_error_string gives
// null): refused with 400, not an exception from formatting a null pointer (found by
// fuzz_service_upload; kept as its seed fuzz/corpus/service_upload/regression_null_error.zip).
TEST(ArchiveRegressionTest, ALibarchiveErrorWithoutAMessageIsARefusal) {
  const std::string zip(
      "\x50\x4b\x03\x04\x18\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff"
      "\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff"
      "\xff\xff\xff\xff\x00\x00\x00\x08\x00\xeb\x50\x7b\x5d\x67\x2e\x6e\xeb\x0c\xf0\x73\xe7\xe5"
      "\x92\xe2\x62\x60\x60\xe0\xf5\xf4\x70\x09\x02\xd2\x1c\x40\xcc\xc6\xc1\x06\x24\xff\xb1\xde"
      "\xff\x0d\xa4\xc2\x3c\x5d\x1c\x43\x2a\xe6\x88\x9e\x52\x64\x3c\xec\xc0\xc3\x70\x20\xdc\x28"
      "\x46\x50\x7f\x91\x85\x17\xd3\x6a\xa5\x1d\x4a\x9e\x52\x64\x3c\xec\xc0\xc3\x70\x20\xdc\x28"
      "\x46\x40\x7f\x91\x85\x17\xd3\x6a\xa5\x1d\x4a\x4a\x49\x16\x6d\xdb\xaa\x4e\x4e\x4e\x4e\x4e"
      "\x2e\x2e\x5c\x30\x30\x2e\x70\x6e\x67\x50\x4b\x05\x06\x00\x00\x00\x00\x01\x00\x01\x00\x37"
      "\x00\x00\x00\xb1\x00\x00\x00\x00\x00",
      185);
  const fs::path out = rephoto::testing::MakeTempDir();
  try {
    ExtractRenders(zip, {"00", "03"}, {}, out);
    FAIL() << "accepted";
  } catch (const Refused& refused) {
    EXPECT_EQ(refused.status, 400);
    EXPECT_NE(std::string(refused.what()).find("unknown error"), std::string::npos)
        << refused.what();
  }
}

}  // namespace
}  // namespace rephoto::service
