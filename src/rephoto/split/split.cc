#include "rephoto/split/split.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <set>

#include "rephoto/core/error.h"
#include "rephoto/split/random.h"

namespace rephoto::split {

namespace fs = std::filesystem;

namespace {

std::vector<std::string_view> SplitOn(std::string_view text, char separator) {
  std::vector<std::string_view> parts;
  size_t start = 0;
  for (;;) {
    const size_t end = text.find(separator, start);
    parts.push_back(text.substr(start, end == std::string_view::npos ? end : end - start));
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  return parts;
}

long long ParseCount(std::string_view text, std::string_view scheme, std::string_view what,
                     long long min_value) {
  long long value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  REPHOTO_CHECK(ec == std::errc() && end == text.data() + text.size() && !text.empty(),
                "--scheme '{}': {} must be an integer, got '{}'", scheme, what, text);
  REPHOTO_CHECK(value >= min_value && value <= 1'000'000'000,
                "--scheme '{}': {} = {} must be at least {}", scheme, what, value, min_value);
  return value;
}

uint64_t ParseSeed(std::string_view text, std::string_view scheme) {
  uint64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  REPHOTO_CHECK(ec == std::errc() && end == text.data() + text.size() && !text.empty(),
                "--scheme '{}': seed must be a non-negative integer, got '{}'", scheme, text);
  return value;
}

}  // namespace

std::vector<ImageListEntry> ReadImageListEntries(const fs::path& path) {
  std::ifstream in(path);
  REPHOTO_CHECK(in, "{}: cannot open image list", path.string());
  std::vector<ImageListEntry> entries;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const size_t last = line.find_last_not_of(" \t\r");
    std::string name = line.substr(first, last - first + 1);
    while (name.size() > 2 && name.starts_with("./")) name.erase(0, 2);
    entries.push_back({std::move(name), line_number});
  }
  REPHOTO_CHECK(!in.bad(), "{}: read error", path.string());
  return entries;
}

namespace {

// Single-fold split from a per-image test flag over `sorted` names.
Split SingleFold(const Scheme& scheme, const std::vector<std::string>& sorted,
                 const std::vector<bool>& is_test) {
  Split split;
  split.scheme = scheme;
  Fold fold;
  for (size_t i = 0; i < sorted.size(); ++i)
    (is_test[i] ? fold.test : fold.train).push_back(sorted[i]);
  split.folds.push_back(std::move(fold));
  return split;
}

}  // namespace

std::string_view Scheme::Name() const {
  switch (kind) {
    case SchemeKind::kKFold:
      return "kfold";
    case SchemeKind::kInterleaved:
      return "interleaved";
    case SchemeKind::kLeaveOneOut:
      return "loo";
    case SchemeKind::kEveryNth:
      return "every";
    case SchemeKind::kFraction:
      return "fraction";
    case SchemeKind::kLists:
      return "lists";
    case SchemeKind::kNone:
      return "none";
  }
  return "none";
}

std::string Scheme::ToString() const {
  switch (kind) {
    case SchemeKind::kKFold:
      return fmt::format("kfold:{}:{}", folds, seed);
    case SchemeKind::kInterleaved:
      return fmt::format("interleaved:{}", folds);
    case SchemeKind::kLeaveOneOut:
      return "loo";
    case SchemeKind::kEveryNth:
      return fmt::format("every:{}", every);
    case SchemeKind::kFraction:
      return fmt::format("fraction:{}:{}", fraction, seed);
    case SchemeKind::kLists:
      return fmt::format("lists:{},{}", train_list.string(), test_list.string());
    case SchemeKind::kNone:
      return "none";
  }
  return "none";
}

namespace {
Scheme ParseSchemeText(std::string_view text);
}  // namespace

Scheme ParseScheme(std::string_view text) {
  // A scheme is a setting: whatever is wrong with its text is a usage error (exit 2).
  try {
    return ParseSchemeText(text);
  } catch (const UsageError&) {
    throw;
  } catch (const Error& e) {
    throw UsageError(e.what());
  }
}

namespace {
Scheme ParseSchemeText(std::string_view text) {
  const size_t colon = text.find(':');
  const std::string_view name = text.substr(0, colon);
  const std::string_view rest = colon == std::string_view::npos ? "" : text.substr(colon + 1);
  const std::vector<std::string_view> params =
      colon == std::string_view::npos ? std::vector<std::string_view>{} : SplitOn(rest, ':');
  Scheme scheme;
  if (name == "kfold") {
    REPHOTO_CHECK(params.size() == 1 || params.size() == 2,
                  "--scheme '{}': expected kfold:K or kfold:K:SEED", text);
    scheme.kind = SchemeKind::kKFold;
    scheme.folds = static_cast<int>(ParseCount(params[0], text, "K", 2));
    if (params.size() == 2) scheme.seed = ParseSeed(params[1], text);
  } else if (name == "interleaved") {
    REPHOTO_CHECK(params.size() == 1, "--scheme '{}': expected interleaved:K", text);
    scheme.kind = SchemeKind::kInterleaved;
    scheme.folds = static_cast<int>(ParseCount(params[0], text, "K", 2));
  } else if (name == "loo") {
    REPHOTO_CHECK(params.empty(), "--scheme '{}': loo takes no parameters", text);
    scheme.kind = SchemeKind::kLeaveOneOut;
  } else if (name == "every") {
    REPHOTO_CHECK(params.size() == 1, "--scheme '{}': expected every:N", text);
    scheme.kind = SchemeKind::kEveryNth;
    scheme.every = static_cast<int>(ParseCount(params[0], text, "N", 2));
  } else if (name == "fraction") {
    REPHOTO_CHECK(params.size() == 1 || params.size() == 2,
                  "--scheme '{}': expected fraction:F or fraction:F:SEED", text);
    scheme.kind = SchemeKind::kFraction;
    double value = 0.0;
    const auto [end, ec] =
        std::from_chars(params[0].data(), params[0].data() + params[0].size(), value);
    REPHOTO_CHECK(ec == std::errc() && end == params[0].data() + params[0].size() &&
                      !params[0].empty() && value > 0.0 && value < 1.0,
                  "--scheme '{}': F must be a number strictly between 0 and 1, got '{}'", text,
                  params[0]);
    scheme.fraction = value;
    if (params.size() == 2) scheme.seed = ParseSeed(params[1], text);
  } else if (name == "lists") {
    const std::vector<std::string_view> files = SplitOn(rest, ',');
    REPHOTO_CHECK(colon != std::string_view::npos && files.size() == 2 && !files[0].empty() &&
                      !files[1].empty(),
                  "--scheme '{}': expected lists:TRAIN_FILE,TEST_FILE", text);
    scheme.kind = SchemeKind::kLists;
    scheme.train_list = std::string(files[0]);
    scheme.test_list = std::string(files[1]);
  } else if (name == "none") {
    REPHOTO_CHECK(params.empty(), "--scheme '{}': none takes no parameters", text);
    scheme.kind = SchemeKind::kNone;
  } else {
    ThrowError(
        "--scheme '{}': unknown scheme '{}' (supported: kfold:K[:SEED], loo, interleaved:K, "
        "every:N, fraction:F[:SEED], lists:TRAIN,TEST, none)",
        text, name);
  }
  return scheme;
}
}  // namespace

std::vector<std::string> ReadImageList(const fs::path& path) {
  std::vector<std::string> names;
  for (ImageListEntry& entry : ReadImageListEntries(path)) names.push_back(std::move(entry.name));
  return names;
}

Split MakeSplit(const std::vector<std::string>& image_names, const Scheme& scheme) {
  std::vector<std::string> sorted = image_names;
  std::sort(sorted.begin(), sorted.end());
  const auto duplicate = std::adjacent_find(sorted.begin(), sorted.end());
  REPHOTO_CHECK(duplicate == sorted.end(), "split: image name '{}' occurs twice in the scene",
                duplicate == sorted.end() ? std::string() : *duplicate);
  const size_t n = sorted.size();
  REPHOTO_CHECK(n >= 1, "split: the scene has no images");
  const std::string scheme_text = scheme.ToString();

  switch (scheme.kind) {
    case SchemeKind::kKFold:
    case SchemeKind::kInterleaved:
    case SchemeKind::kLeaveOneOut: {
      const size_t k =
          scheme.kind == SchemeKind::kLeaveOneOut ? n : static_cast<size_t>(scheme.folds);
      // A scheme that does not fit the scene is a bad setting (exit 2), as a malformed one is.
      REPHOTO_CHECK_USAGE(k >= 2 && k <= n, "split {}: needs 2 <= K <= number of images ({})",
                          scheme_text, n);
      std::vector<size_t> order(n);
      for (size_t i = 0; i < n; ++i) order[i] = i;
      if (scheme.kind == SchemeKind::kKFold) SeededShuffle(order, scheme.seed);
      std::vector<size_t> fold_of(n);
      for (size_t position = 0; position < n; ++position) fold_of[order[position]] = position % k;
      Split split;
      split.scheme = scheme;
      split.folds.resize(k);
      for (size_t i = 0; i < n; ++i) {
        for (size_t f = 0; f < k; ++f) {
          (fold_of[i] == f ? split.folds[f].test : split.folds[f].train).push_back(sorted[i]);
        }
      }
      return split;
    }
    case SchemeKind::kEveryNth: {
      REPHOTO_CHECK_USAGE(scheme.every >= 2, "split {}: N must be at least 2", scheme_text);
      REPHOTO_CHECK_USAGE(n >= 2, "split {}: needs at least 2 images", scheme_text);
      std::vector<bool> is_test(n);
      for (size_t i = 0; i < n; ++i) is_test[i] = i % static_cast<size_t>(scheme.every) == 0;
      return SingleFold(scheme, sorted, is_test);
    }
    case SchemeKind::kFraction: {
      REPHOTO_CHECK_USAGE(n >= 2, "split {}: needs at least 2 images", scheme_text);
      const long long rounded = std::llround(scheme.fraction * static_cast<double>(n));
      const size_t test_count =
          static_cast<size_t>(std::clamp<long long>(rounded, 1, static_cast<long long>(n) - 1));
      std::vector<size_t> order(n);
      for (size_t i = 0; i < n; ++i) order[i] = i;
      SeededShuffle(order, scheme.seed);
      std::vector<bool> is_test(n, false);
      for (size_t position = 0; position < test_count; ++position) is_test[order[position]] = true;
      return SingleFold(scheme, sorted, is_test);
    }
    case SchemeKind::kLists: {
      std::map<std::string, std::string, std::less<>> where;  // name -> "<list>:<line>"
      Split split;
      split.scheme = scheme;
      Fold fold;
      for (const auto& [path, is_test] :
           {std::pair{scheme.train_list, false}, std::pair{scheme.test_list, true}}) {
        for (ImageListEntry& entry : ReadImageListEntries(path)) {
          const std::string location = fmt::format("{}:{}", path.string(), entry.line);
          REPHOTO_CHECK(std::binary_search(sorted.begin(), sorted.end(), entry.name),
                        "{}: image '{}' is not in the scene", location, entry.name);
          const auto [it, inserted] = where.emplace(entry.name, location);
          REPHOTO_CHECK(inserted, "{}: image '{}' is already listed at {}", location, entry.name,
                        it->second);
          (is_test ? fold.test : fold.train).push_back(std::move(entry.name));
        }
      }
      REPHOTO_CHECK(!fold.test.empty(), "{}: the test list is empty", scheme.test_list.string());
      std::sort(fold.train.begin(), fold.train.end());
      std::sort(fold.test.begin(), fold.test.end());
      split.folds.push_back(std::move(fold));
      return split;
    }
    case SchemeKind::kNone: {
      Split split;
      split.scheme = scheme;
      split.cross_validated = false;
      split.folds.push_back({sorted, sorted});
      return split;
    }
  }
  ThrowError("split: unknown scheme");
}

}  // namespace rephoto::split
