// Shared by rephoto's libFuzzer targets: run a reader on the input and accept only two
// outcomes, a result or a rephoto::Error. Any other exception (std::out_of_range,
// std::bad_alloc, ...) escapes and libFuzzer reports it; AddressSanitizer and
// UndefinedBehaviorSanitizer report memory errors and undefined behaviour.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"

namespace rephoto::fuzz {

inline std::string_view AsText(const uint8_t* data, size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// Runs `read`; returns false when it threw rephoto::Error (bad input, the expected outcome
// for most fuzz inputs). The readers' warnings are silenced.
template <typename Read>
bool AcceptsInput(Read&& read) {
  SetQuiet(true);
  try {
    read();
    return true;
  } catch (const Error&) {
    return false;
  }
}

}  // namespace rephoto::fuzz
