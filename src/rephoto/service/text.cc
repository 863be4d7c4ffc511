#include "rephoto/service/text.h"

#include <fmt/format.h>

#include "rephoto/service/archive.h"

namespace rephoto::service {
namespace {

// The length of the valid UTF-8 sequence at text[i] and its code point, or 0 when invalid.
size_t Utf8Sequence(std::string_view text, size_t i, char32_t* code_point) {
  const auto byte = [&](size_t k) { return static_cast<unsigned char>(text[i + k]); };
  const unsigned char first = byte(0);
  size_t length = 0;
  char32_t value = 0, minimum = 0;
  if (first < 0x80) {
    *code_point = first;
    return 1;
  } else if ((first & 0xE0) == 0xC0) {
    length = 2, value = first & 0x1F, minimum = 0x80;
  } else if ((first & 0xF0) == 0xE0) {
    length = 3, value = first & 0x0F, minimum = 0x800;
  } else if ((first & 0xF8) == 0xF0) {
    length = 4, value = first & 0x07, minimum = 0x10000;
  } else {
    return 0;
  }
  if (i + length > text.size()) return 0;
  for (size_t k = 1; k < length; ++k) {
    if ((byte(k) & 0xC0) != 0x80) return 0;
    value = (value << 6) | (byte(k) & 0x3F);
  }
  if (value < minimum || value > 0x10FFFF || (value >= 0xD800 && value <= 0xDFFF)) return 0;
  *code_point = value;
  return length;
}

bool IsControl(char32_t c, TextPolicy policy) {
  if (policy == TextPolicy::kMultiLine && (c == '\n' || c == '\r' || c == '\t')) return false;
  return c < 0x20 || (c >= 0x7F && c <= 0x9F);
}

}  // namespace

bool IsCleanText(std::string_view text, TextPolicy policy) {
  for (size_t i = 0; i < text.size();) {
    char32_t c = 0;
    const size_t length = Utf8Sequence(text, i, &c);
    if (length == 0 || IsControl(c, policy)) return false;
    i += length;
  }
  return true;
}

void CheckRequestText(std::string_view text, std::string_view field, size_t min_bytes,
                      size_t max_bytes, TextPolicy policy) {
  if (text.size() < min_bytes || text.size() > max_bytes) {
    throw Refused(400, fmt::format("{}: must be {} to {} bytes", field, min_bytes, max_bytes));
  }
  if (!IsCleanText(text, policy)) {
    throw Refused(400, fmt::format("{}: '{}' is not UTF-8 text without control characters", field,
                                   Printable(text)));
  }
}

void CheckRequestTarget(std::string_view path,
                        const std::multimap<std::string, std::string>& params) {
  if (!IsCleanText(path)) {
    throw Refused(400, "the path is not UTF-8 text without control characters");
  }
  for (const auto& [key, value] : params) {
    if (!IsCleanText(key) || !IsCleanText(value, TextPolicy::kMultiLine)) {
      throw Refused(400, fmt::format("query parameter '{}': not UTF-8 text without control "
                                     "characters",
                                     Printable(key, 100)));
    }
  }
}

std::string Printable(std::string_view text, size_t max_bytes) {
  std::string out;
  const size_t end = std::min(text.size(), max_bytes);
  for (size_t i = 0; i < end;) {
    char32_t c = 0;
    const size_t length = Utf8Sequence(text, i, &c);
    if (length == 0 || IsControl(c, TextPolicy::kOneLine) || i + length > end) {
      out += fmt::format("\\x{:02x}", static_cast<unsigned char>(text[i]));
      ++i;
    } else {
      out.append(text.substr(i, length));
      i += length;
    }
  }
  if (end < text.size()) out += "...";
  return out;
}

}  // namespace rephoto::service
