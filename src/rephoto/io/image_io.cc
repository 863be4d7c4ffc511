#include "rephoto/io/image_io.h"

#include <fcntl.h>
#include <spng.h>
#include <sys/stat.h>
#include <tinyexr.h>
#include <turbojpeg.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <string_view>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/limits.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/progress.h"
#include "rephoto/io/image_encode.h"
#include "rephoto/io/png_inflate.h"

namespace rephoto::io {
namespace fs = std::filesystem;

namespace {

enum class Format { kUnknown, kPng, kJpeg, kExr, kPfm };

Format DetectFormat(std::span<const uint8_t> b) {
  static constexpr uint8_t kPng[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  if (b.size() >= 8 && std::memcmp(b.data(), kPng, 8) == 0) return Format::kPng;
  if (b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF) return Format::kJpeg;
  if (b.size() >= 4 && b[0] == 0x76 && b[1] == 0x2F && b[2] == 0x31 && b[3] == 0x01) {
    return Format::kExr;
  }
  if (b.size() >= 3 && b[0] == 'P' && (b[1] == 'F' || b[1] == 'f') && std::isspace(b[2])) {
    return Format::kPfm;
  }
  return Format::kUnknown;
}

[[noreturn]] void ThrowUnknownFormat(const std::string& name, size_t size) {
  if (size == 0) ThrowError("{}: empty file, not an image", name);
  ThrowError("{}: not a supported image file (expected PNG, JPEG, EXR or PFM content)", name);
}

// Decoders check the size a header claims before allocating anything for it: at most
// --max-pixels pixels and, once the channels are known, --max-memory bytes of values
// (core/limits.h), so that a corrupt or hostile header gives an error naming the file instead
// of an allocation failure. `bytes_per_value`: 4 for the float Image, 1 for Image8.
void CheckSize(const std::string& name, const char* format, int64_t width, int64_t height,
               int channels = 0, int bytes_per_value = 4) {
  CheckImageSize(name, format, width, height, channels, bytes_per_value);
}

struct FileCloser {
  int fd;
  ~FileCloser() {
    if (fd >= 0) ::close(fd);
  }
};

// Reads up to `limit` bytes of the file (all of it by default) into `bytes`.
void ReadFileBytes(const fs::path& path, std::vector<uint8_t>* bytes,
                   size_t limit = static_cast<size_t>(-1)) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) ThrowError("{}: cannot open: {}", path.string(), std::strerror(errno));
  FileCloser closer{fd};
  struct stat st {};
  REPHOTO_CHECK(::fstat(fd, &st) == 0, "{}: cannot read: {}", path.string(), std::strerror(errno));
  REPHOTO_CHECK(!S_ISDIR(st.st_mode), "{}: is a folder, not an image file", path.string());
  const size_t size = std::min(static_cast<size_t>(st.st_size), limit);
  bytes->resize(size);
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::read(fd, bytes->data() + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    REPHOTO_CHECK(n >= 0, "{}: read failed: {}", path.string(), std::strerror(errno));
    if (n == 0) break;  // the file shrank while reading
    done += static_cast<size_t>(n);
  }
  bytes->resize(done);
}

// Per-thread scratch buffers: decoding many large images reuses the same memory.
std::vector<uint8_t>& FileScratch() {
  thread_local std::vector<uint8_t> bytes;
  return bytes;
}
UninitVector<uint8_t>& PixelScratch() {
  thread_local UninitVector<uint8_t> pixels;
  return pixels;
}

// Converts interleaved 8-bit or 16-bit samples to [0,1] floats (v/255, v/65535).
template <typename T>
void ConvertToFloat(const T* samples, int width, int height, int channels, Image* image) {
  image->Resize(width, height, channels);
  constexpr float kMax = sizeof(T) == 1 ? 255.f : 65535.f;
  const size_t row_values = static_cast<size_t>(width) * channels;
  const int64_t grain = std::max<int64_t>(1, 65536 / static_cast<int64_t>(row_values));
  ParallelFor(0, height, grain, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      const T* in = samples + static_cast<size_t>(y) * row_values;
      float* out = image->row(static_cast<int>(y));
      for (size_t i = 0; i < row_values; ++i) out[i] = static_cast<float>(in[i]) / kMax;
    }
  });
}

// ----------------------------------------------------------------------------------- PNG

// Set by internal::DecodeImageByLibspng for the calling thread.
thread_local bool libspng_only = false;
bool LibspngOnly() { return libspng_only; }

struct SpngDeleter {
  void operator()(spng_ctx* ctx) const { spng_ctx_free(ctx); }
};
using SpngPtr = std::unique_ptr<spng_ctx, SpngDeleter>;

int PngChannels(int color_type, bool has_trns) {
  switch (color_type) {
    case SPNG_COLOR_TYPE_GRAYSCALE:
      return has_trns ? 2 : 1;
    case SPNG_COLOR_TYPE_TRUECOLOR:
    case SPNG_COLOR_TYPE_INDEXED:
      return has_trns ? 4 : 3;
    case SPNG_COLOR_TYPE_GRAYSCALE_ALPHA:
      return 2;
    case SPNG_COLOR_TYPE_TRUECOLOR_ALPHA:
      return 4;
    default:
      return 0;
  }
}

// With `image8`, 8-bit samples are decoded straight into it (no float conversion) and the
// function returns true; otherwise (or for 16-bit PNGs) `image` gets floats and it returns false.
bool DecodePng(std::span<const uint8_t> bytes, const std::string& name, Image* image,
               Image8* image8 = nullptr) {
  SpngPtr ctx(spng_ctx_new(0));
  REPHOTO_CHECK(ctx, "{}: out of memory", name);
  spng_set_png_buffer(ctx.get(), bytes.data(), bytes.size());
  spng_ihdr ihdr{};
  int r = spng_get_ihdr(ctx.get(), &ihdr);
  REPHOTO_CHECK(r == 0, "{}: invalid PNG: {}", name, spng_strerror(r));
  CheckSize(name, "PNG", ihdr.width, ihdr.height);
  spng_trns trns{};
  r = spng_get_trns(ctx.get(), &trns);
  REPHOTO_CHECK(r == 0 || r == SPNG_ECHUNKAVAIL, "{}: invalid PNG: {}", name, spng_strerror(r));
  const bool has_trns = r == 0;
  const int channels = PngChannels(ihdr.color_type, has_trns);
  REPHOTO_CHECK(channels > 0, "{}: unsupported PNG colour type {}", name, ihdr.color_type);
  const bool wide = ihdr.bit_depth == 16;
  // libdeflate's inflate for the common variants (io/png_inflate.h), libspng's for the others
  // and for any file that path does not take.
  // Floats (4 bytes) plus the decoded samples (1 or 2 bytes), or the 8-bit samples alone.
  const int stored = wide ? 2 : 1;
  const int bytes_per_value = image8 != nullptr && !wide ? 1 : 4 + stored;
  CheckSize(name, "PNG", ihdr.width, ihdr.height, channels, bytes_per_value);
  // The libdeflate path also holds the filtered samples (1 or 2 bytes per value): taken only
  // where that fits in --max-memory too, so that every PNG libspng decodes within the limit
  // still decodes (libspng, row by row).
  const uint64_t values = uint64_t{ihdr.width} * ihdr.height * channels;
  const bool inflate = internal::InflatePngHandles(ihdr.color_type, ihdr.bit_depth,
                                                   ihdr.interlace_method, has_trns) &&
                       !LibspngOnly() &&
                       values * (bytes_per_value + stored) + ihdr.height <= MaxMemoryBytes();

  int format = 0;
  switch (ihdr.color_type) {
    case SPNG_COLOR_TYPE_GRAYSCALE:
      format = wide ? (has_trns ? SPNG_FMT_GA16 : SPNG_FMT_PNG)
                    : (has_trns ? SPNG_FMT_GA8 : SPNG_FMT_G8);
      break;
    case SPNG_COLOR_TYPE_TRUECOLOR:
      format = wide ? (has_trns ? SPNG_FMT_RGBA16 : SPNG_FMT_PNG)
                    : (has_trns ? SPNG_FMT_RGBA8 : SPNG_FMT_RGB8);
      break;
    case SPNG_COLOR_TYPE_INDEXED:
      format = has_trns ? SPNG_FMT_RGBA8 : SPNG_FMT_RGB8;
      break;
    case SPNG_COLOR_TYPE_GRAYSCALE_ALPHA:
      format = SPNG_FMT_PNG;  // 8 or 16 bit grey+alpha as stored (host byte order)
      break;
    case SPNG_COLOR_TYPE_TRUECOLOR_ALPHA:
      format = wide ? SPNG_FMT_RGBA16 : SPNG_FMT_RGBA8;
      break;
  }
  const bool out16 = wide && ihdr.color_type != SPNG_COLOR_TYPE_INDEXED;
  size_t size = 0;
  r = spng_decoded_image_size(ctx.get(), format, &size);
  REPHOTO_CHECK(r == 0, "{}: unsupported PNG variant: {}", name, spng_strerror(r));
  const size_t expected =
      static_cast<size_t>(ihdr.width) * ihdr.height * channels * (out16 ? 2 : 1);
  REPHOTO_CHECK(size == expected, "{}: unexpected PNG decoded size {} (expected {})", name, size,
                expected);
  const bool direct = image8 != nullptr && !out16;
  UninitVector<uint8_t>& pixels = PixelScratch();
  uint8_t* target = nullptr;
  if (direct) {
    image8->Resize(static_cast<int>(ihdr.width), static_cast<int>(ihdr.height), channels);
    target = image8->data();
  } else {
    pixels.resize(size);
    target = pixels.data();
  }
  const internal::PngLayout layout{.width = ihdr.width,
                                   .height = ihdr.height,
                                   .channels = channels,
                                   .bit_depth = ihdr.bit_depth};
  r = inflate && internal::InflatePng(bytes, layout, target, size)
          ? 0
          : spng_decode_image(ctx.get(), target, size, format, has_trns ? SPNG_DECODE_TRNS : 0);
  if (r != 0) {
    if (r == SPNG_EOF) ThrowError("{}: truncated PNG ({})", name, spng_strerror(r));
    ThrowError("{}: corrupt PNG: {}", name, spng_strerror(r));
  }
  if (direct) return true;
  if (out16) {
    ConvertToFloat(reinterpret_cast<const uint16_t*>(pixels.data()), ihdr.width, ihdr.height,
                   channels, image);
  } else {
    ConvertToFloat(pixels.data(), ihdr.width, ihdr.height, channels, image);
  }
  return false;
}

// ---------------------------------------------------------------------------------- JPEG

struct TjDeleter {
  void operator()(void* handle) const { tjDestroy(handle); }
};

std::unique_ptr<void, TjDeleter>& DecompressorHandle() {
  thread_local std::unique_ptr<void, TjDeleter> handle;
  return handle;
}

tjhandle Decompressor() {
  std::unique_ptr<void, TjDeleter>& handle = DecompressorHandle();
  if (!handle) handle.reset(tjInitDecompress());
  return handle.get();
}

bool DecodeJpegWith(tjhandle tj, std::span<const uint8_t> bytes, const std::string& name,
                    Image* image, Image8* image8, int min_width);

// As DecodePng: 8-bit samples into `image8` when given (returns true), else floats.
// min_width > 0: a reduced decode (ReadImagePreview).
bool DecodeJpeg(std::span<const uint8_t> bytes, const std::string& name, Image* image,
                Image8* image8 = nullptr, int min_width = 0) {
  try {
    return DecodeJpegWith(Decompressor(), bytes, name, image, image8, min_width);
  } catch (...) {
    // A decoder that failed half-way keeps state (Huffman tables, markers) that made the next,
    // valid JPEG on this thread fail with "Bogus Huffman table definition": start afresh.
    DecompressorHandle().reset();
    throw;
  }
}

bool DecodeJpegWith(tjhandle tj, std::span<const uint8_t> bytes, const std::string& name,
                    Image* image, Image8* image8, int min_width) {
  REPHOTO_CHECK(tj != nullptr, "{}: cannot initialize the JPEG decoder", name);
  // TurboJPEG 2.x takes non-const buffers but does not write to them.
  auto* data = const_cast<unsigned char*>(bytes.data());
  const auto size = static_cast<unsigned long>(bytes.size());
  int width = 0, height = 0, subsampling = 0, colorspace = 0;
  if (tjDecompressHeader3(tj, data, size, &width, &height, &subsampling, &colorspace) != 0) {
    ThrowError("{}: invalid JPEG: {}", name, tjGetErrorStr2(tj));
  }
  CheckSize(name, "JPEG", width, height);
  REPHOTO_CHECK(colorspace != TJCS_CMYK && colorspace != TJCS_YCCK,
                "{}: CMYK JPEG is not supported (convert it to RGB)", name);
  const bool grey = colorspace == TJCS_GRAY;
  const int channels = grey ? 1 : 3;
  CheckSize(name, "JPEG", width, height, channels, image8 != nullptr ? 1 : 5);
  if (min_width > 0 && min_width < width) {
    // The smallest of libjpeg-turbo's DCT scaling factors (1/8, 1/4, 3/8, 1/2, ...) that keeps
    // at least min_width columns: the decoder then skips most of the inverse DCT work.
    int count = 0;
    const tjscalingfactor* factors = tjGetScalingFactors(&count);
    int best_width = width, best_height = height;
    for (int i = 0; factors != nullptr && i < count; ++i) {
      const int w = TJSCALED(width, factors[i]), h = TJSCALED(height, factors[i]);
      if (w >= min_width && w < best_width && h >= 1) {
        best_width = w;
        best_height = h;
      }
    }
    width = best_width;
    height = best_height;
  }
  UninitVector<uint8_t>& pixels = PixelScratch();
  uint8_t* target = nullptr;
  if (image8 != nullptr) {
    image8->Resize(width, height, channels);
    target = image8->data();
  } else {
    pixels.resize(static_cast<size_t>(width) * height * channels);
    target = pixels.data();
  }
  if (tjDecompress2(tj, data, size, target, width, 0, height, grey ? TJPF_GRAY : TJPF_RGB, 0) !=
      0) {
    const std::string message = tjGetErrorStr2(tj);
    if (tjGetErrorCode(tj) == TJERR_FATAL) ThrowError("{}: corrupt JPEG: {}", name, message);
    // Warnings: libjpeg fills a truncated scan with grey and carries on; a missing part of the
    // photo must not be compared, so truncation is an error. Other warnings (e.g. extraneous
    // bytes before a marker) leave the pixels intact, as in every other decoder.
    if (message.find("Premature end") != std::string::npos) {
      ThrowError("{}: truncated JPEG ({})", name, message);
    }
    LogWarning(fmt::format("{}: {} (decoded anyway)", name, message));
  }
  if (image8 != nullptr) return true;
  ConvertToFloat(pixels.data(), width, height, channels, image);
  return false;
}

// ----------------------------------------------------------------------------------- EXR

struct ExrHeaderGuard {
  EXRHeader header;
  ExrHeaderGuard() { InitEXRHeader(&header); }
  ~ExrHeaderGuard() { FreeEXRHeader(&header); }
};
struct ExrImageGuard {
  EXRImage image;
  ExrImageGuard() { InitEXRImage(&image); }
  ~ExrImageGuard() { FreeEXRImage(&image); }
};

[[noreturn]] void ThrowExr(const std::string& name, const char* what, int code, const char* err) {
  std::string message = err ? std::string(err) : fmt::format("tinyexr error {}", code);
  if (err) FreeEXRErrorMessage(err);
  // tinyexr messages may span lines; rephoto errors are one line.
  for (char& c : message) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  while (!message.empty() && message.back() == ' ') message.pop_back();
  ThrowError("{}: {}: {}", name, what, message);
}

// tinyexr reads the "tiles" (9 bytes) and "compression" (1 byte) attributes without checking
// their size: a header whose "tiles" attribute was shorter made it read past its buffer (found
// by fuzz_image). So the attributes of a single-part header are walked here first: each is
// "<name>\0<type>\0", a little-endian 32-bit size and that many bytes; a 0 byte ends the list.
void CheckExrAttributes(std::span<const uint8_t> bytes, const std::string& name) {
  size_t pos = 8;  // magic number and version field
  auto c_string = [&](const char* what) {
    const void* nul =
        pos < bytes.size() ? std::memchr(bytes.data() + pos, 0, bytes.size() - pos) : nullptr;
    REPHOTO_CHECK(nul != nullptr, "{}: truncated EXR header ({})", name, what);
    const auto length = static_cast<size_t>(static_cast<const uint8_t*>(nul) - bytes.data() - pos);
    const std::string_view text(reinterpret_cast<const char*>(bytes.data()) + pos, length);
    pos += length + 1;
    return text;
  };
  for (;;) {
    REPHOTO_CHECK(pos < bytes.size(), "{}: truncated EXR header", name);
    if (bytes[pos] == 0) return;
    const std::string_view attribute = c_string("attribute name");
    c_string("attribute type");
    REPHOTO_CHECK(bytes.size() - pos >= 4, "{}: truncated EXR header (attribute '{}')", name,
                  attribute);
    const uint32_t size = uint32_t{bytes[pos]} | (uint32_t{bytes[pos + 1]} << 8) |
                          (uint32_t{bytes[pos + 2]} << 16) | (uint32_t{bytes[pos + 3]} << 24);
    pos += 4;
    REPHOTO_CHECK(size <= bytes.size() - pos, "{}: truncated EXR header (attribute '{}')", name,
                  attribute);
    const uint32_t needed = attribute == "tiles" ? 9 : attribute == "compression" ? 1 : 0;
    REPHOTO_CHECK(size >= needed, "{}: invalid EXR header: attribute '{}' has {} bytes, not {}",
                  name, attribute, size, needed);
    pos += size;
  }
}

// Parses the version field and the header of a single-part EXR; throws Error otherwise.
void ParseExrHeader(std::span<const uint8_t> bytes, const std::string& name, EXRHeader* header) {
  EXRVersion version{};
  int r = ParseEXRVersionFromMemory(&version, bytes.data(), bytes.size());
  REPHOTO_CHECK(r == 0, "{}: invalid EXR version field", name);
  REPHOTO_CHECK(!version.multipart, "{}: multi-part EXR is not supported", name);
  REPHOTO_CHECK(!version.non_image, "{}: deep EXR is not supported", name);
  CheckExrAttributes(bytes, name);
  const char* err = nullptr;
  r = ParseEXRHeaderFromMemory(header, &version, bytes.data(), bytes.size(), &err);
  if (r != 0) ThrowExr(name, "invalid EXR header", r, err);
}

// Indices of the channels ReadImage returns, in output order; throws if none fit.
std::vector<int> SelectExrChannels(const EXRHeader& header, const std::string& name) {
  auto find = [&](const char* channel) {
    for (int i = 0; i < header.num_channels; ++i) {
      if (std::strcmp(header.channels[i].name, channel) == 0) return i;
    }
    return -1;
  };
  const int r = find("R"), g = find("G"), b = find("B"), a = find("A"), y = find("Y");
  std::vector<int> selected;
  if (r >= 0 && g >= 0 && b >= 0) {
    selected = {r, g, b};
  } else if (y >= 0) {
    selected = {y};
  } else if (header.num_channels == 1) {
    selected = {0};
  } else {
    std::string names;
    for (int i = 0; i < header.num_channels; ++i) {
      if (i > 0) names += ',';
      names += header.channels[i].name;
    }
    ThrowError("{}: EXR has no R,G,B or Y channels (found {})", name, names);
  }
  if (a >= 0 && std::find(selected.begin(), selected.end(), a) == selected.end()) {
    selected.push_back(a);
  }
  for (int index : selected) {
    REPHOTO_CHECK(header.channels[index].x_sampling <= 1 && header.channels[index].y_sampling <= 1,
                  "{}: EXR channel {} is subsampled, which is not supported", name,
                  header.channels[index].name);
  }
  return selected;
}

float ExrSample(const unsigned char* plane, int pixel_type, size_t index) {
  if (pixel_type == TINYEXR_PIXELTYPE_UINT) {
    return static_cast<float>(reinterpret_cast<const uint32_t*>(plane)[index]);
  }
  return reinterpret_cast<const float*>(plane)[index];
}

void DecodeExr(std::span<const uint8_t> bytes, const std::string& name, Image* image) {
  ExrHeaderGuard header;
  ParseExrHeader(bytes, name, &header.header);
  EXRHeader& h = header.header;
  const std::vector<int> selected = SelectExrChannels(h, name);
  for (int i = 0; i < h.num_channels; ++i) {
    if (h.pixel_types[i] == TINYEXR_PIXELTYPE_HALF) {
      h.requested_pixel_types[i] = TINYEXR_PIXELTYPE_FLOAT;
    }
  }
  const int64_t width = int64_t{h.data_window.max_x} - h.data_window.min_x + 1;
  const int64_t height = int64_t{h.data_window.max_y} - h.data_window.min_y + 1;
  CheckSize(name, "EXR", width, height);
  // tinyexr decodes every channel of the file (4 bytes per value) before the selected ones are
  // copied into the image.
  CheckAllocation(name,
                  fmt::format("EXR image of {}x{} pixels x {} channels (+ {} output channels)",
                              width, height, h.num_channels, selected.size()),
                  SaturatingMultiply(SaturatingMultiply(width, height),
                                     4 * (uint64_t(h.num_channels) + selected.size())));
  ExrImageGuard exr;
  // tinyexr frees a half-decoded image with FreeEXRImage, which frees num_channels planes; for
  // scanline files that fail it had not set num_channels yet and leaked every plane (found by
  // fuzz_image under LeakSanitizer). It sets the same value itself when it succeeds.
  exr.image.num_channels = h.num_channels;
  const char* err = nullptr;
  // tinyexr 1.0.1 checks where each 4-byte value of an uncompressed chunk starts, not where it
  // ends: a file whose last chunk is cut short makes it read up to 3 bytes past the buffer
  // (fuzz_image under AddressSanitizer). It decodes from a copy with zeroed slack after the
  // data; the size it is told stays the file's, so its checks are unchanged.
  constexpr size_t kSlack = 16;
  std::vector<uint8_t> padded(bytes.size() + kSlack, 0);
  std::copy(bytes.begin(), bytes.end(), padded.begin());
  const int r = LoadEXRImageFromMemory(&exr.image, &h, padded.data(), bytes.size(), &err);
  if (r != 0) {
    // tinyexr frees the image itself when decoding fails but leaves the pointers dangling.
    InitEXRImage(&exr.image);
    ThrowExr(name, "corrupt or truncated EXR", r, err);
  }
  const EXRImage& e = exr.image;
  CheckSize(name, "EXR", e.width, e.height);
  const int channels = static_cast<int>(selected.size());
  image->Resize(e.width, e.height, channels);
  if (e.tiles == nullptr) {
    REPHOTO_CHECK(e.images != nullptr, "{}: EXR holds no pixel data", name);
    ParallelFor(0, e.height, 64, [&](int64_t y0, int64_t y1) {
      for (int64_t y = y0; y < y1; ++y) {
        float* out = image->row(static_cast<int>(y));
        for (int c = 0; c < channels; ++c) {
          const int src = selected[c];
          const int type = h.requested_pixel_types[src];
          for (int x = 0; x < e.width; ++x) {
            out[x * channels + c] = ExrSample(e.images[src], type, y * e.width + x);
          }
        }
      }
    });
  } else {
    // Tiles: offset_x/offset_y are tile indices, data rows have tile_size_x samples.
    std::fill(image->data(), image->data() + image->size(), 0.f);
    for (int t = 0; t < e.num_tiles; ++t) {
      const EXRTile& tile = e.tiles[t];
      for (int j = 0; j < tile.height; ++j) {
        const int y = tile.offset_y * h.tile_size_y + j;
        if (y >= e.height) continue;
        for (int i = 0; i < tile.width; ++i) {
          const int x = tile.offset_x * h.tile_size_x + i;
          if (x >= e.width) continue;
          const size_t src_index = static_cast<size_t>(j) * h.tile_size_x + i;
          for (int c = 0; c < channels; ++c) {
            image->at(x, y, c) = ExrSample(tile.images[selected[c]],
                                           h.requested_pixel_types[selected[c]], src_index);
          }
        }
      }
    }
  }
}

// ----------------------------------------------------------------------------------- PFM

struct PfmHeader {
  int width = 0;
  int height = 0;
  int channels = 0;
  bool little_endian = true;
  size_t data_offset = 0;
};

PfmHeader ParsePfmHeader(std::span<const uint8_t> b, const std::string& name) {
  PfmHeader header;
  header.channels = b[1] == 'F' ? 3 : 1;
  size_t pos = 2;
  auto token = [&](const char* what) {
    while (pos < b.size() && std::isspace(b[pos])) ++pos;
    const size_t start = pos;
    while (pos < b.size() && !std::isspace(b[pos])) ++pos;
    REPHOTO_CHECK(pos > start && pos < b.size() && pos - start < 32,
                  "{}: truncated or invalid PFM header (reading {})", name, what);
    return std::string(reinterpret_cast<const char*>(b.data()) + start, pos - start);
  };
  const std::string width = token("width");
  const std::string height = token("height");
  const std::string scale = token("scale");
  char* end = nullptr;
  const long w = std::strtol(width.c_str(), &end, 10);
  REPHOTO_CHECK(*end == 0, "{}: invalid PFM width '{}'", name, width);
  const long h = std::strtol(height.c_str(), &end, 10);
  REPHOTO_CHECK(*end == 0, "{}: invalid PFM height '{}'", name, height);
  const double s = std::strtod(scale.c_str(), &end);
  REPHOTO_CHECK(*end == 0 && s != 0 && std::isfinite(s), "{}: invalid PFM scale '{}'", name, scale);
  CheckSize(name, "PFM", w, h);
  header.width = static_cast<int>(w);
  header.height = static_cast<int>(h);
  header.little_endian = s < 0;
  header.data_offset = pos + 1;  // exactly one whitespace byte ends the header
  return header;
}

void DecodePfm(std::span<const uint8_t> bytes, const std::string& name, Image* image) {
  const PfmHeader header = ParsePfmHeader(bytes, name);
  CheckSize(name, "PFM", header.width, header.height, header.channels);
  const size_t values = static_cast<size_t>(header.width) * header.height * header.channels;
  const size_t available = bytes.size() - std::min(bytes.size(), header.data_offset);
  REPHOTO_CHECK(available >= values * 4,
                "{}: truncated PFM: {}x{}x{} needs {} bytes of pixels, found {}", name,
                header.width, header.height, header.channels, values * 4, available);
  image->Resize(header.width, header.height, header.channels);
  const bool swap = header.little_endian != (std::endian::native == std::endian::little);
  const size_t row_values = static_cast<size_t>(header.width) * header.channels;
  const uint8_t* data = bytes.data() + header.data_offset;
  ParallelFor(0, header.height, 64, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      // PFM stores the bottom row first.
      const uint8_t* in = data + static_cast<size_t>(header.height - 1 - y) * row_values * 4;
      float* out = image->row(static_cast<int>(y));
      for (size_t i = 0; i < row_values; ++i) {
        uint32_t bits;
        std::memcpy(&bits, in + 4 * i, 4);
        if (swap) bits = __builtin_bswap32(bits);
        std::memcpy(out + i, &bits, 4);
      }
    }
  });
}

// ----------------------------------------------------------------------- header-only reads

class FilePrefix {
 public:
  explicit FilePrefix(const fs::path& path) : path_(path), in_(path, std::ios::binary) {
    REPHOTO_CHECK(!fs::is_directory(path), "{}: is a folder, not an image file", path.string());
    REPHOTO_CHECK(in_, "{}: cannot open: {}", path.string(), std::strerror(errno));
  }
  // Reads exactly n bytes or throws "truncated <what>".
  void Read(void* out, size_t n, const char* what) {
    in_.read(static_cast<char*>(out), static_cast<std::streamsize>(n));
    REPHOTO_CHECK(static_cast<size_t>(in_.gcount()) == n, "{}: truncated {}", path_.string(), what);
  }
  void Skip(uint64_t n, const char* what) {
    in_.seekg(static_cast<std::streamoff>(n), std::ios::cur);
    REPHOTO_CHECK(in_, "{}: truncated {}", path_.string(), what);
  }
  std::ifstream& stream() { return in_; }

 private:
  fs::path path_;
  std::ifstream in_;
};

using internal::BigEndian32;
uint16_t BigEndian16(const uint8_t* p) { return static_cast<uint16_t>((p[0] << 8) | p[1]); }

ImageHeader PngHeader(FilePrefix& file, const std::string& name) {
  uint8_t chunk[8 + 8 + 13];
  file.Read(chunk, sizeof chunk, "PNG header");
  REPHOTO_CHECK(BigEndian32(chunk + 8) == 13 && std::memcmp(chunk + 12, "IHDR", 4) == 0,
                "{}: invalid PNG: first chunk is not IHDR", name);
  ImageHeader header;
  const uint32_t width = BigEndian32(chunk + 16), height = BigEndian32(chunk + 20);
  CheckSize(name, "PNG", width, height);
  header.width = static_cast<int>(width);
  header.height = static_cast<int>(height);
  const int color_type = chunk[25];
  file.Skip(4, "PNG header");  // IHDR CRC
  bool has_trns = false;
  for (;;) {
    uint8_t head[8];
    file.Read(head, 8, "PNG (no image data)");
    if (std::memcmp(head + 4, "IDAT", 4) == 0) break;
    if (std::memcmp(head + 4, "tRNS", 4) == 0) has_trns = true;
    file.Skip(uint64_t{BigEndian32(head)} + 4, "PNG (no image data)");
  }
  header.channels = PngChannels(color_type, has_trns);
  REPHOTO_CHECK(header.channels > 0, "{}: unsupported PNG colour type {}", name, color_type);
  return header;
}

ImageHeader JpegHeader(FilePrefix& file, const std::string& name) {
  file.Skip(2, "JPEG header");  // SOI, already checked
  for (;;) {
    uint8_t byte = 0;
    file.Read(&byte, 1, "JPEG header (no frame header)");
    if (byte != 0xFF) continue;  // stray byte between segments
    uint8_t marker = 0xFF;
    while (marker == 0xFF) file.Read(&marker, 1, "JPEG header (no frame header)");
    if (marker == 0x01 || marker == 0xD8 || (marker >= 0xD0 && marker <= 0xD7)) continue;
    REPHOTO_CHECK(marker != 0xD9 && marker != 0xDA, "{}: invalid JPEG: no frame header", name);
    uint8_t length_bytes[2];
    file.Read(length_bytes, 2, "JPEG header");
    const int length = BigEndian16(length_bytes);
    REPHOTO_CHECK(length >= 2, "{}: invalid JPEG: bad segment length", name);
    const bool frame =
        marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (!frame) {
      file.Skip(length - 2, "JPEG header");
      continue;
    }
    uint8_t sof[6];
    file.Read(sof, 6, "JPEG frame header");
    REPHOTO_CHECK(sof[0] == 8, "{}: {}-bit JPEG is not supported (only 8-bit)", name, sof[0]);
    const int height = BigEndian16(sof + 1), width = BigEndian16(sof + 3);
    CheckSize(name, "JPEG", width, height);
    const int components = sof[5];
    REPHOTO_CHECK(components != 4, "{}: CMYK JPEG is not supported (convert it to RGB)", name);
    REPHOTO_CHECK(components == 1 || components == 3,
                  "{}: JPEG with {} components is not "
                  "supported",
                  name, components);
    return {width, height, components};
  }
}

ImageHeader ExrHeaderOnly(const fs::path& path, const std::string& name) {
  // The header is at the start of the file; most are a few hundred bytes. Retry with the whole
  // file if the prefix was too short.
  std::vector<uint8_t> bytes;
  ReadFileBytes(path, &bytes, 1 << 16);
  ExrHeaderGuard header;
  try {
    ParseExrHeader(bytes, name, &header.header);
  } catch (const Error&) {
    if (bytes.size() < (1u << 16)) throw;
    ReadFileBytes(path, &bytes);
    FreeEXRHeader(&header.header);
    InitEXRHeader(&header.header);
    ParseExrHeader(bytes, name, &header.header);
  }
  const EXRHeader& h = header.header;
  const int64_t width = int64_t{h.data_window.max_x} - h.data_window.min_x + 1;
  const int64_t height = int64_t{h.data_window.max_y} - h.data_window.min_y + 1;
  CheckSize(name, "EXR", width, height);
  return {static_cast<int>(width), static_cast<int>(height),
          static_cast<int>(SelectExrChannels(h, name).size())};
}

// ---------------------------------------------------------------------------------- write

struct FileHandle {
  FILE* file = nullptr;
  ~FileHandle() {
    if (file) std::fclose(file);
  }
};

void EncodePng(const fs::path& path, const void* pixels, size_t size, int width, int height,
               int channels, int depth, PngCompression compression = PngCompression::kFast) {
  // kFast: libdeflate level 1 (zlib level 6 had taken 4 s of CPU for a 12 MP RGBA error image;
  // level 1 with the "up" filter writes a 1152x768 RGBA rendering in about 15 ms). kNone: stored
  // blocks, unfiltered: a cached 1152x768 16-bit photo decodes in 8 ms instead of 30 ms, for a
  // file about 15 % larger.
  const std::vector<uint8_t> png =
      io::EncodePng(pixels, size, width, height, channels, depth,
                    compression == PngCompression::kNone ? 0 : 1, path.string());
  WriteFileAtomically(path, [&](const fs::path& temporary) {
    FileHandle out{std::fopen(temporary.c_str(), "wb")};
    REPHOTO_CHECK(out.file, "{}: cannot open for writing: {}", path.string(), std::strerror(errno));
    const size_t written = std::fwrite(png.data(), 1, png.size(), out.file);
    const int closed = std::fclose(out.file);
    out.file = nullptr;
    REPHOTO_CHECK(written == png.size() && closed == 0, "{}: write failed: {}", path.string(),
                  std::strerror(errno));
  });
}

// The PNG sample of a value: clamped to [0,1] (NaN fails both comparisons and becomes 0),
// scaled to the sample's range, rounded half up.
template <typename T>
T QuantizeSample(float v) {
  constexpr float kMax = sizeof(T) == 1 ? 255.f : 65535.f;
  const float clamped = v > 0.f ? (v < 1.f ? v : 1.f) : 0.f;
  return static_cast<T>(clamped * kMax + 0.5f);
}

// The PNG samples of `image` into `out`; with `back` (may be image's own values), also the
// values ReadImage returns for them, in the same pass.
template <typename T>
void QuantizeTo(const Image& image, T* dst, float* back = nullptr) {
  constexpr float kMax = sizeof(T) == 1 ? 255.f : 65535.f;
  const float* in = image.data();
  ParallelFor(0, static_cast<int64_t>(image.size()), 1 << 16, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      dst[i] = QuantizeSample<T>(in[i]);
      if (back != nullptr) back[i] = static_cast<float>(dst[i]) / kMax;
    }
  });
}

template <typename T>
void QuantizeInPlace(Image* image) {
  constexpr float kMax = sizeof(T) == 1 ? 255.f : 65535.f;
  float* values = image->data();
  ParallelFor(0, static_cast<int64_t>(image->size()), 1 << 16, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      values[i] = static_cast<float>(QuantizeSample<T>(values[i])) / kMax;
    }
  });
}

std::string LowerExtension(const fs::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace

// ------------------------------------------------------------------------------ public API

void DecodeImage(std::span<const uint8_t> bytes, const std::string& name, Image* image) {
  switch (DetectFormat(bytes)) {
    case Format::kPng:
      DecodePng(bytes, name, image);
      return;
    case Format::kJpeg:
      DecodeJpeg(bytes, name, image);
      return;
    case Format::kExr:
      return DecodeExr(bytes, name, image);
    case Format::kPfm:
      return DecodePfm(bytes, name, image);
    case Format::kUnknown:
      break;
  }
  ThrowUnknownFormat(name, bytes.size());
}

namespace internal {
void DecodeImageByLibspng(std::span<const uint8_t> bytes, const std::string& name, Image* image) {
  struct Restore {
    bool before = libspng_only;
    ~Restore() { libspng_only = before; }
  } restore;
  libspng_only = true;
  DecodeImage(bytes, name, image);
}
}  // namespace internal

void ReadImage(const fs::path& path, Image* image) {
  std::vector<uint8_t>& bytes = FileScratch();
  ReadFileBytes(path, &bytes);
  DecodeImage(bytes, path.string(), image);
}

bool ReadImage8(const fs::path& path, Image8* image8, Image* image) {
  std::vector<uint8_t>& bytes = FileScratch();
  ReadFileBytes(path, &bytes);
  const std::string name = path.string();
  switch (DetectFormat(bytes)) {
    case Format::kPng:
      return DecodePng(bytes, name, image, image8);
    case Format::kJpeg:
      return DecodeJpeg(bytes, name, image, image8);
    default:
      DecodeImage(bytes, name, image);
      return false;
  }
}

Image ReadImage(const fs::path& path) {
  Image image;
  ReadImage(path, &image);
  return image;
}

void ReadImagePreview(const fs::path& path, int min_width, Image* image) {
  std::vector<uint8_t>& bytes = FileScratch();
  ReadFileBytes(path, &bytes);
  if (min_width > 0 && DetectFormat(bytes) == Format::kJpeg) {
    DecodeJpeg(bytes, path.string(), image, nullptr, min_width);
  } else {
    DecodeImage(bytes, path.string(), image);
  }
}

Image ReadImagePreview(const fs::path& path, int min_width) {
  Image image;
  ReadImagePreview(path, min_width, &image);
  return image;
}

ImageHeader ReadImageHeader(const fs::path& path) {
  const std::string name = path.string();
  std::array<uint8_t, 8> magic{};
  size_t magic_size = 0;
  {
    FilePrefix file(path);
    file.stream().read(reinterpret_cast<char*>(magic.data()), magic.size());
    magic_size = static_cast<size_t>(file.stream().gcount());
    file.stream().clear();
    file.stream().seekg(0);
    const std::span<const uint8_t> head(magic.data(), magic_size);
    switch (DetectFormat(head)) {
      case Format::kPng:
        return PngHeader(file, name);
      case Format::kJpeg:
        return JpegHeader(file, name);
      case Format::kExr:
      case Format::kPfm:
        break;
      case Format::kUnknown:
        ThrowUnknownFormat(name, magic_size);
    }
  }
  if (DetectFormat({magic.data(), magic_size}) == Format::kExr) return ExrHeaderOnly(path, name);
  std::vector<uint8_t> bytes;
  ReadFileBytes(path, &bytes, 256);
  const PfmHeader pfm = ParsePfmHeader(bytes, name);
  return {pfm.width, pfm.height, pfm.channels};
}

void ReadMask(const fs::path& path, Mask* mask) {
  thread_local Image image;
  ReadImage(path, &image);
  mask->Resize(image.width(), image.height(), 1);
  const int channels = image.channels();
  const float* in = image.data();
  uint8_t* out = mask->data();
  ParallelFor(0, static_cast<int64_t>(mask->size()), 1 << 16, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) out[i] = in[i * channels] > 0.f ? 1 : 0;
  });
}

Mask ReadMask(const fs::path& path) {
  Mask mask;
  ReadMask(path, &mask);
  return mask;
}

void QuantizeAsPng(Image* image, PngDepth depth) {
  if (depth == PngDepth::k16) {
    QuantizeInPlace<uint16_t>(image);
  } else {
    QuantizeInPlace<uint8_t>(image);
  }
}

namespace {
void WritePngOf(const fs::path& path, const Image& image, PngDepth depth,
                PngCompression compression, float* back) {
  if (depth == PngDepth::k8) {
    thread_local std::vector<uint8_t> bytes;
    bytes.resize(image.size());
    QuantizeTo(image, bytes.data(), back);
    EncodePng(path, bytes.data(), bytes.size(), image.width(), image.height(), image.channels(), 8,
              compression);
  } else {
    thread_local std::vector<uint16_t> words;
    words.resize(image.size());
    QuantizeTo(image, words.data(), back);
    EncodePng(path, words.data(), words.size() * 2, image.width(), image.height(), image.channels(),
              16, compression);
  }
}
}  // namespace

void WritePng(const fs::path& path, const Image& image, PngDepth depth,
              PngCompression compression) {
  WritePngOf(path, image, depth, compression, nullptr);
}

void WritePngAndQuantize(const fs::path& path, Image* image, PngDepth depth,
                         PngCompression compression) {
  WritePngOf(path, *image, depth, compression, image->data());
}

void WritePngAndQuantize(const fs::path& path, const Image& image, Image8* bytes) {
  if (bytes->width() != image.width() || bytes->height() != image.height() ||
      bytes->channels() != image.channels()) {
    *bytes = Image8(image.width(), image.height(), image.channels());
  }
  QuantizeTo(image, bytes->data());
  EncodePng(path, bytes->data(), bytes->size(), image.width(), image.height(), image.channels(), 8,
            PngCompression::kFast);
}

void WritePng(const fs::path& path, const Mask& mask) {
  std::vector<uint8_t> bytes(mask.size());
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = mask.data()[i] ? 255 : 0;
  EncodePng(path, bytes.data(), bytes.size(), mask.width(), mask.height(), mask.channels(), 8);
}

void WritePng8(const fs::path& path, std::span<const uint8_t> pixels, int width, int height,
               int channels) {
  REPHOTO_CHECK(pixels.size() == static_cast<size_t>(width) * height * channels,
                "{}: {} bytes given for a {}x{}x{} image", path.string(), pixels.size(), width,
                height, channels);
  EncodePng(path, pixels.data(), pixels.size(), width, height, channels, 8);
}

void WriteExr(const fs::path& path, const Image& image) {
  const int channels = image.channels();
  REPHOTO_CHECK(channels >= 1 && channels <= 4, "{}: cannot write {} channels as EXR",
                path.string(), channels);
  REPHOTO_CHECK(!image.empty(), "{}: cannot write an empty image", path.string());
  // EXR readers expect channels sorted by name: A, B, G, R / A, Y. `order` maps each file
  // channel to the image channel that feeds it.
  static const std::vector<std::pair<const char*, int>> kLayouts[5] = {
      {},
      {{"Y", 0}},
      {{"A", 1}, {"Y", 0}},
      {{"B", 2}, {"G", 1}, {"R", 0}},
      {{"A", 3}, {"B", 2}, {"G", 1}, {"R", 0}}};
  const auto& layout = kLayouts[channels];
  const size_t pixels = image.pixel_count();
  thread_local std::vector<float> planar_scratch;
  planar_scratch.resize(pixels * channels);
  // Worker threads must not name the thread_local (they would see their own, empty one).
  float* const planar = planar_scratch.data();
  ParallelFor(0, static_cast<int64_t>(pixels), 1 << 16, [&](int64_t b, int64_t e) {
    for (int c = 0; c < channels; ++c) {
      float* plane = planar + static_cast<size_t>(c) * pixels;
      const int source = layout[c].second;
      for (int64_t i = b; i < e; ++i) plane[i] = image.data()[i * channels + source];
    }
  });
  std::vector<EXRChannelInfo> infos(channels);
  std::vector<int> types(channels, TINYEXR_PIXELTYPE_FLOAT);
  std::vector<unsigned char*> planes(channels);
  for (int c = 0; c < channels; ++c) {
    std::memset(&infos[c], 0, sizeof(EXRChannelInfo));
    std::strncpy(infos[c].name, layout[c].first, sizeof(infos[c].name) - 1);
    planes[c] = reinterpret_cast<unsigned char*>(planar + static_cast<size_t>(c) * pixels);
  }
  EXRHeader header;
  InitEXRHeader(&header);
  header.num_channels = channels;
  header.channels = infos.data();
  header.pixel_types = types.data();
  header.requested_pixel_types = types.data();
  // Uncompressed: ZIP saved about 5 % on 12 MP float error images (their low mantissa bits are
  // noise) for 2 s of CPU per file.
  header.compression_type = TINYEXR_COMPRESSIONTYPE_NONE;
  EXRImage exr;
  InitEXRImage(&exr);
  exr.images = planes.data();
  exr.width = image.width();
  exr.height = image.height();
  exr.num_channels = channels;
  WriteFileAtomically(path, [&](const fs::path& temporary) {
    const char* err = nullptr;
    const int r = SaveEXRImageToFile(&exr, &header, temporary.c_str(), &err);
    if (r != 0) ThrowExr(path.string(), "EXR writing failed", r, err);
  });
}

void WritePfm(const fs::path& path, const Image& image) {
  const int channels = image.channels();
  REPHOTO_CHECK(channels == 1 || channels == 3, "{}: PFM holds 1 or 3 channels, the image has {}",
                path.string(), channels);
  REPHOTO_CHECK(!image.empty(), "{}: cannot write an empty image", path.string());
  std::string content =
      fmt::format("{}\n{} {}\n-1\n", channels == 3 ? "PF" : "Pf", image.width(), image.height());
  const size_t header_size = content.size();
  const size_t row_bytes = static_cast<size_t>(image.width()) * channels * 4;
  content.resize(header_size + row_bytes * image.height());
  for (int y = 0; y < image.height(); ++y) {
    char* out =
        content.data() + header_size + static_cast<size_t>(image.height() - 1 - y) * row_bytes;
    const float* in = image.row(y);
    for (size_t i = 0; i < row_bytes / 4; ++i) {
      uint32_t bits;
      std::memcpy(&bits, in + i, 4);
      if constexpr (std::endian::native == std::endian::big) bits = __builtin_bswap32(bits);
      std::memcpy(out + 4 * i, &bits, 4);
    }
  }
  WriteTextFileAtomically(path, content);
}

void WriteImage(const fs::path& path, const Image& image) {
  const std::string ext = LowerExtension(path);
  if (ext == ".png") return WritePng(path, image);
  if (ext == ".exr") return WriteExr(path, image);
  if (ext == ".pfm") return WritePfm(path, image);
  ThrowError("{}: cannot write images with extension '{}' (use .png, .exr or .pfm)", path.string(),
             ext);
}

bool IsImageFile(const fs::path& path) {
  const std::string ext = LowerExtension(path);
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".exr" || ext == ".pfm";
}

}  // namespace rephoto::io
