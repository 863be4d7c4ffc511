#include "rephoto/io/image_encode.h"

#include <libdeflate.h>
#include <turbojpeg.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "rephoto/core/error.h"

namespace rephoto::io {
namespace {

void CheckPixels(std::span<const uint8_t> pixels, int width, int height, int channels,
                 const std::string& name) {
  REPHOTO_CHECK(width > 0 && height > 0, "{}: cannot encode an empty image ({}x{})", name, width,
                height);
  REPHOTO_CHECK(pixels.size() == static_cast<size_t>(width) * height * channels,
                "{}: {} bytes given for a {}x{}x{} image", name, pixels.size(), width, height,
                channels);
}

struct CompressorDeleter {
  void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};

struct TjDeleter {
  void operator()(void* handle) const { tjDestroy(handle); }
};

}  // namespace

std::vector<uint8_t> EncodePngToMemory(std::span<const uint8_t> pixels, int width, int height,
                                       int channels, const std::string& name) {
  return EncodePng(pixels.data(), pixels.size(), width, height, channels, 8, 6, name);
}

std::vector<uint8_t> EncodePng(const void* pixels, size_t bytes, int width, int height,
                               int channels, int depth, int level, const std::string& name) {
  REPHOTO_CHECK(channels >= 1 && channels <= 4, "{}: cannot write {} channels as PNG", name,
                channels);
  REPHOTO_CHECK(width > 0 && height > 0, "{}: cannot encode an empty image ({}x{})", name, width,
                height);
  REPHOTO_CHECK(depth == 8 || depth == 16, "{}: PNG bit depth {} (8 or 16)", name, depth);
  REPHOTO_CHECK(level >= 0 && level <= 12, "{}: PNG compression level {} (0-12)", name, level);
  const size_t sample_bytes = static_cast<size_t>(depth / 8);
  const size_t stride = static_cast<size_t>(width) * channels * sample_bytes;
  REPHOTO_CHECK(bytes == stride * height, "{}: {} bytes given for a {}x{}x{} {}-bit image", name,
                bytes, width, height, channels, depth);

  // Filtered rows: a filter-type byte, then the row's bytes (16-bit samples big-endian) minus
  // the row above's ("up"), or as they are (none: stored data stays readable by a plain copy).
  const uint8_t filter = level == 0 ? 0 : 2;
  thread_local std::vector<uint8_t> filtered, rows[2];  // rows: big-endian copies of 16-bit rows
  filtered.resize((stride + 1) * height);
  const auto* in = static_cast<const uint8_t*>(pixels);
  const uint8_t* above = nullptr;  // the previous row's bytes (none above the first)
  for (int y = 0; y < height; ++y) {
    const uint8_t* source = in + stride * y;
    if (depth == 16) {
      std::vector<uint8_t>& row = rows[y % 2];
      row.resize(stride);
      for (size_t i = 0; i < stride; i += 2) {
        uint16_t v;
        std::memcpy(&v, source + i, 2);
        row[i] = static_cast<uint8_t>(v >> 8);
        row[i + 1] = static_cast<uint8_t>(v & 0xff);
      }
      source = row.data();
    }
    uint8_t* out = filtered.data() + (stride + 1) * y;
    out[0] = filter;
    if (filter == 0 || above == nullptr) {
      std::memcpy(out + 1, source, stride);  // "up" from a row of zeros is the row itself
    } else {
      for (size_t i = 0; i < stride; ++i) out[1 + i] = static_cast<uint8_t>(source[i] - above[i]);
    }
    above = source;
  }

  // One compressor per thread and level (allocating one costs more than a small image).
  thread_local std::unique_ptr<libdeflate_compressor, CompressorDeleter> compressors[13];
  auto& compressor = compressors[level];
  if (!compressor) compressor.reset(libdeflate_alloc_compressor(level));
  REPHOTO_CHECK(compressor, "{}: out of memory", name);
  thread_local std::vector<uint8_t> deflated;
  deflated.resize(libdeflate_zlib_compress_bound(compressor.get(), filtered.size()));
  const size_t deflated_size = libdeflate_zlib_compress(
      compressor.get(), filtered.data(), filtered.size(), deflated.data(), deflated.size());
  REPHOTO_CHECK(deflated_size > 0, "{}: PNG compression failed", name);

  static constexpr uint8_t kColorType[5] = {0, 0, 4, 2, 6};  // grey, grey+alpha, RGB, RGBA
  std::vector<uint8_t> png;
  png.reserve(deflated_size + 128);
  auto append = [&png](const void* data, size_t size) {
    const size_t at = png.size();
    png.resize(at + size);
    if (size > 0) std::memcpy(png.data() + at, data, size);
  };
  auto put32 = [&append](uint32_t v) {
    const uint8_t b[4] = {static_cast<uint8_t>(v >> 24), static_cast<uint8_t>(v >> 16),
                          static_cast<uint8_t>(v >> 8), static_cast<uint8_t>(v)};
    append(b, 4);
  };
  auto chunk = [&](const char* type, const uint8_t* data, size_t size) {
    put32(static_cast<uint32_t>(size));
    const size_t start = png.size();
    append(type, 4);
    append(data, size);
    put32(libdeflate_crc32(0, png.data() + start, size + 4));
  };
  const uint8_t signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  append(signature, 8);
  uint8_t ihdr[13];
  const uint32_t w = static_cast<uint32_t>(width), h = static_cast<uint32_t>(height);
  for (int i = 0; i < 4; ++i) {
    ihdr[i] = static_cast<uint8_t>(w >> (24 - 8 * i));
    ihdr[4 + i] = static_cast<uint8_t>(h >> (24 - 8 * i));
  }
  ihdr[8] = static_cast<uint8_t>(depth);
  ihdr[9] = kColorType[channels];
  ihdr[10] = ihdr[11] = ihdr[12] = 0;  // deflate, adaptive filtering, no interlace
  chunk("IHDR", ihdr, sizeof(ihdr));
  constexpr size_t kMaxChunk = size_t{1} << 30;
  for (size_t offset = 0; offset < deflated_size; offset += kMaxChunk) {
    chunk("IDAT", deflated.data() + offset, std::min(kMaxChunk, deflated_size - offset));
  }
  chunk("IEND", nullptr, 0);
  return png;
}

std::vector<uint8_t> EncodeJpegToMemory(std::span<const uint8_t> pixels, int width, int height,
                                        int channels, int quality, const std::string& name,
                                        bool full_chroma) {
  REPHOTO_CHECK(channels == 1 || channels == 3, "{}: cannot encode {} channels as JPEG", name,
                channels);
  REPHOTO_CHECK(quality >= 1 && quality <= 100, "{}: JPEG quality {} is not in 1-100", name,
                quality);
  CheckPixels(pixels, width, height, channels, name);
  std::unique_ptr<void, TjDeleter> tj(tjInitCompress());
  REPHOTO_CHECK(tj, "{}: cannot initialise the JPEG encoder", name);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  const int r = tjCompress2(tj.get(), pixels.data(), width, 0, height,
                            channels == 1 ? TJPF_GRAY : TJPF_RGB, &buffer, &size,
                            channels == 1 ? TJSAMP_GRAY : (full_chroma ? TJSAMP_444 : TJSAMP_420),
                            quality, TJFLAG_ACCURATEDCT);
  if (r != 0) {
    const std::string message = tjGetErrorStr2(tj.get());
    if (buffer) tjFree(buffer);
    ThrowError("{}: JPEG encoding failed: {}", name, message);
  }
  std::vector<uint8_t> jpeg(buffer, buffer + size);
  tjFree(buffer);
  return jpeg;
}

}  // namespace rephoto::io
