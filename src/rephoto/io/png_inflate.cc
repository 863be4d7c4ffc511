#include "rephoto/io/png_inflate.h"

#include <libdeflate.h>

#include <algorithm>
#include <bit>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <vector>

#include "rephoto/core/image.h"

namespace rephoto::io::internal {
namespace {

struct DecompressorDeleter {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

libdeflate_decompressor* Decompressor() {
  thread_local std::unique_ptr<libdeflate_decompressor, DecompressorDeleter> decompressor(
      libdeflate_alloc_decompressor());
  return decompressor.get();
}

// Scratch buffers above this size are given back after each image, so that one huge image does
// not keep its memory for the rest of a thread's life.
constexpr size_t kKeptScratchBytes = size_t{64} << 20;

void Trim(UninitVector<uint8_t>& v) {
  if (v.capacity() > kKeptScratchBytes) UninitVector<uint8_t>().swap(v);
}

// PNG's Paeth predictor (PNG specification, section 9.4).
inline uint8_t Paeth(int a, int b, int c) {
  const int p = a + b - c;
  const int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return static_cast<uint8_t>(pa <= pb && pa <= pc ? a : (pb <= pc ? b : c));
}

// Undoes one row's filter: `src` the filtered bytes, `prior` the previous unfiltered row (zeros
// for the first), `dst` this row. BPP: bytes per complete pixel (PNG's "bpp", at least 1).
template <int BPP>
bool UnfilterRow(int filter, const uint8_t* src, const uint8_t* prior, uint8_t* dst, size_t n) {
  switch (filter) {
    case 0:
      std::memcpy(dst, src, n);
      return true;
    case 1:  // Sub
      for (size_t i = 0; i < BPP; ++i) dst[i] = src[i];
      for (size_t i = BPP; i < n; ++i) dst[i] = static_cast<uint8_t>(src[i] + dst[i - BPP]);
      return true;
    case 2:  // Up
      for (size_t i = 0; i < n; ++i) dst[i] = static_cast<uint8_t>(src[i] + prior[i]);
      return true;
    case 3:  // Average
      for (size_t i = 0; i < BPP; ++i) dst[i] = static_cast<uint8_t>(src[i] + (prior[i] >> 1));
      for (size_t i = BPP; i < n; ++i) {
        dst[i] = static_cast<uint8_t>(src[i] + ((dst[i - BPP] + prior[i]) >> 1));
      }
      return true;
    case 4:  // Paeth
      for (size_t i = 0; i < BPP; ++i) dst[i] = static_cast<uint8_t>(src[i] + prior[i]);
      for (size_t i = BPP; i < n; ++i) {
        dst[i] = static_cast<uint8_t>(src[i] + Paeth(dst[i - BPP], prior[i], prior[i - BPP]));
      }
      return true;
    default:
      return false;
  }
}

template <int BPP>
bool Unfilter(const uint8_t* filtered, size_t row_bytes, uint32_t height, uint8_t* out) {
  thread_local std::vector<uint8_t> zeros;
  if (zeros.size() < row_bytes) zeros.assign(row_bytes, 0);
  const uint8_t* prior = zeros.data();
  for (uint32_t y = 0; y < height; ++y) {
    const uint8_t* row = filtered + static_cast<size_t>(y) * (row_bytes + 1);
    uint8_t* dst = out + static_cast<size_t>(y) * row_bytes;
    if (!UnfilterRow<BPP>(row[0], row + 1, prior, dst, row_bytes)) return false;
    prior = dst;
  }
  return true;
}

bool UnfilterAny(int bpp, const uint8_t* filtered, size_t row_bytes, uint32_t height,
                 uint8_t* out) {
  switch (bpp) {
    case 1:
      return Unfilter<1>(filtered, row_bytes, height, out);
    case 2:
      return Unfilter<2>(filtered, row_bytes, height, out);
    case 3:
      return Unfilter<3>(filtered, row_bytes, height, out);
    case 4:
      return Unfilter<4>(filtered, row_bytes, height, out);
    case 6:
      return Unfilter<6>(filtered, row_bytes, height, out);
    case 8:
      return Unfilter<8>(filtered, row_bytes, height, out);
    default:
      return false;
  }
}

// The concatenated data of the file's consecutive IDAT chunks (CRCs checked): a view into
// `file` when there is one chunk, else copied into `joined`. Empty when the chunks are not
// well-formed or there is no IDAT.
std::span<const uint8_t> ImageData(std::span<const uint8_t> file, UninitVector<uint8_t>& joined) {
  constexpr size_t kSignature = 8;
  size_t pos = kSignature;
  std::span<const uint8_t> first;
  size_t chunks = 0, total = 0, start = 0;
  // First pass: find the IDAT run, check it and count its bytes.
  while (pos <= file.size() && file.size() - pos >= 12) {
    const uint32_t length = BigEndian32(file.data() + pos);
    if (length > 0x7fffffffu || length > file.size() - pos - 12) return {};
    const uint8_t* type = file.data() + pos + 4;
    const bool idat = std::memcmp(type, "IDAT", 4) == 0;
    if (!idat && chunks > 0) break;  // the end of the image data
    if (idat) {
      const uint32_t crc = BigEndian32(file.data() + pos + 8 + length);
      if (libdeflate_crc32(0, type, size_t{length} + 4) != crc) return {};
      if (chunks == 0) {
        start = pos;
        first = file.subspan(pos + 8, length);
      }
      ++chunks;
      total += length;
    } else if (std::memcmp(type, "IEND", 4) == 0) {
      return {};
    }
    pos += size_t{length} + 12;
  }
  if (chunks == 0) return {};
  if (chunks == 1) return first;
  joined.resize(total);
  size_t filled = 0;
  for (pos = start; filled < total;) {
    const uint32_t length = BigEndian32(file.data() + pos);
    std::memcpy(joined.data() + filled, file.data() + pos + 8, length);
    filled += length;
    pos += size_t{length} + 12;
  }
  return {joined.data(), joined.size()};
}

}  // namespace

bool InflatePngHandles(int color_type, int bit_depth, int interlace_method, bool has_trns) {
  const bool type_ok = color_type == 0 || color_type == 2 || color_type == 4 || color_type == 6;
  return type_ok && (bit_depth == 8 || bit_depth == 16) && interlace_method == 0 && !has_trns;
}

bool InflatePng(std::span<const uint8_t> file, const PngLayout& layout, uint8_t* out,
                size_t out_size) {
  if (layout.channels < 1 || layout.channels > 4) return false;
  if (layout.bit_depth != 8 && layout.bit_depth != 16) return false;
  const int bpp = layout.channels * layout.bit_depth / 8;
  const size_t row_bytes = static_cast<size_t>(layout.width) * bpp;
  if (layout.width == 0 || layout.height == 0 || row_bytes * layout.height != out_size) {
    return false;
  }
  thread_local UninitVector<uint8_t> joined, filtered;
  const std::span<const uint8_t> data = ImageData(file, joined);
  bool ok = !data.empty();
  if (ok) {
    filtered.resize((row_bytes + 1) * layout.height);
    libdeflate_decompressor* d = Decompressor();
    // Without an actual-size argument libdeflate succeeds only when the stream gives exactly
    // this many bytes; it checks the zlib header and the Adler-32.
    ok = d != nullptr && libdeflate_zlib_decompress(d, data.data(), data.size(), filtered.data(),
                                                    filtered.size(),
                                                    nullptr) == LIBDEFLATE_SUCCESS &&
         UnfilterAny(bpp, filtered.data(), row_bytes, layout.height, out);
  }
  if (ok && layout.bit_depth == 16 && std::endian::native == std::endian::little) {
    for (size_t i = 0; i + 1 < out_size; i += 2) std::swap(out[i], out[i + 1]);
  }
  Trim(joined);
  Trim(filtered);
  return ok;
}

}  // namespace rephoto::io::internal
