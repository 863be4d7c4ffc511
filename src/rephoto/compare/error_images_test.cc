#include "rephoto/compare/error_images.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "rephoto/compare/compare.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"
#include "rephoto/testing/testing.h"

namespace rephoto::compare {
namespace {

namespace fs = std::filesystem;

// Written band by band, the EXR and the PNG are the very files io::WriteExr and
// ColourErrorImage + io::WritePng8 make of the whole image.
TEST(ErrorImages, SameFilesAsWholeImageWriters) {
  auto rng = testing::MakeRng();
  std::uniform_real_distribution<float> u(-0.1f, 1.2f);
  const fs::path dir = testing::MakeTempDir();
  for (const auto& [w, h] : {std::pair{1, 1}, std::pair{37, 300}, std::pair{300, 5}}) {
    Image error(w, h, 1);
    for (size_t i = 0; i < error.size(); ++i) error.data()[i] = u(rng);
    error.data()[0] = std::numeric_limits<float>::quiet_NaN();
    error.data()[error.size() - 1] = std::numeric_limits<float>::infinity();
    io::WriteExr(dir / "whole.exr", error);
    std::vector<uint8_t> rgba;
    ColourErrorImage(error, 0.f, 0.5f, &rgba);
    io::WritePng8(dir / "whole.png", rgba, w, h, 4);
    fs::remove(dir / "bands.exr");
    {
      ErrorExrWriter exr(dir / "bands.exr", w, h);
      for (int y0 = 0; y0 < h; y0 += 64) {
        const int y1 = std::min(h, y0 + 64);
        exr.WriteRows(y0, y1, error.row(y0));
      }
      EXPECT_FALSE(fs::exists(dir / "bands.exr"));  // only under its temporary name so far
      std::vector<uint8_t> scratch;
      WriteErrorPng(exr, w, h, 0.f, 0.5f, dir / "bands.png", &scratch);
      exr.Commit();
    }
    EXPECT_EQ(ReadFileToString(dir / "bands.exr"), ReadFileToString(dir / "whole.exr"));
    EXPECT_EQ(ReadFileToString(dir / "bands.png"), ReadFileToString(dir / "whole.png"));
  }
  // Not committed: nothing is left behind.
  {
    ErrorExrWriter exr(dir / "abandoned.exr", 4, 4);
    EXPECT_THROW(exr.WriteRows(1, 2, nullptr), Error);  // out of order
  }
  for (const auto& entry : fs::directory_iterator(dir)) {
    EXPECT_EQ(entry.path().string().find("abandoned"), std::string::npos) << entry.path();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rephoto::compare
