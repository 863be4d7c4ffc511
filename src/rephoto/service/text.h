// Checks of the text a request brings (query parameters, form fields, archive member names,
// URL paths) and its safe display in messages and logs.
//
// "Clean text" is valid UTF-8 (shortest form, no surrogates, at most U+10FFFF) without control
// characters: no C0 (U+0000..U+001F), no DEL (U+007F), no C1 (U+0080..U+009F). Only a
// description may hold line breaks and tabs (TextPolicy::kMultiLine). Everything the server
// stores or echoes passes this check at the door, so a stored value always serialises as JSON
// and HTML.
// Thread safety: pure functions.
#pragma once

#include <cstddef>
#include <map>
#include <string>
#include <string_view>

namespace rephoto::service {

enum class TextPolicy { kOneLine, kMultiLine };

// True when `text` is clean (see above); kMultiLine also allows '\n', '\r' and '\t'.
bool IsCleanText(std::string_view text, TextPolicy policy = TextPolicy::kOneLine);

// Throws Refused(400) "<field>: <why>" unless `text` is clean and at most `max_bytes` long
// (`min_bytes` = 1: required).
void CheckRequestText(std::string_view text, std::string_view field, size_t min_bytes,
                      size_t max_bytes, TextPolicy policy = TextPolicy::kOneLine);

// The checks of a request's decoded path and query parameters, before anything else looks at
// them: throws Refused(400) unless the path, every key and every value are clean text (values
// may hold line breaks: a description).
void CheckRequestTarget(std::string_view path,
                        const std::multimap<std::string, std::string>& params);

// `text` for a message or a log line: clean one-line text as is; every byte of an invalid
// sequence and every control character as \xNN; at most `max_bytes` bytes of input shown
// (then "..."). The result is always clean text.
std::string Printable(std::string_view text, size_t max_bytes = 200);

}  // namespace rephoto::service
