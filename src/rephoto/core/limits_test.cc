#include "rephoto/core/limits.h"

#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "rephoto/core/error.h"

namespace rephoto {
namespace {

// Restores the process-wide limits when a test ends.
struct LimitsGuard {
  uint64_t pixels = MaxPixels();
  uint64_t memory = MaxMemoryBytes();
  ~LimitsGuard() {
    SetMaxPixels(pixels);
    SetMaxMemoryBytes(memory);
  }
};

std::string MessageOf(auto&& call) {
  try {
    call();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Limits, Defaults) {
  EXPECT_EQ(kDefaultMaxPixels, 16384u * 16384u);
  EXPECT_EQ(MaxPixels(), kDefaultMaxPixels);
  EXPECT_EQ(MaxMemoryBytes(), DefaultMaxMemoryBytes());
  EXPECT_GE(DefaultMaxMemoryBytes(), uint64_t{2} << 30);
}

TEST(Limits, ParseByteSize) {
  EXPECT_EQ(ParseByteSize("1048576"), 1048576u);
  EXPECT_EQ(ParseByteSize("512M"), uint64_t{512} << 20);
  EXPECT_EQ(ParseByteSize("16G"), uint64_t{16} << 30);
  EXPECT_EQ(ParseByteSize("16g"), uint64_t{16} << 30);
  EXPECT_EQ(ParseByteSize("2GiB"), uint64_t{2} << 30);
  EXPECT_EQ(ParseByteSize("3KB"), 3072u);
  EXPECT_EQ(ParseByteSize("1T"), uint64_t{1} << 40);
  EXPECT_EQ(ParseByteSize("7B"), 7u);
  for (const char* bad : {"", "G", "0", "0G", "-1", "1.5G", "16X", "16GG", " 16G",
                          "99999999999999999999", "8388609T"}) {
    EXPECT_THROW(ParseByteSize(bad), Error) << bad;
  }
  EXPECT_EQ(MessageOf([] { ParseByteSize("16X"); }),
            "--max-memory: unknown unit in '16X' (use a number of bytes or K, M, G, T, e.g. 16G)");
}

TEST(Limits, SaturatingMultiplyAndFormat) {
  EXPECT_EQ(SaturatingMultiply(3, 4), 12u);
  EXPECT_EQ(SaturatingMultiply(uint64_t{1} << 40, uint64_t{1} << 30),
            std::numeric_limits<uint64_t>::max());
  EXPECT_EQ(FormatBytes(512), "512 B");
  EXPECT_EQ(FormatBytes(1536), "1.5 KiB");
  EXPECT_EQ(FormatBytes(uint64_t{48} << 30), "48.0 GiB");
}

TEST(Limits, CheckAllocationNamesFileClaimAndOption) {
  LimitsGuard guard;
  SetMaxMemoryBytes(uint64_t{16} << 30);
  EXPECT_NO_THROW(CheckAllocation("huge.ply", "4 vertices", 48));
  EXPECT_EQ(MessageOf([] { CheckAllocation("huge.ply", "4000000000 vertices", 48000000000); }),
            "huge.ply: 4000000000 vertices need 44.7 GiB, more than --max-memory 16.0 GiB "
            "(raise it with --max-memory)");
  SetMaxMemoryBytes(uint64_t{64} << 30);
  EXPECT_NO_THROW(CheckAllocation("huge.ply", "4000000000 vertices", 48000000000));
  EXPECT_THROW(SetMaxMemoryBytes(0), Error);
}

TEST(Limits, CheckImageSize) {
  LimitsGuard guard;
  EXPECT_EQ(MessageOf([] { CheckImageSize("big.png", "PNG", 32768, 32768, 3, 4); }),
            "big.png: PNG image of 32768x32768 pixels (1.07e+09) exceeds --max-pixels 268435456 "
            "(raise it with --max-pixels)");
  EXPECT_EQ(MessageOf([] { CheckImageSize("a.pfm", "PFM", 0, 5, 1, 4); }),
            "a.pfm: invalid PFM: image size 0x5");
  EXPECT_NO_THROW(CheckImageSize("ok.png", "PNG", 16384, 16384, 0, 4));
  SetMaxPixels(uint64_t{1} << 30);
  SetMaxMemoryBytes(uint64_t{64} << 30);
  EXPECT_NO_THROW(CheckImageSize("big.png", "PNG", 32768, 32768, 3, 4));
  SetMaxMemoryBytes(uint64_t{8} << 30);
  EXPECT_EQ(MessageOf([] { CheckImageSize("big.png", "PNG", 32768, 32768, 3, 4); }),
            "big.png: PNG image of 32768x32768 pixels x 3 channels need 12.0 GiB, more than "
            "--max-memory 8.0 GiB (raise it with --max-memory)");
  // Sides whose product overflows 64 bits are too large, not small.
  EXPECT_THROW(CheckImageSize("x.exr", "EXR", int64_t{1} << 40, int64_t{1} << 40, 1, 4), Error);
  EXPECT_THROW(SetMaxPixels(0), Error);
}

}  // namespace
}  // namespace rephoto
