#include "rephoto/scene/image_name.h"

#include <filesystem>
#include <map>
#include <set>

#include "rephoto/core/error.h"

namespace rephoto::scene {
namespace {

// Printable form of a hostile name for a one-line message (control characters escaped).
std::string Printable(std::string_view raw) {
  std::string out;
  for (const char c : raw.substr(0, 200)) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) {
      out += fmt::format("\\x{:02x}", byte);
    } else {
      out += c;
    }
  }
  if (raw.size() > 200) out += "...";
  return out;
}

}  // namespace

std::string CheckedImageName(std::string_view raw, std::string_view where) {
  auto refuse = [&](std::string_view why) {
    ThrowError("{}: image name '{}' {}", where, Printable(raw), why);
  };
  if (raw.empty()) refuse("is empty");
  for (const char c : raw) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) refuse("contains a control character");
    if (c == '\\') refuse("contains a backslash; use '/' between folders");
  }
  if (raw.front() == '/') refuse("is an absolute path; names must be relative to the image root");
  if (raw.back() == '/') refuse("ends in '/' (a folder, not an image)");
  std::string name;
  size_t begin = 0;
  while (begin <= raw.size()) {
    size_t end = raw.find('/', begin);
    if (end == std::string_view::npos) end = raw.size();
    const std::string_view component = raw.substr(begin, end - begin);
    if (component == "..") refuse("contains '..'; names must stay inside the image root");
    if (!component.empty() && component != ".") {
      if (!name.empty()) name += '/';
      name += component;
    }
    begin = end + 1;
  }
  if (name.empty()) refuse("names no file");
  return name;
}

std::vector<size_t> ViewIndices(const Scene& scene, const std::vector<std::string>& names,
                                std::string_view source) {
  std::map<std::string, size_t, std::less<>> by_name;
  for (size_t v = 0; v < scene.views.size(); ++v) by_name.emplace(scene.views[v].name, v);
  std::vector<size_t> indices;
  indices.reserve(names.size());
  for (const std::string& raw : names) {
    const std::string name = CheckedImageName(raw, source);
    const auto it = by_name.find(name);
    REPHOTO_CHECK(it != by_name.end(), "{}: image '{}' is not in the scene", source, name);
    indices.push_back(it->second);
  }
  return indices;
}

std::vector<std::string> OutputStems(const Scene& scene) {
  namespace fs = std::filesystem;
  auto stems_by = [&](auto&& stem_of) {
    std::vector<std::string> stems;
    std::set<std::string> seen;
    bool distinct = true;
    for (const View& view : scene.views) {
      stems.push_back(stem_of(fs::path(view.name)));
      distinct &= seen.insert(stems.back()).second;
    }
    return std::make_pair(stems, distinct);
  };
  auto [file_stems, files_distinct] =
      stems_by([](const fs::path& name) { return name.stem().generic_string(); });
  if (files_distinct) return file_stems;
  auto [path_stems, paths_distinct] =
      stems_by([](fs::path name) { return name.replace_extension("").generic_string(); });
  if (paths_distinct) return path_stems;
  std::vector<std::string> names;
  for (const View& view : scene.views) names.push_back(view.name);
  return names;
}

}  // namespace rephoto::scene
