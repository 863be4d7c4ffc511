// Encoding 8-bit images to PNG or JPEG bytes in memory (for images embedded in other files,
// e.g. the base64 thumbnails of report.html). Files on disk are written by image_io.h.
//
// `pixels`: width*height*channels bytes, interleaved, top row first (the layout of
// io::WritePng8). Throws rephoto::Error ("<name>: <what is wrong>") when the size or channel
// count is invalid or the encoder fails; `name` only labels the message.
// Thread-safe (no shared state).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace rephoto::io {

// PNG, 8 bit per channel; channels 1 (grey), 2 (grey+alpha), 3 (RGB) or 4 (RGBA). Deflate
// level 6 (these images are small; size matters more than speed here).
std::vector<uint8_t> EncodePngToMemory(std::span<const uint8_t> pixels, int width, int height,
                                       int channels, const std::string& name = "PNG");

// The PNG encoder behind EncodePngToMemory and io::WritePng*: `pixels` holds width * height *
// channels samples of `depth` bits (8: bytes; 16: uint16_t in host byte order), channels 1-4
// (grey, grey+alpha, RGB, RGBA), non-interlaced. Rows are filtered with PNG's "up" filter (none
// at level 0) and deflated with libdeflate at `level`: 0 stores the data uncompressed (fastest
// to read back), 1 is the fastest compression (about 1.6 times zlib's speed with run-length
// matches at a similar size on renderings and error images), up to 12. One IDAT chunk per GiB.
// libspng, which decodes rephoto's PNGs, compresses only through zlib; the PNG framing
// (signature, IHDR, IDAT, IEND with CRC-32) is all that is written here.
std::vector<uint8_t> EncodePng(const void* pixels, size_t bytes, int width, int height,
                               int channels, int depth, int level, const std::string& name);

// Baseline JPEG, quality 1-100; channels 1 (grey) or 3 (RGB). RGB chroma is subsampled 4:2:0
// unless `full_chroma` (4:4:4: sharper colour edges, e.g. for colour-mapped images).
std::vector<uint8_t> EncodeJpegToMemory(std::span<const uint8_t> pixels, int width, int height,
                                        int channels, int quality = 85,
                                        const std::string& name = "JPEG", bool full_chroma = false);

}  // namespace rephoto::io
