// Image files: the only place where 8/16-bit and file formats are converted.
//
// Reading returns rephoto::Image (float, interleaved, top row first) with values as stored,
// scaled to [0,1]: 8-bit v/255, 16-bit v/65535; EXR and PFM values as they are (PFM rows are
// flipped to top-first). Channels: 1 (grey), 2 (grey+alpha), 3 (RGB) or 4 (RGBA), as stored.
// Formats by content (magic bytes), not extension: PNG (8/16-bit, palette/grey/RGB, with or
// without alpha, via libspng), JPEG (libjpeg-turbo; CMYK is rejected), EXR (tinyexr, half and
// float), PFM (Pf grey, PF RGB, either byte order).
// Writing: PNG (8 or 16 bit, values clamped to [0,1] and rounded), EXR (32-bit float), chosen by
// extension, always atomically (temporary name + rename).
// Every failure throws rephoto::Error whose message starts with the file path.
#pragma once

#include <filesystem>

#include "rephoto/core/image.h"

namespace rephoto::io {

Image ReadImage(const std::filesystem::path& path);

// Reads only the size (width, height, channels) from the header; cheap.
struct ImageHeader {
  int width = 0;
  int height = 0;
  int channels = 0;
};
ImageHeader ReadImageHeader(const std::filesystem::path& path);

// Reads a mask image: a pixel is valid where its first channel is > 0 (any format above).
Mask ReadMask(const std::filesystem::path& path);

enum class PngDepth { k8 = 8, k16 = 16 };
void WritePng(const std::filesystem::path& path, const Image& image, PngDepth depth = PngDepth::k8);
void WritePng(const std::filesystem::path& path, const Mask& mask);  // 0 -> 0, else 255
void WriteExr(const std::filesystem::path& path, const Image& image);
// By extension: .png (8 bit), .exr, .pfm.
void WriteImage(const std::filesystem::path& path, const Image& image);
void WritePfm(const std::filesystem::path& path, const Image& image);

// True if the extension is one ReadImage handles (.png .jpg .jpeg .exr .pfm, any case).
bool IsImageFile(const std::filesystem::path& path);

}  // namespace rephoto::io
