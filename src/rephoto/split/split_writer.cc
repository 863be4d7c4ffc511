#include "rephoto/split/split_writer.h"

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>
#include <unordered_map>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/scene/transforms_json.h"

namespace rephoto::split {

namespace fs = std::filesystem;

scene::Scene SubsetScene(const scene::Scene& scene, const std::vector<std::string>& names,
                         bool keep_points) {
  std::unordered_map<std::string, int> index_of_name;
  for (size_t i = 0; i < scene.views.size(); ++i) {
    index_of_name.emplace(scene.views[i].name, static_cast<int>(i));
  }
  std::vector<bool> selected(scene.views.size(), false);
  for (const std::string& name : names) {
    const auto it = index_of_name.find(name);
    REPHOTO_CHECK(it != index_of_name.end(), "split: image '{}' is not a view of the scene", name);
    selected[it->second] = true;
  }
  scene::Scene subset;
  subset.image_root = scene.image_root;
  std::vector<int> new_index(scene.views.size(), -1);
  for (size_t i = 0; i < scene.views.size(); ++i) {
    if (!selected[i]) continue;
    new_index[i] = static_cast<int>(subset.views.size());
    subset.views.push_back(scene.views[i]);
    subset.cameras.emplace(scene.views[i].camera_id, scene.CameraOf(scene.views[i]));
  }
  if (!keep_points) return subset;
  for (const scene::Point3D& point : scene.points) {
    scene::Point3D kept;
    kept.position = point.position;
    kept.color = point.color;
    for (const scene::Observation& observation : point.track) {
      const int index = new_index.at(observation.view_index);
      if (index >= 0) kept.track.push_back({index, observation.pixel});
    }
    if (kept.track.size() >= 2) subset.points.push_back(std::move(kept));
  }
  return subset;
}

std::string FoldFolderName(size_t index, size_t count) {
  const size_t digits = std::max<size_t>(2, std::to_string(count > 0 ? count - 1 : 0).size());
  return fmt::format("fold_{:0{}}", index, digits);
}

fs::path SplitTestList(const fs::path& dir) {
  std::error_code ec;
  REPHOTO_CHECK(fs::is_directory(dir, ec), "{}: split folder does not exist", dir.string());
  if (fs::is_regular_file(dir / "test.txt", ec)) return dir / "test.txt";
  std::vector<std::string> folds;  // fold folders holding a test list
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.starts_with("fold_") && fs::is_regular_file(it->path() / "test.txt", ec)) {
      folds.push_back(name);
    }
  }
  REPHOTO_CHECK(!ec, "{}: cannot list the split folder: {}", dir.string(), ec.message());
  std::sort(folds.begin(), folds.end());
  REPHOTO_CHECK(!folds.empty(),
                "{}: not a split folder (no test.txt, no fold_XX/test.txt: see `rephoto split`)",
                dir.string());
  REPHOTO_CHECK(
      folds.size() == 1, "{}: the split has {} folds ({} ... {}); name the fold's folder, e.g. {}",
      dir.string(), folds.size(), folds.front(), folds.back(), (dir / folds.front()).string());
  return dir / folds.front() / "test.txt";
}

namespace {

std::string JoinLines(const std::vector<std::string>& names) {
  std::string text;
  for (const std::string& name : names) text += name + "\n";
  return text;
}

// Writes the COLMAP text model and transforms.json of `part` into `folder`; returns whether
// transforms.json could be written.
bool WritePart(const scene::Scene& part, const fs::path& folder) {
  scene::WriteColmap(part, folder / "sparse", scene::ColmapFormat::kText);
  try {
    scene::WriteTransformsJson(part, folder / "transforms.json");
  } catch (const Error& e) {
    LogWarning(fmt::format("{}: not written: {}", (folder / "transforms.json").string(), e.what()));
    return false;
  }
  return true;
}

}  // namespace

std::vector<fs::path> WriteSplit(const scene::Scene& scene, const Split& split,
                                 const SplitSource& source, const fs::path& out_dir) {
  nlohmann::json json;
  json["schema"] = "rephoto.split/1";
  json["source"] = source.path;
  json["format"] = source.format;
  json["image_root"] = fs::absolute(scene.image_root).lexically_normal().string();
  json["scheme"] = split.scheme.ToString();
  json["scheme_name"] = std::string(split.scheme.Name());
  json["seed"] =
      split.scheme.Seeded() ? nlohmann::json(split.scheme.seed) : nlohmann::json(nullptr);
  json["cross_validated"] = split.cross_validated;
  json["num_images"] = scene.views.size();
  json["num_folds"] = split.folds.size();
  json["folds"] = nlohmann::json::array();

  std::vector<fs::path> folders;
  bool transforms_written = true;
  Progress progress("split", split.folds.size());
  for (size_t f = 0; f < split.folds.size(); ++f) {
    const Fold& fold = split.folds[f];
    const std::string name = FoldFolderName(f, split.folds.size());
    const fs::path folder = out_dir / name;
    WriteTextFileAtomically(folder / "train.txt", JoinLines(fold.train));
    WriteTextFileAtomically(folder / "test.txt", JoinLines(fold.test));
    const scene::Scene train = SubsetScene(scene, fold.train, /*keep_points=*/true);
    const scene::Scene test = SubsetScene(scene, fold.test, /*keep_points=*/false);
    transforms_written &= WritePart(train, folder / "train");
    transforms_written &= WritePart(test, folder / "test");
    json["folds"].push_back({{"index", f},
                             {"folder", name},
                             {"train", fold.train},
                             {"test", fold.test},
                             {"train_points", train.points.size()}});
    folders.push_back(folder);
    progress.Advance(name);
  }
  json["transforms_json"] = transforms_written;
  WriteTextFileAtomically(out_dir / "split.json", json.dump(2) + "\n");
  return folders;
}

}  // namespace rephoto::split
