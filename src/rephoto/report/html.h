// Small HTML helpers of the reports: escaping, base64 data URIs, number formatting.
//
// Thread safety: pure functions.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace rephoto::report {

// Escapes text for HTML element content and quoted attribute values: & < > " ' become
// entities. All text that comes from files (names, paths, messages, settings) goes through it.
std::string HtmlEscape(std::string_view text);

// Standard base64 (RFC 4648, with '=' padding).
std::string Base64(std::span<const uint8_t> bytes);

// "data:<mime>;base64,..." for embedding an image in an <img src>.
std::string DataUri(std::string_view mime, std::span<const uint8_t> bytes);

// A value for display: 4 significant digits ("0.05133", "29.24", "1.2e-05"), "inf"/"-inf",
// and "–" (en dash) for NaN (not evaluated).
std::string DisplayNumber(double value);

// A value for a data attribute read by the report's JavaScript (Number(...)): shortest
// round-trip text, "Infinity"/"-Infinity", "" for NaN.
std::string DataNumber(double value);

}  // namespace rephoto::report
