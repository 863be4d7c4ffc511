// rephoto's one error policy.
//
// Bad input (a file that is missing, truncated, lies about its size, holds NaN, ...) and broken
// preconditions throw rephoto::Error whose message is one line naming the file, and where
// known the line, record or field, and what is wrong: "photos/a.jpg: not a JPEG file".
// Per-item misses that are a normal outcome (a point behind the camera) are std::optional,
// never exceptions. The CLI catches Error, prints "rephoto: <message>" and exits with
// ExitCode::kFailure; bad command-line options exit with ExitCode::kUsage.
//
// Two kinds of Error say more, and main() maps them to their exit codes in one place:
//   UsageError   a setting is invalid wherever it was found (a flag, a TOML config, a sweep
//                file, a --scheme text): exit 2, like a parse error of the command line.
//   Interrupted  the user stopped the run (SIGINT/SIGTERM); what was finished is kept and the
//                same command resumes: exit 130 (128 + SIGINT, the shell's convention).
//
// Thread safety: exception types without shared state.
#pragma once

#include <fmt/format.h>

#include <stdexcept>
#include <string>

namespace rephoto {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// A bad setting (see above). Thrown by option checks in every layer; the CLI exits with kUsage.
class UsageError : public Error {
 public:
  using Error::Error;
};

// The run was stopped by SIGINT/SIGTERM; finished work is kept (the CLI exits kInterrupted).
class Interrupted : public Error {
 public:
  using Error::Error;
};

// Process exit codes of the rephoto CLI.
enum class ExitCode : int {
  kOk = 0,             // everything requested was done
  kFailure = 1,        // bad input or a failed step; the message says which file and why
  kUsage = 2,          // invalid command-line options
  kIncomplete = 3,     // finished, but some items were missing or failed (listed in the outputs)
  kInterrupted = 130,  // stopped by SIGINT/SIGTERM; rerun the same command to resume
};

template <typename... Args>
[[noreturn]] void ThrowError(fmt::format_string<Args...> format, Args&&... args) {
  throw Error(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace rephoto

// REPHOTO_CHECK(cond, "fmt", args...): throws rephoto::Error with the formatted message.
// REPHOTO_CHECK_USAGE(cond, "fmt", args...): the same with rephoto::UsageError.
#define REPHOTO_CHECK_USAGE(cond, ...)                         \
  do {                                                         \
    if (!(cond)) {                                             \
      throw ::rephoto::UsageError(::fmt::format(__VA_ARGS__)); \
    }                                                          \
  } while (false)
#define REPHOTO_CHECK(cond, ...)          \
  do {                                    \
    if (!(cond)) {                        \
      ::rephoto::ThrowError(__VA_ARGS__); \
    }                                     \
  } while (false)
