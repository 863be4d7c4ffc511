// The pixel data of the common PNG variants, decoded with libdeflate instead of zlib.
//
// libspng (image_io.cc's PNG decoder) inflates with zlib; libdeflate's whole-buffer inflate is
// 1.4x (noisy photos) to 3.4x (renderings) faster on the same streams (docs/speed.md), and PNG
// decoding is a tenth of `rephoto evaluate`'s CPU. This is used only after libspng has read and
// checked the header and every chunk before the image data (spng_get_ihdr, spng_get_trns), and
// only for: bit depth 8 or 16; grey, grey+alpha, RGB or RGBA; not interlaced; no tRNS chunk.
// Everything else (palette, 1/2/4-bit grey, Adam7, transparency keys) stays libspng's.
//
// It decodes the same samples libspng returns (SPNG_FMT_G8/RGB8/RGBA8 or the PNG's own format,
// 16-bit samples in host byte order). Anything unexpected (a chunk that runs past the file, a
// CRC mismatch, a zlib stream that is invalid, fails its Adler-32 or does not give exactly the
// image's bytes, an unknown filter type) returns false: the caller then decodes the file with
// libspng, whose error messages and leniency stay what they were. io/png_inflate_test checks
// the samples against libspng's on files with every filter type, and fuzz/fuzz_image compares
// the two decoders on every input both accept.
//
// Thread-safe: scratch buffers and the decompressor are per thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace rephoto::io::internal {

// The big-endian 32-bit value at p (PNG's chunk lengths, CRCs and IHDR fields).
inline uint32_t BigEndian32(const uint8_t* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3];
}

struct PngLayout {
  uint32_t width = 0, height = 0;
  int channels = 0;   // 1-4
  int bit_depth = 0;  // 8 or 16
};

// True when InflatePng handles a PNG of this IHDR (colour type 0, 2, 4 or 6 with bit depth 8
// or 16, interlace method 0) without a tRNS chunk.
bool InflatePngHandles(int color_type, int bit_depth, int interlace_method, bool has_trns);

// The image's samples, unfiltered, into `out` (width * channels * bit_depth / 8 bytes per row,
// rows top first; `out_size` must be exactly that times height); false (and `out` undefined)
// for anything unexpected, see above.
bool InflatePng(std::span<const uint8_t> file, const PngLayout& layout, uint8_t* out,
                size_t out_size);

}  // namespace rephoto::io::internal
