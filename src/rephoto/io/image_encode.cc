#include "rephoto/io/image_encode.h"

#include <spng.h>
#include <turbojpeg.h>

#include <cstdlib>
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

struct SpngDeleter {
  void operator()(spng_ctx* ctx) const { spng_ctx_free(ctx); }
};

struct TjDeleter {
  void operator()(void* handle) const { tjDestroy(handle); }
};

}  // namespace

std::vector<uint8_t> EncodePngToMemory(std::span<const uint8_t> pixels, int width, int height,
                                       int channels, const std::string& name) {
  REPHOTO_CHECK(channels >= 1 && channels <= 4, "{}: cannot encode {} channels as PNG", name,
                channels);
  CheckPixels(pixels, width, height, channels, name);
  static constexpr uint8_t kColorType[5] = {
      0, SPNG_COLOR_TYPE_GRAYSCALE, SPNG_COLOR_TYPE_GRAYSCALE_ALPHA, SPNG_COLOR_TYPE_TRUECOLOR,
      SPNG_COLOR_TYPE_TRUECOLOR_ALPHA};
  std::unique_ptr<spng_ctx, SpngDeleter> ctx(spng_ctx_new(SPNG_CTX_ENCODER));
  REPHOTO_CHECK(ctx, "{}: out of memory", name);
  spng_set_option(ctx.get(), SPNG_ENCODE_TO_BUFFER, 1);
  spng_set_option(ctx.get(), SPNG_IMG_COMPRESSION_LEVEL, 6);
  spng_ihdr ihdr{};
  ihdr.width = static_cast<uint32_t>(width);
  ihdr.height = static_cast<uint32_t>(height);
  ihdr.bit_depth = 8;
  ihdr.color_type = kColorType[channels];
  int r = spng_set_ihdr(ctx.get(), &ihdr);
  if (r == 0) {
    r = spng_encode_image(ctx.get(), pixels.data(), pixels.size(), SPNG_FMT_PNG,
                          SPNG_ENCODE_FINALIZE);
  }
  REPHOTO_CHECK(r == 0, "{}: PNG encoding failed: {}", name, spng_strerror(r));
  size_t size = 0;
  void* buffer = spng_get_png_buffer(ctx.get(), &size, &r);
  REPHOTO_CHECK(buffer && r == 0, "{}: PNG encoding failed: {}", name, spng_strerror(r));
  const uint8_t* bytes = static_cast<const uint8_t*>(buffer);
  std::vector<uint8_t> png(bytes, bytes + size);
  std::free(buffer);  // spng_get_png_buffer hands over a malloc'ed buffer
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
