// libFuzzer target for the image decoders (PNG, JPEG, EXR, PFM; detected by content as
// io::DecodeImage does). The input is the whole file; the first byte's lowest bit also picks
// io::ReadImage8's 8-bit path (written to a memfd, since it reads a path). Limits are lowered
// to 16 Mpx and 512 MiB (core/limits.h) so that the decoders' own checks, not the fuzzer's
// -rss_limit_mb, stop headers that claim huge sizes. tinyexr is compiled into the target
// (tinyexr_implementation.cc) so that libFuzzer sees its coverage and the sanitizers check it;
// libspng and libjpeg-turbo are the system libraries. PNGs are also decoded by libspng alone
// and must give the same values wherever it decodes them (the libdeflate path, io/png_inflate.h).
#include <sys/mman.h>
#include <unistd.h>

#include <cstring>
#include <span>

#include "fuzz_common.h"
#include "rephoto/core/limits.h"
#include "rephoto/io/image_io.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rephoto::SetMaxPixels(uint64_t{16} << 20);
  rephoto::SetMaxMemoryBytes(uint64_t{512} << 20);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  Image image;
  bool decoded = false;
  fuzz::AcceptsInput([&] {
    io::DecodeImage(std::span<const uint8_t>(data, size), "image", &image);
    if (image.size() != static_cast<size_t>(image.width()) * image.height() * image.channels()) {
      __builtin_trap();
    }
    decoded = true;
  });
  // Differential: where libspng alone decodes the PNG too, the libdeflate path
  // (io/png_inflate.h) must have given the same values.
  static constexpr uint8_t kPng[4] = {0x89, 'P', 'N', 'G'};
  if (size >= 4 && std::memcmp(data, kPng, 4) == 0) {
    Image reference;
    bool reference_decoded = false;
    fuzz::AcceptsInput([&] {
      io::internal::DecodeImageByLibspng(std::span<const uint8_t>(data, size), "image",
                                         &reference);
      reference_decoded = true;
    });
    if (reference_decoded &&
        (!decoded || reference.width() != image.width() || reference.height() != image.height() ||
         reference.channels() != image.channels() ||
         std::memcmp(reference.data(), image.data(), image.size() * sizeof(float)) != 0)) {
      __builtin_trap();
    }
  }
  if (size > 0 && (data[0] & 1) != 0) {
    static const int fd = memfd_create("fuzz_image", 0);
    if (fd < 0 || ftruncate(fd, 0) != 0 ||
        pwrite(fd, data, size, 0) != static_cast<ssize_t>(size)) {
      return 0;
    }
    Image8 image8;
    fuzz::AcceptsInput(
        [&] { io::ReadImage8("/proc/self/fd/" + std::to_string(fd), &image8, &image); });
  }
  return 0;
}
