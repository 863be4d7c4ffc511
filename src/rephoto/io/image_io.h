// Image files: the only place where 8/16-bit and file formats are converted.
//
// Reading returns rephoto::Image (float, interleaved, top row first) with values as stored,
// scaled to [0,1]: 8-bit v/255, 16-bit v/65535 (and 1/2/4-bit PNG greys scaled to 8 bit first);
// EXR and PFM values as they are (PFM rows are flipped to top-first). No colour management:
// gamma (gAMA), ICC profiles and EXR chromaticities are ignored, values stay display-referred.
// Channels: 1 (grey), 2 (grey+alpha), 3 (RGB) or 4 (RGBA), as stored:
//   PNG   grey -> 1, grey+alpha -> 2, RGB -> 3, RGBA -> 4, palette -> 3; a tRNS chunk (palette
//         transparency or a transparent grey/RGB key colour) adds an alpha channel (2 or 4).
//         Decoded by libspng; the image data of 8/16-bit grey, grey+alpha, RGB and RGBA files
//         without tRNS, not interlaced, inflated by libdeflate instead (io/png_inflate.h: the
//         same samples, 1.4-3.4x faster than zlib).
//   JPEG  grey -> 1, YCbCr/RGB -> 3 (CMYK/YCCK are rejected). Decoded by libjpeg-turbo with
//         its defaults (accurate integer IDCT, smooth chroma upsampling), the same pixels as
//         libjpeg/Pillow. The EXIF orientation tag is ignored on purpose: photogrammetry tools
//         (COLMAP, OpenMVG, MVE) calibrate the pixel grid as stored, so rotating would break the
//         link to the camera. Decoder warnings other than truncation are logged, not fatal.
//   EXR   channels R,G,B[,A] -> 3 or 4; Y[,A] -> 1 or 2; a single channel of any name -> 1.
//         HALF, FLOAT and UINT pixels become float. Scanline and single-level tiled files;
//         the data window gives the size; multi-part and deep files are rejected.
//   PFM   "Pf" (grey) -> 1, "PF" (RGB) -> 3, either byte order (sign of the scale).
// Formats are detected by content (magic bytes), not by extension.
//
// Writing: PNG (8 or 16 bit, 1-4 channels, values clamped to [0,1] and rounded, NaN -> 0;
// libdeflate level 1, the "up" filter),
// EXR (32-bit float, uncompressed for speed; channel names Y / YA / RGB / RGBA), PFM (1 or 3
// channels, little-endian). Always atomically (temporary name + rename, core/file.h).
//
// Every failure (missing file, not an image, truncated, corrupt, unsupported variant, write
// error) throws rephoto::Error with a one-line message "<path>: <what is wrong>".
// All functions are thread-safe (no shared state besides per-thread scratch buffers).
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>

#include "rephoto/core/image.h"

namespace rephoto::io {

Image ReadImage(const std::filesystem::path& path);

// Same, decoding into `image` and reusing its allocation when it is large enough (reading many
// large images one after another without paying for new memory each time).
void ReadImage(const std::filesystem::path& path, Image* image);

// For code that samples large 8-bit photos without needing floats (saves the conversion and 4x
// the memory): 8-bit JPEG and PNG files are decoded into `image8` as stored (the value v stands
// for v / 255) and the call returns true; other files (16-bit PNG, EXR, PFM) are decoded into
// `image` exactly as ReadImage does and it returns false. Same errors as ReadImage.
bool ReadImage8(const std::filesystem::path& path, Image8* image8, Image* image);

// For previews (thumbnails), not for metrics: the image at a reduced size of at least
// `min_width` pixels wide (aspect kept) where the format can decode one cheaply, else as
// ReadImage. JPEG: libjpeg-turbo's DCT scaling (the smallest factor 1/8, 1/4, 3/8, 1/2, ... that
// keeps min_width columns; about 8x faster to decode a 12 MP photo for a 480-pixel thumbnail),
// values close to a box-filtered full decode but not equal to it. Other formats: full size.
// min_width <= 0: as ReadImage. Same errors as ReadImage.
Image ReadImagePreview(const std::filesystem::path& path, int min_width);
// Same, decoding into `image` and reusing its allocation when it is large enough.
void ReadImagePreview(const std::filesystem::path& path, int min_width, Image* image);

// Decodes an image file held in memory; `name` is used in error messages (normally the path).
void DecodeImage(std::span<const uint8_t> bytes, const std::string& name, Image* image);

namespace internal {
// DecodeImage with every PNG decoded by libspng alone, none by the libdeflate path of
// io/png_inflate.h: the reference that path is checked against (tests, fuzz/fuzz_image).
void DecodeImageByLibspng(std::span<const uint8_t> bytes, const std::string& name, Image* image);
}  // namespace internal

// Reads only the size (width, height, channels as ReadImage would return them) from the
// header; cheap (reads the first bytes of the file, not the pixels). Does not validate pixels.
struct ImageHeader {
  int width = 0;
  int height = 0;
  int channels = 0;
};
ImageHeader ReadImageHeader(const std::filesystem::path& path);

// Reads a mask image: a pixel is valid (1) where its first channel is > 0, else 0 (any format
// above; an RGBA PNG counts by its first channel, not its alpha).
Mask ReadMask(const std::filesystem::path& path);
void ReadMask(const std::filesystem::path& path, Mask* mask);

enum class PngDepth { k8 = 8, k16 = 16 };
// kFast: deflate level 1 with the "up" filter (renderings, error images). kNone: stored deflate
// blocks without filtering, for caches read back often (files ~15 % larger for noisy photos,
// decoded several times faster). Both through io::EncodePng (image_encode.h).
enum class PngCompression { kFast, kNone };
// Any channel count 1-4 (grey, grey+alpha, RGB, RGBA).
void WritePng(const std::filesystem::path& path, const Image& image, PngDepth depth = PngDepth::k8,
              PngCompression compression = PngCompression::kFast);
void WritePng(const std::filesystem::path& path, const Mask& mask);  // 0 -> 0, else 255
// Replaces the values by those ReadImage returns for the PNG that WritePng(path, image, depth)
// writes (clamped to [0,1], NaN -> 0, rounded to 8 or 16 bits), without the file round trip.
void QuantizeAsPng(Image* image, PngDepth depth = PngDepth::k8);
// WritePng, then QuantizeAsPng, in one pass over the values.
void WritePngAndQuantize(const std::filesystem::path& path, Image* image,
                         PngDepth depth = PngDepth::k8,
                         PngCompression compression = PngCompression::kFast);
// WritePng (8 bit, kFast), and the file's samples into `bytes` (resized to the image's size):
// the values ReadImage8 returns for the PNG, without the file round trip. `image` is unchanged.
void WritePngAndQuantize(const std::filesystem::path& path, const Image& image, Image8* bytes);
// 8-bit pixels already converted by the caller: width*height*channels bytes, interleaved, top
// row first, channels 1-4. Avoids a float copy for large colour-mapped images.
void WritePng8(const std::filesystem::path& path, std::span<const uint8_t> pixels, int width,
               int height, int channels);
void WriteExr(const std::filesystem::path& path, const Image& image);
void WritePfm(const std::filesystem::path& path, const Image& image);
// By extension (any case): .png (8 bit), .exr, .pfm; anything else throws Error.
void WriteImage(const std::filesystem::path& path, const Image& image);

// True if the extension is one ReadImage handles (.png .jpg .jpeg .exr .pfm, any case).
bool IsImageFile(const std::filesystem::path& path);

}  // namespace rephoto::io
