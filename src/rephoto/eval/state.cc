#include "rephoto/eval/state.h"

#include <tbb/global_control.h>

#include <algorithm>

namespace rephoto::eval {
namespace fs = std::filesystem;

fs::path RunContext::CacheDir() const {
  return options.cache_dir.empty() ? run / "cache"
                                   : fs::absolute(options.cache_dir).lexically_normal();
}

int RunContext::CommandThreads() const {
  const int all = static_cast<int>(
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  return std::max(1, all / std::max(1, options.jobs));
}

void FailFold(FoldOutcome& fold, const std::string& message) {
  fold.ok = false;
  if (fold.message.empty()) fold.message = message;
}

fs::path FindImageByStem(const fs::path& folder, const std::string& stem) {
  static constexpr const char* kImageExtensions[] = {".png", ".jpg", ".jpeg", ".exr", ".pfm",
                                                     ".PNG", ".JPG", ".JPEG", ".EXR", ".PFM"};
  std::error_code ec;
  for (const char* ext : kImageExtensions) {
    const fs::path candidate = folder / (stem + ext);
    if (fs::is_regular_file(candidate, ec)) return candidate;
  }
  return {};
}

std::string Shorten(const std::string& text, size_t max_chars) {
  std::string one_line = text;
  std::replace(one_line.begin(), one_line.end(), '\n', ' ');
  if (one_line.size() <= max_chars) return one_line;
  return one_line.substr(0, max_chars) + "...";
}

}  // namespace rephoto::eval
