#include "rephoto/core/progress.h"

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdio>

#include <fmt/format.h>

namespace rephoto {
namespace {
std::atomic<bool> g_quiet{false};

std::string FormatDuration(double seconds) {
  if (seconds < 60) return fmt::format("{:.0f}s", seconds);
  if (seconds < 3600) return fmt::format("{:.0f}m{:02.0f}s", std::floor(seconds / 60), std::fmod(seconds, 60));
  return fmt::format("{:.0f}h{:02.0f}m", std::floor(seconds / 3600), std::fmod(seconds / 60, 60));
}
}  // namespace

void SetQuiet(bool quiet) { g_quiet = quiet; }

void LogInfo(std::string_view message) {
  if (!g_quiet) fmt::print(stderr, "rephoto: {}\n", message);
}

void LogWarning(std::string_view message) { fmt::print(stderr, "rephoto: warning: {}\n", message); }

Progress::Progress(std::string task, size_t total)
    : task_(std::move(task)),
      total_(total),
      terminal_(::isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()) {}

Progress::~Progress() { Finish(); }

void Progress::Advance(std::string_view item) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++done_;
  if (g_quiet) return;
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double remaining =
      done_ > 0 ? elapsed / static_cast<double>(done_) * static_cast<double>(total_ - done_) : 0;
  const double percent = total_ > 0 ? 100.0 * static_cast<double>(done_) / total_ : 100.0;
  if (terminal_) {
    fmt::print(stderr, "\r\x1b[K{} [{}/{}] {:.0f}% ETA {} {}", task_, done_, total_, percent,
               FormatDuration(remaining), item);
  } else {
    fmt::print(stderr, "rephoto: {} [{}/{}] {} ({:.1f}s elapsed)\n", task_, done_, total_, item,
               elapsed);
  }
  std::fflush(stderr);
}

void Progress::Finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return;
  finished_ = true;
  if (terminal_ && !g_quiet && done_ > 0) fmt::print(stderr, "\n");
}

}  // namespace rephoto
