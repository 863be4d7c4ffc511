#include "rephoto/compare/error_images.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <string>

#include "rephoto/compare/compare.h"
#include "rephoto/core/colormap.h"
#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/io/image_io.h"

namespace rephoto::compare {
namespace fs = std::filesystem;

namespace {

// EXR header exactly as tinyexr (behind io::WriteExr) writes it for one FLOAT channel "Y",
// no compression, increasing lines: version 2, single-part scanline file.
std::vector<uint8_t> ExrHeader(int width, int height) {
  std::vector<uint8_t> h;
  auto bytes = [&h](const void* data, size_t size) {
    const auto* p = static_cast<const uint8_t*>(data);
    h.insert(h.end(), p, p + size);
  };
  auto i32 = [&](int32_t v) {
    const uint32_t u = static_cast<uint32_t>(v);
    const uint8_t b[4] = {static_cast<uint8_t>(u), static_cast<uint8_t>(u >> 8),
                          static_cast<uint8_t>(u >> 16), static_cast<uint8_t>(u >> 24)};
    bytes(b, 4);
  };
  auto f32 = [&](float v) { i32(std::bit_cast<int32_t>(v)); };
  auto text = [&](const char* s) { bytes(s, std::strlen(s) + 1); };
  auto attribute = [&](const char* name, const char* type, int32_t size) {
    text(name);
    text(type);
    i32(size);
  };
  const uint8_t magic[8] = {0x76, 0x2f, 0x31, 0x01, 0x02, 0x00, 0x00, 0x00};
  bytes(magic, 8);
  attribute("channels", "chlist", 19);
  text("Y");
  i32(2);  // FLOAT
  const uint8_t linear_and_reserved[4] = {0, 0, 0, 0};
  bytes(linear_and_reserved, 4);
  i32(1);          // x sampling
  i32(1);          // y sampling
  h.push_back(0);  // end of the channel list
  attribute("compression", "compression", 1);
  h.push_back(0);  // none
  for (const char* window : {"dataWindow", "displayWindow"}) {
    attribute(window, "box2i", 16);
    i32(0);
    i32(0);
    i32(width - 1);
    i32(height - 1);
  }
  attribute("lineOrder", "lineOrder", 1);
  h.push_back(0);  // increasing y
  attribute("pixelAspectRatio", "float", 4);
  f32(1.f);
  attribute("screenWindowCenter", "v2f", 8);
  f32(0.f);
  f32(0.f);
  attribute("screenWindowWidth", "float", 4);
  f32(1.f);
  h.push_back(0);  // end of the header
  return h;
}

void WriteAll(int fd, const uint8_t* data, size_t size, uint64_t offset, const fs::path& path) {
  while (size > 0) {
    const ssize_t n = ::pwrite(fd, data, size, static_cast<off_t>(offset));
    if (n < 0 && errno == EINTR) continue;
    REPHOTO_CHECK(n > 0, "{}: write failed: {}", path.string(), std::strerror(errno));
    data += n;
    size -= static_cast<size_t>(n);
    offset += static_cast<uint64_t>(n);
  }
}

}  // namespace

ErrorExrWriter::ErrorExrWriter(const fs::path& path, int width, int height)
    : path_(path), width_(width), height_(height) {
  REPHOTO_CHECK(width > 0 && height > 0, "{}: cannot write an empty image", path.string());
  temporary_ = path;
  temporary_ += ".tmp-" + std::to_string(::getpid());
  fd_ = ::open(temporary_.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  REPHOTO_CHECK(fd_ >= 0, "{}: cannot open for writing: {}", path.string(), std::strerror(errno));
  std::vector<uint8_t> head = ExrHeader(width, height);
  const uint64_t table = head.size();
  data_offset_ = table + 8 * static_cast<uint64_t>(height);
  const uint64_t chunk = 8 + 4 * static_cast<uint64_t>(width);
  head.resize(data_offset_);
  for (int y = 0; y < height; ++y) {
    const uint64_t offset = data_offset_ + chunk * static_cast<uint64_t>(y);
    for (int b = 0; b < 8; ++b) head[table + 8 * y + b] = static_cast<uint8_t>(offset >> (8 * b));
  }
  WriteAll(fd_, head.data(), head.size(), 0, path_);
}

ErrorExrWriter::~ErrorExrWriter() {
  if (fd_ >= 0) {
    ::close(fd_);
    std::error_code ec;
    fs::remove(temporary_, ec);
  }
}

void ErrorExrWriter::WriteRows(int y0, int y1, const float* values) {
  REPHOTO_CHECK(y0 == rows_written_ && y1 >= y0 && y1 <= height_,
                "{}: rows {}-{} written out of order", path_.string(), y0, y1);
  const size_t row_bytes = 4 * static_cast<size_t>(width_);
  chunks_.resize((8 + row_bytes) * static_cast<size_t>(y1 - y0));
  uint8_t* out = chunks_.data();
  for (int y = y0; y < y1; ++y) {
    const int32_t header[2] = {y, static_cast<int32_t>(row_bytes)};
    std::memcpy(out, header, 8);  // little-endian, as the floats (x86-64)
    std::memcpy(out + 8, values + static_cast<size_t>(y - y0) * width_, row_bytes);
    out += 8 + row_bytes;
  }
  WriteAll(fd_, chunks_.data(), chunks_.size(),
           data_offset_ + (8 + row_bytes) * static_cast<uint64_t>(y0), path_);
  rows_written_ = y1;
}

void ErrorExrWriter::ReadRows(int y0, int y1, float* values) const {
  const size_t row_bytes = 4 * static_cast<size_t>(width_);
  for (int y = y0; y < y1; ++y) {
    uint8_t* out = reinterpret_cast<uint8_t*>(values + static_cast<size_t>(y - y0) * width_);
    uint64_t offset = data_offset_ + (8 + row_bytes) * static_cast<uint64_t>(y) + 8;
    size_t left = row_bytes;
    while (left > 0) {
      const ssize_t n = ::pread(fd_, out, left, static_cast<off_t>(offset));
      if (n < 0 && errno == EINTR) continue;
      REPHOTO_CHECK(n > 0, "{}: read back failed: {}", path_.string(), std::strerror(errno));
      out += n;
      left -= static_cast<size_t>(n);
      offset += static_cast<uint64_t>(n);
    }
  }
}

void ErrorExrWriter::Commit() {
  REPHOTO_CHECK(rows_written_ == height_, "{}: only {} of {} rows written", path_.string(),
                rows_written_, height_);
  const int fd = fd_;
  fd_ = -1;
  REPHOTO_CHECK(::close(fd) == 0, "{}: write failed: {}", path_.string(), std::strerror(errno));
  std::error_code ec;
  fs::rename(temporary_, path_, ec);
  if (ec) {
    fs::remove(temporary_, ec);
    ThrowError("{}: cannot write: {}", path_.string(), ec.message());
  }
}

void ColourErrorValues(const float* values, size_t count, float low, float high, uint8_t* rgba) {
  const float scale = 1.f / (high - low);
  for (size_t i = 0; i < count; ++i) {
    const float v = values[i];
    uint8_t* px = rgba + 4 * i;
    if (std::isnan(v)) {
      px[0] = px[1] = px[2] = px[3] = 0;
      continue;
    }
    const auto colour = JetColor((v - low) * scale);
    for (int c = 0; c < 3; ++c) px[c] = static_cast<uint8_t>(colour[c] * 255.f + 0.5f);
    px[3] = 255;
  }
}

void WriteErrorPng(const ErrorExrWriter& exr, int width, int height, float low, float high,
                   const fs::path& path, std::vector<uint8_t>* rgba) {
  REPHOTO_CHECK(low != high, "{}: empty colour range [{}, {}]", path.string(), low, high);
  rgba->resize(static_cast<size_t>(width) * height * 4);
  constexpr int kRows = 64;
  ParallelFor(0, height, kRows, [&](int64_t y0, int64_t y1) {
    thread_local std::vector<float> values;
    values.resize(static_cast<size_t>(y1 - y0) * width);
    exr.ReadRows(static_cast<int>(y0), static_cast<int>(y1), values.data());
    uint8_t* out = rgba->data() + static_cast<size_t>(y0) * width * 4;
    ColourErrorValues(values.data(), values.size(), low, high, out);
  });
  io::WritePng8(path, *rgba, width, height, 4);
}

void WriteErrorImages(const std::vector<Image>& errors, const std::vector<metrics::Metric>& metrics,
                      const fs::path& folder, const std::string& name, std::vector<uint8_t>* rgba,
                      const std::vector<metrics::Metric>& only) {
  REPHOTO_CHECK(errors.size() == metrics.size(), "{}: {} error images for {} metrics",
                (folder / name).string(), errors.size(), metrics.size());
  for (size_t i = 0; i < errors.size(); ++i) {
    if (!only.empty() && std::find(only.begin(), only.end(), metrics[i]) == only.end()) continue;
    const std::string base = fmt::format("{}.{}", name, metrics::MetricName(metrics[i]));
    const Image& error = errors[i];
    // Bands of rows through ErrorExrWriter: no whole-file buffer (io::WriteExr's), the same bytes.
    ErrorExrWriter exr(folder / (base + ".exr"), error.width(), error.height());
    for (int y0 = 0; y0 < error.height(); y0 += 64) {
      exr.WriteRows(y0, std::min(error.height(), y0 + 64), error.row(y0));
    }
    const auto [low, high] = ErrorColourRange(metrics[i]);
    ColourErrorImage(error, low, high, rgba);
    io::WritePng8(folder / (base + ".png"), *rgba, error.width(), error.height(), 4);
    exr.Commit();
  }
}

}  // namespace rephoto::compare
