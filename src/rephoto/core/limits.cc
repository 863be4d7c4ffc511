#include "rephoto/core/limits.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <limits>

#include "rephoto/core/error.h"

namespace rephoto {
namespace {

constexpr uint64_t kGiB = uint64_t{1} << 30;

std::atomic<uint64_t>& MaxPixelsValue() {
  static std::atomic<uint64_t> value{kDefaultMaxPixels};
  return value;
}

std::atomic<uint64_t>& MaxMemoryValue() {
  static std::atomic<uint64_t> value{DefaultMaxMemoryBytes()};
  return value;
}

}  // namespace

uint64_t DefaultMaxMemoryBytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page_size = ::sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page_size <= 0) return 16 * kGiB;
  const uint64_t physical =
      SaturatingMultiply(static_cast<uint64_t>(pages), static_cast<uint64_t>(page_size));
  return std::max(physical / 2, 2 * kGiB);
}

uint64_t MaxPixels() { return MaxPixelsValue().load(std::memory_order_relaxed); }
uint64_t MaxMemoryBytes() { return MaxMemoryValue().load(std::memory_order_relaxed); }

void SetMaxPixels(uint64_t pixels) {
  REPHOTO_CHECK(pixels > 0, "--max-pixels must be at least 1");
  MaxPixelsValue().store(pixels, std::memory_order_relaxed);
}

void SetMaxMemoryBytes(uint64_t bytes) {
  REPHOTO_CHECK(bytes > 0, "--max-memory must be at least 1 byte");
  MaxMemoryValue().store(bytes, std::memory_order_relaxed);
}

uint64_t SaturatingMultiply(uint64_t a, uint64_t b) {
  uint64_t product = 0;
  if (__builtin_mul_overflow(a, b, &product)) return std::numeric_limits<uint64_t>::max();
  return product;
}

std::string FormatBytes(uint64_t bytes) {
  if (bytes == std::numeric_limits<uint64_t>::max()) return "more than 16 EiB";
  if (bytes < 1024) return fmt::format("{} B", bytes);
  static constexpr const char* kUnits[] = {"KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  double value = static_cast<double>(bytes) / 1024;
  int unit = 0;
  while (value >= 1024 && unit + 1 < 6) {
    value /= 1024;
    ++unit;
  }
  return fmt::format("{:.1f} {}", value, kUnits[unit]);
}

void CheckAllocation(std::string_view file, std::string_view what, uint64_t bytes) {
  const uint64_t limit = MaxMemoryBytes();
  if (bytes <= limit) return;
  ThrowError("{}: {} need {}, more than --max-memory {} (raise it with --max-memory)", file, what,
             FormatBytes(bytes), FormatBytes(limit));
}

void CheckImageSize(std::string_view file, std::string_view format, int64_t width, int64_t height,
                    int channels, int bytes_per_value) {
  REPHOTO_CHECK(width > 0 && height > 0, "{}: invalid {}: image size {}x{}", file, format, width,
                height);
  const uint64_t pixels =
      SaturatingMultiply(static_cast<uint64_t>(width), static_cast<uint64_t>(height));
  const uint64_t limit = MaxPixels();
  REPHOTO_CHECK(pixels <= limit,
                "{}: {} image of {}x{} pixels ({:.3g}) exceeds --max-pixels {} (raise it with "
                "--max-pixels)",
                file, format, width, height, static_cast<double>(pixels), limit);
  if (channels <= 0) return;
  const uint64_t bytes = SaturatingMultiply(
      pixels, static_cast<uint64_t>(channels) * static_cast<uint64_t>(bytes_per_value));
  CheckAllocation(
      file, fmt::format("{} image of {}x{} pixels x {} channels", format, width, height, channels),
      bytes);
}

uint64_t ParseByteSize(std::string_view text, std::string_view option) {
  size_t pos = 0;
  uint64_t number = 0;
  while (pos < text.size() && std::isdigit(static_cast<unsigned char>(text[pos]))) {
    REPHOTO_CHECK(number <= (std::numeric_limits<uint64_t>::max() - 9) / 10,
                  "{}: size '{}' is too large", option, text);
    number = number * 10 + static_cast<uint64_t>(text[pos] - '0');
    ++pos;
  }
  REPHOTO_CHECK(pos > 0, "{}: expected a size such as 16G, 512M or 1048576, not '{}'", option,
                text);
  std::string unit;
  for (size_t i = pos; i < text.size(); ++i) {
    unit.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(text[i]))));
  }
  int shift = -1;
  if (unit.empty() || unit == "B") {
    shift = 0;
  } else {
    static constexpr std::string_view kPrefixes = "KMGT";
    const size_t prefix = kPrefixes.find(unit[0]);
    const std::string_view rest = std::string_view(unit).substr(1);
    if (prefix != std::string_view::npos && (rest.empty() || rest == "B" || rest == "IB")) {
      shift = 10 * static_cast<int>(prefix + 1);
    }
  }
  REPHOTO_CHECK(shift >= 0,
                "{}: unknown unit in '{}' (use a number of bytes or K, M, G, T, e.g. 16G)", option,
                text);
  REPHOTO_CHECK(number > 0, "{}: size must be at least 1 byte, not '{}'", option, text);
  REPHOTO_CHECK(number <= (uint64_t{1} << (63 - shift)), "{}: size '{}' is too large", option,
                text);
  return number << shift;
}

}  // namespace rephoto
