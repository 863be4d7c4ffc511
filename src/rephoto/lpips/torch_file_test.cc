// torch_file.h against files written by PyTorch itself (testdata/make_tiny.py, Debian
// python3-torch 1.13): both container formats, strided and offset views, a non-float tensor;
// then every truncation and many single-byte corruptions of them must end in an Error (or a
// valid parse), never a crash or an out-of-bounds read (run under ASan in the sanitizer build).
#include "rephoto/lpips/torch_file.h"

#include <gtest/gtest.h>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::lpips {
namespace {

std::string Tiny(const std::string& name) {
  return ReadFileToString(testing::SourceDir() / "src/rephoto/lpips/testdata" / name);
}

void ExpectTinyValues(const StateDict& dict) {
  ASSERT_EQ(dict.size(), 3u);
  const FloatTensor& w = dict.at("w");
  EXPECT_EQ(w.shape, (std::vector<int64_t>{2, 3}));
  EXPECT_EQ(w.values, (std::vector<float>{0, 2, 4, 1, 3, 5}));
  EXPECT_EQ(w.dtype, "FloatStorage");
  const FloatTensor& b = dict.at("b");
  EXPECT_EQ(b.shape, (std::vector<int64_t>{3}));
  EXPECT_EQ(b.values, (std::vector<float>{0.5f, -1.5f, 2.25f}));
  const FloatTensor& n = dict.at("n");
  EXPECT_TRUE(n.shape.empty());
  EXPECT_TRUE(n.values.empty());
  EXPECT_EQ(n.dtype, "LongStorage");
}

TEST(TorchFile, ZipFormat) { ExpectTinyValues(ParseTorchFile(Tiny("tiny_zip.pth"), "tiny")); }

TEST(TorchFile, LegacyFormat) {
  ExpectTinyValues(ParseTorchFile(Tiny("tiny_legacy.pth"), "tiny"));
}

TEST(TorchFile, ReadsFromDisk) {
  ExpectTinyValues(ReadTorchFile(testing::SourceDir() / "src/rephoto/lpips/testdata/tiny_zip.pth"));
  EXPECT_NE(testing::ErrorOf([] { ReadTorchFile("/nonexistent/alex.pth"); }).find("alex.pth"),
            std::string::npos);
}

TEST(TorchFile, ErrorsNameTheFile) {
  EXPECT_NE(testing::ErrorOf([] { ParseTorchFile("not a torch file", "x.pth"); })
                .find("x.pth: not a torch.save file"),
            std::string::npos);
  // A tensor that reaches past its storage: size 3 -> 4 in the zip's pickle ("K\x03\x85" is
  // the tuple (3,) of 'b').
  std::string zip = Tiny("tiny_zip.pth");
  const size_t at = zip.find(std::string("K\x03\x85", 3));
  ASSERT_NE(at, std::string::npos);
  zip[at + 1] = 4;
  EXPECT_NE(testing::ErrorOf([&] { ParseTorchFile(zip, "x.pth"); }).find("reaches element"),
            std::string::npos)
      << testing::ErrorOf([&] { ParseTorchFile(zip, "x.pth"); });
}

TEST(TorchFile, AnyCallableOtherThanTensorsIsRefused) {
  std::string legacy = Tiny("tiny_legacy.pth");
  const std::string from = "ccollections\nOrderedDict\n";
  const size_t at = legacy.find(from, 0x80);
  ASSERT_NE(at, std::string::npos);
  legacy.replace(at, from.size(), "cos\nsystem\n");
  EXPECT_NE(testing::ErrorOf([&] { ParseTorchFile(legacy, "x.pth"); }).find("'os.system'"),
            std::string::npos);
}

void Mutate(const std::string& original) {
  for (size_t n = 0; n < original.size(); ++n) {  // every truncation
    try {
      ParseTorchFile(std::string_view(original).substr(0, n), "cut.pth");
    } catch (const Error&) {
    }
  }
  std::mt19937_64 rng = testing::MakeRng();
  for (int k = 0; k < 4000; ++k) {  // single and double byte changes
    std::string bytes = original;
    for (int j = 0; j < 1 + k % 2; ++j) {
      bytes[rng() % bytes.size()] = static_cast<char>(rng());
    }
    try {
      ParseTorchFile(bytes, "changed.pth");
    } catch (const Error&) {
    }
  }
}

TEST(TorchFile, HostileChangesAreErrors) {
  Mutate(Tiny("tiny_zip.pth"));
  Mutate(Tiny("tiny_legacy.pth"));
}

TEST(TorchFile, DeepNestingIsRefused) {
  // PROTO 2, EMPTY_TUPLE, then TUPLE1 repeated: a tuple nested 100000 deep.
  std::string pickle = "\x80\x02)";
  pickle += std::string(100000, '\x85');
  pickle += ".";
  const std::string legacy = Tiny("tiny_legacy.pth").substr(0, 0x89) + pickle;
  EXPECT_NE(testing::ErrorOf([&] { ParseTorchFile(legacy, "deep.pth"); }).find("nested deeper"),
            std::string::npos);
}

}  // namespace
}  // namespace rephoto::lpips
