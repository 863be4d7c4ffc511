#include "rephoto/ibr/depth_map_io.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/limits.h"
#include "rephoto/io/image_io.h"

namespace rephoto::ibr {
namespace {

static_assert(std::endian::native == std::endian::little,
              "COLMAP depth maps are little-endian; add byte swapping for this platform");

// Largest accepted side: COLMAP depth maps are image-sized, far below this.
constexpr int64_t kMaxSide = 1 << 17;

float CleanDepth(float v) {
  return std::isfinite(v) && v > 0 ? v : std::numeric_limits<float>::quiet_NaN();
}

// Reads "<int>&" after optional whitespace; throws naming the field.
int64_t ReadHeaderField(std::istream& in, const std::string& name, const char* field) {
  while (in.peek() == ' ' || in.peek() == '\n' || in.peek() == '\t' || in.peek() == '\r') {
    in.get();
  }
  int64_t value = 0;
  int digits = 0;
  while (std::isdigit(in.peek())) {
    value = value * 10 + (in.get() - '0');
    REPHOTO_CHECK(++digits <= 9, "{}: COLMAP depth map header: {} has too many digits", name,
                  field);
  }
  REPHOTO_CHECK(digits > 0, "{}: COLMAP depth map header: {} is not a number", name, field);
  REPHOTO_CHECK(in.get() == '&', "{}: COLMAP depth map header: '&' expected after the {}", name,
                field);
  return value;
}

}  // namespace

Image ReadColmapDepthMap(std::istream& in, const std::string& name) {
  const int64_t width = ReadHeaderField(in, name, "width");
  const int64_t height = ReadHeaderField(in, name, "height");
  const int64_t channels = ReadHeaderField(in, name, "channel count");
  REPHOTO_CHECK(width > 0 && height > 0 && width <= kMaxSide && height <= kMaxSide,
                "{}: COLMAP depth map header: bad size {}x{}", name, width, height);
  REPHOTO_CHECK(channels >= 1 && channels <= 4, "{}: COLMAP depth map header: bad channel count {}",
                name, channels);
  // Before allocating: the size against --max-pixels / --max-memory (core/limits.h), and the
  // payload against the bytes the stream still holds, when it can tell.
  CheckImageSize(name, "COLMAP depth map", width, height, 1, sizeof(float));
  const size_t plane = static_cast<size_t>(width) * static_cast<size_t>(height);
  const std::streampos here = in.tellg();
  if (here != std::streampos(-1)) {
    in.seekg(0, std::ios::end);
    const std::streampos end = in.tellg();
    in.seekg(here);
    if (end != std::streampos(-1) && in) {
      const auto available = static_cast<uint64_t>(end - here);
      REPHOTO_CHECK(available >= plane * channels * 4,
                    "{}: truncated COLMAP depth map: {} of {} bytes of values", name, available,
                    plane * channels * 4);
    } else {
      in.clear();
      in.seekg(here);
    }
  }
  Image depth(static_cast<int>(width), static_cast<int>(height), 1);
  // Only the first channel (the first plane) is needed, but the whole payload must be there.
  in.read(reinterpret_cast<char*>(depth.data()), static_cast<std::streamsize>(plane * 4));
  REPHOTO_CHECK(static_cast<size_t>(in.gcount()) == plane * 4,
                "{}: truncated COLMAP depth map: {} of {} bytes of values", name,
                static_cast<size_t>(in.gcount()), plane * channels * 4);
  if (channels > 1) {
    in.ignore(static_cast<std::streamsize>(plane * 4 * (channels - 1)));
    REPHOTO_CHECK(static_cast<size_t>(in.gcount()) == plane * 4 * (channels - 1),
                  "{}: truncated COLMAP depth map: {} of {} bytes of values", name,
                  plane * 4 + static_cast<size_t>(in.gcount()), plane * channels * 4);
  }
  REPHOTO_CHECK(in.peek() == std::char_traits<char>::eof(),
                "{}: COLMAP depth map has bytes after the {}x{}x{} values (wrong header?)", name,
                width, height, channels);
  float* values = depth.data();
  for (size_t i = 0; i < plane; ++i) values[i] = CleanDepth(values[i]);
  return depth;
}

Image ReadDepthMap(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  REPHOTO_CHECK(file.good(), "{}: cannot open depth map", path.string());
  char first = 0;
  file.get(first);
  REPHOTO_CHECK(file.good(), "{}: empty depth map file", path.string());
  if (std::isdigit(static_cast<unsigned char>(first)) || first == ' ') {
    file.unget();
    return ReadColmapDepthMap(file, path.string());
  }
  file.close();
  Image image = io::ReadImage(path);
  REPHOTO_CHECK(image.channels() >= 1 && !image.empty(), "{}: depth map has no pixels",
                path.string());
  Image depth(image.width(), image.height(), 1);
  const int c = image.channels();
  for (size_t i = 0; i < depth.pixel_count(); ++i)
    depth.data()[i] = CleanDepth(image.data()[i * c]);
  return depth;
}

void WriteColmapDepthMap(const std::filesystem::path& path, const Image& depth) {
  REPHOTO_CHECK(depth.channels() == 1, "{}: a depth map has 1 channel, not {}", path.string(),
                depth.channels());
  std::vector<float> values(depth.pixel_count());
  for (size_t i = 0; i < values.size(); ++i) {
    const float v = depth.data()[i];
    values[i] = std::isfinite(v) && v > 0 ? v : 0.0f;
  }
  WriteFileAtomically(path, [&](const std::filesystem::path& temporary) {
    std::ofstream out(temporary, std::ios::binary);
    REPHOTO_CHECK(out.good(), "{}: cannot write", temporary.string());
    out << depth.width() << '&' << depth.height() << '&' << 1 << '&';
    out.write(reinterpret_cast<const char*>(values.data()),
              static_cast<std::streamsize>(values.size() * sizeof(float)));
    out.close();
    REPHOTO_CHECK(out.good(), "{}: write error", temporary.string());
  });
}

}  // namespace rephoto::ibr
