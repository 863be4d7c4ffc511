#include "rephoto/compare/pairing.h"

#include <algorithm>
#include <system_error>

#include "rephoto/core/error.h"
#include "rephoto/io/image_io.h"

namespace rephoto::compare {
namespace fs = std::filesystem;

std::vector<ImageFile> ListImages(const fs::path& folder, const std::string& what) {
  std::error_code ec;
  const fs::file_status status = fs::status(folder, ec);
  REPHOTO_CHECK(fs::exists(status), "{}: {} folder does not exist", folder.string(), what);
  REPHOTO_CHECK(fs::is_directory(status), "{}: {} folder is not a folder", folder.string(), what);
  std::vector<ImageFile> images;
  fs::directory_iterator it(folder, ec);
  REPHOTO_CHECK(!ec, "{}: cannot list {} folder: {}", folder.string(), what, ec.message());
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    REPHOTO_CHECK(!ec, "{}: cannot list {} folder: {}", folder.string(), what, ec.message());
    const fs::path& path = it->path();
    const std::string filename = path.filename().string();
    if (filename.empty() || filename[0] == '.' || !io::IsImageFile(path)) continue;
    // Depth maps that `rephoto render` writes next to its rephotos are not images to compare.
    if (filename.size() > 10 && filename.ends_with(".depth.exr")) continue;
    std::error_code file_ec;
    if (!it->is_regular_file(file_ec)) continue;
    images.push_back({path.stem().string(), path});
  }
  std::sort(images.begin(), images.end(), [](const ImageFile& a, const ImageFile& b) {
    return a.stem != b.stem ? a.stem < b.stem : a.path < b.path;
  });
  for (size_t i = 1; i < images.size(); ++i) {
    REPHOTO_CHECK(images[i].stem != images[i - 1].stem, "{}: two {} share the name '{}': {} and {}",
                  folder.string(), what, images[i].stem, images[i - 1].path.filename().string(),
                  images[i].path.filename().string());
  }
  return images;
}

std::map<std::string, fs::path> ImagesByStem(const std::vector<ImageFile>& images) {
  std::map<std::string, fs::path> by_stem;
  for (const ImageFile& image : images) by_stem.emplace(image.stem, image.path);
  return by_stem;
}

Pairing PairByStem(std::vector<ImageFile> photos, std::vector<ImageFile> renders) {
  auto by_stem = [](const ImageFile& a, const ImageFile& b) { return a.stem < b.stem; };
  std::sort(photos.begin(), photos.end(), by_stem);
  std::sort(renders.begin(), renders.end(), by_stem);
  Pairing pairing;
  size_t p = 0, r = 0;
  while (p < photos.size() || r < renders.size()) {
    if (r == renders.size() || (p < photos.size() && photos[p].stem < renders[r].stem)) {
      pairing.missing.push_back({photos[p].stem, Missing::kRender, photos[p].path});
      ++p;
    } else if (p == photos.size() || renders[r].stem < photos[p].stem) {
      pairing.missing.push_back({renders[r].stem, Missing::kPhoto, renders[r].path});
      ++r;
    } else {
      pairing.pairs.push_back({photos[p].stem, photos[p].path, renders[r].path});
      ++p;
      ++r;
    }
  }
  return pairing;
}

}  // namespace rephoto::compare
