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

// PNG, 8 bit per channel; channels 1 (grey), 2 (grey+alpha), 3 (RGB) or 4 (RGBA). zlib level 6
// (these images are small; size matters more than speed here).
std::vector<uint8_t> EncodePngToMemory(std::span<const uint8_t> pixels, int width, int height,
                                       int channels, const std::string& name = "PNG");

// Baseline JPEG, quality 1-100; channels 1 (grey) or 3 (RGB). RGB chroma is subsampled 4:2:0
// unless `full_chroma` (4:4:4: sharper colour edges, e.g. for colour-mapped images).
std::vector<uint8_t> EncodeJpegToMemory(std::span<const uint8_t> pixels, int width, int height,
                                        int channels, int quality = 85,
                                        const std::string& name = "JPEG", bool full_chroma = false);

}  // namespace rephoto::io
