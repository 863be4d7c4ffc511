// Pairing photos with renderings (and masks) by file stem.
//
// A folder's images are its regular files whose extension ReadImage handles (.png .jpg .jpeg
// .exr .pfm, any case), not recursively; hidden files (".name"), other files and the depth maps
// `rephoto render` writes next to its rephotos ("<stem>.depth.exr") are ignored.
// The stem is the file name without its last extension ("IMG_0001.JPG" -> "IMG_0001"),
// compared case-sensitively. Two images of one folder with the same stem ("a.png", "a.jpg")
// are an error naming both, since it is unclear which one is meant.
//
// Thread safety: reentrant (lists folders; no shared state).
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace rephoto::compare {

struct ImageFile {
  std::string stem;
  std::filesystem::path path;
};

// The images of `folder`, sorted by stem. Throws Error naming the folder when it does not exist
// or is not a folder, and naming both files when two share a stem. `what` ("photos",
// "renderings", ...) is used in messages.
std::vector<ImageFile> ListImages(const std::filesystem::path& folder, const std::string& what);

// Stem -> path, for mask folders.
std::map<std::string, std::filesystem::path> ImagesByStem(const std::vector<ImageFile>& images);

struct ImagePair {
  std::string name;  // the shared stem
  std::filesystem::path photo;
  std::filesystem::path render;
};

// Which counterpart is missing.
enum class Missing { kRender, kPhoto };

struct MissingImage {
  std::string name;  // the stem
  Missing missing = Missing::kRender;
  std::filesystem::path present;  // the file that has no counterpart
};

struct Pairing {
  std::vector<ImagePair> pairs;       // sorted by name
  std::vector<MissingImage> missing;  // sorted by name
};

// Matches photos and renderings by stem; every image is either in a pair or listed as missing.
// Stems are assumed unique within each list (as ListImages guarantees).
Pairing PairByStem(std::vector<ImageFile> photos, std::vector<ImageFile> renders);

}  // namespace rephoto::compare
