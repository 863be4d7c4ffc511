// rephoto's one error policy.
//
// Bad input (a file that is missing, truncated, lies about its size, holds NaN, ...) and broken
// preconditions throw rephoto::Error whose message is one line naming the file, and where
// known the line, record or field, and what is wrong: "photos/a.jpg: not a JPEG file".
// Per-item misses that are a normal outcome (a point behind the camera) are std::optional,
// never exceptions. The CLI catches Error, prints "rephoto: <message>" and exits with
// ExitCode::kFailure; bad command-line options exit with ExitCode::kUsage.
#pragma once

#include <fmt/format.h>

#include <stdexcept>
#include <string>

namespace rephoto {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// Process exit codes of the rephoto CLI.
enum class ExitCode : int {
  kOk = 0,       // everything requested was done
  kFailure = 1,  // bad input or a failed step; the message says which file and why
  kUsage = 2,    // invalid command-line options
  kIncomplete = 3,  // finished, but some items were missing or failed (listed in the outputs)
};

template <typename... Args>
[[noreturn]] void ThrowError(fmt::format_string<Args...> format, Args&&... args) {
  throw Error(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace rephoto

// REPHOTO_CHECK(cond, "fmt", args...): throws rephoto::Error with the formatted message.
#define REPHOTO_CHECK(cond, ...)          \
  do {                                    \
    if (!(cond)) {                        \
      ::rephoto::ThrowError(__VA_ARGS__); \
    }                                     \
  } while (false)
