#include "rephoto/service/dataset.h"

#include <fmt/format.h>
#include <openssl/rand.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "rephoto/service/api.h"
#include "rephoto/service/archive.h"
#include "rephoto/compare/pairing.h"
#include "rephoto/compare/resample.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/io/image_io.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/scene/transforms_json.h"
#include "rephoto/split/split.h"
#include "rephoto/split/split_writer.h"

namespace rephoto::service {
namespace fs = std::filesystem;
namespace {

// Removes a staging folder on scope exit unless released.
struct StagingFolder {
  explicit StagingFolder(fs::path path) : path(std::move(path)) {
    fs::remove_all(this->path);
    fs::create_directories(this->path);
  }
  ~StagingFolder() {
    std::error_code ignored;
    if (!path.empty()) fs::remove_all(path, ignored);
  }
  fs::path path;
};

// Writes `scene`'s cameras as COLMAP text and transforms.json into `folder`, with every view's
// image path re-rooted at folder/images so that transforms.json says "images/<name>".
// Returns false when transforms.json cannot hold the intrinsics (then it is left out).
bool WriteCameras(scene::Scene scene, const fs::path& folder) {
  for (scene::View& view : scene.views) view.image_path = folder / "images" / view.name;
  scene::WriteColmap(scene, folder / "sparse", scene::ColmapFormat::kText);
  try {
    scene::WriteTransformsJson(scene, folder / "transforms.json");
    return true;
  } catch (const Error& error) {
    LogWarning(fmt::format("transforms.json left out: {}", error.what()));
    return false;
  }
}

std::vector<TarMember> CameraMembers(const fs::path& folder, bool with_transforms) {
  std::vector<TarMember> members;
  for (const char* file : {"cameras.txt", "images.txt", "points3D.txt"}) {
    members.push_back({std::string("sparse/") + file, folder / "sparse" / file});
  }
  if (with_transforms) members.push_back({"transforms.json", folder / "transforms.json"});
  return members;
}

// Every regular file below `source` (or `source` itself) as shortcuts/<base>/<relative path>.
void AddShortcutMembers(const fs::path& source, std::vector<TarMember>* members) {
  const std::string base = source.filename().string();
  REPHOTO_CHECK_USAGE(fs::exists(source), "--shortcut {}: no such file or folder", source.string());
  if (fs::is_regular_file(source)) {
    members->push_back({"shortcuts/" + base, source});
    return;
  }
  std::vector<fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(source)) {
    if (entry.is_regular_file()) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  for (const fs::path& file : files) {
    members->push_back(
        {"shortcuts/" + base + "/" + fs::relative(file, source).generic_string(), file});
  }
}

PublishedFile Publish(const fs::path& root, const fs::path& path, const std::string& name) {
  return {name, fs::relative(path, root).generic_string(), "application/x-tar",
          static_cast<int64_t>(fs::file_size(path))};
}

nlohmann::json ImageList(const scene::Scene& scene, const std::vector<std::string>* stems) {
  nlohmann::json list = nlohmann::json::array();
  for (size_t i = 0; i < scene.views.size(); ++i) {
    const camera::Camera& camera = scene.cameras.at(scene.views[i].camera_id);
    nlohmann::json item = {
        {"name", scene.views[i].name}, {"width", camera.width}, {"height", camera.height}};
    if (stems) item["stem"] = (*stems)[i];
    list.push_back(item);
  }
  return list;
}

scene::Scene ScaledScene(scene::Scene scene, int short_side) {
  for (auto& [id, camera] : scene.cameras) {
    const auto [w, h] = rephoto::camera::ScaledSize(camera.width, camera.height, short_side);
    if (w != camera.width || h != camera.height) camera = camera.Scaled(w, h);
  }
  return scene;
}

// The mask file of each test view (empty paths when the dataset has no masks).
std::vector<fs::path> TestMasks(const scene::Scene& test, const std::vector<std::string>& stems,
                                const fs::path& folder) {
  std::map<std::string, fs::path> by_stem;
  if (!folder.empty()) by_stem = compare::ImagesByStem(compare::ListImages(folder, "photo masks"));
  std::vector<fs::path> masks;
  size_t found = 0;
  for (size_t i = 0; i < test.views.size(); ++i) {
    fs::path mask;
    if (!folder.empty()) {
      const auto it = by_stem.find(stems[i]);
      if (it != by_stem.end()) mask = it->second;
    } else if (test.views[i].mask_path) {
      mask = *test.views[i].mask_path;
    }
    found += mask.empty() ? 0 : 1;
    masks.push_back(mask);
  }
  REPHOTO_CHECK(found == 0 || found == masks.size(),
                "{}: {} of {} test photos have a mask: give every test photo a mask or none",
                folder.empty() ? "the scene's mask paths" : folder.string(), found, masks.size());
  if (found == 0) masks.clear();
  return masks;
}

// secret/<name>/photos (and masks/): copies, or downscaled 16-bit PNGs for eval_short_side.
void WriteSecretPhotos(const scene::Scene& original, const scene::Scene& scaled,
                       const std::vector<std::string>& stems, const DatasetOptions& options,
                       const fs::path& folder) {
  fs::create_directories(folder / "photos");
  const std::vector<fs::path> masks = TestMasks(original, stems, options.photo_masks);
  if (!masks.empty()) fs::create_directories(folder / "masks");
  for (size_t i = 0; i < original.views.size(); ++i) {
    const camera::Camera& from = original.cameras.at(original.views[i].camera_id);
    const camera::Camera& to = scaled.cameras.at(scaled.views[i].camera_id);
    const fs::path& photo = original.views[i].image_path;
    const bool resize = from.width != to.width || from.height != to.height;
    if (!resize) {
      fs::copy_file(photo, folder / "photos" / (stems[i] + photo.extension().string()));
    } else {
      Image image, small;
      io::ReadImage(photo, &image);
      compare::ResizeImage(image, to.width, to.height, &small);
      io::WritePng(folder / "photos" / (stems[i] + ".png"), small, io::PngDepth::k16);
    }
    if (masks.empty()) continue;
    Mask mask = io::ReadMask(masks[i]);
    REPHOTO_CHECK(mask.width() == from.width && mask.height() == from.height,
                  "{}: the mask is {}x{}, its photo {}x{}", masks[i].string(), mask.width(),
                  mask.height(), from.width, from.height);
    if (resize) {
      Mask small;
      compare::ResizeMask(mask, to.width, to.height, &small);
      mask = std::move(small);
    }
    io::WritePng(folder / "masks" / (stems[i] + ".png"), mask);
  }
}

nlohmann::json Settings(const DatasetOptions& options) {
  nlohmann::json metric_names = nlohmann::json::array();
  for (metrics::Metric metric : options.metrics)
    metric_names.push_back(metrics::MetricName(metric));
  const auto headline = metrics::ParseMetric(options.headline);
  REPHOTO_CHECK_USAGE(
      headline && std::count(options.metrics.begin(), options.metrics.end(), *headline) == 1,
      "--headline '{}': not one of the dataset's metrics", options.headline);
  REPHOTO_CHECK_USAGE(options.eval_short_side >= 0, "--eval-short-side {}: must be >= 0",
                      options.eval_short_side);
  REPHOTO_CHECK_USAGE(options.public_fraction > 0 && options.public_fraction <= 1,
                      "--public-fraction {}: must be in (0, 1]", options.public_fraction);
  REPHOTO_CHECK_USAGE(options.window >= 3 && options.window <= 101 && options.window % 2 == 1,
                      "--window {}: must be odd, 3..101", options.window);
  return {{"metrics", metric_names},
          {"headline", options.headline},
          {"higher_is_better", metrics::HigherIsBetter(*headline)},
          {"window", options.window},
          {"eval_short_side", options.eval_short_side},
          {"ranking", ParseRankingRule(options.ranking).text}};
}

// A random `fraction` of the test stems (at least one, and at least one left private when
// fraction < 1): the public test photos. Random from OpenSSL, so nobody can tell which they are.
nlohmann::json PublicStems(std::vector<std::string> stems, double fraction) {
  const size_t count = std::clamp<size_t>(
      static_cast<size_t>(std::llround(fraction * static_cast<double>(stems.size()))), 1,
      stems.size() - 1);
  for (size_t i = stems.size() - 1; i > 0; --i) {  // Fisher-Yates
    uint64_t random = 0;
    REPHOTO_CHECK(RAND_bytes(reinterpret_cast<unsigned char*>(&random), sizeof(random)) == 1,
                  "OpenSSL RAND_bytes failed");
    std::swap(stems[i], stems[random % (i + 1)]);
  }
  stems.resize(count);
  std::sort(stems.begin(), stems.end());
  return stems;
}

}  // namespace

void CheckDatasetName(const std::string& name) {
  const bool valid =
      !name.empty() && name.size() <= 64 && name[0] != '.' &&
      std::all_of(name.begin(), name.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
      });
  REPHOTO_CHECK_USAGE(valid, "dataset name '{}': use 1 to 64 of A-Z a-z 0-9 _ - . (not first)",
                      name);
}

void RevealDataset(Store& store, const std::string& name) {
  std::optional<DatasetRecord> dataset = store.FindDataset(name);
  REPHOTO_CHECK(dataset, "no dataset named '{}'", name);
  dataset->info["revealed"] = true;
  store.SetDatasetInfo(name, dataset->info);
}

fs::path SecretPhotoFolder(const fs::path& root, const std::string& name) {
  return root / "secret" / name / "photos";
}

fs::path SecretMaskFolder(const fs::path& root, const std::string& name) {
  return root / "secret" / name / "masks";
}

int64_t AddDataset(Store& store, const DatasetOptions& options) {
  CheckDatasetName(options.name);
  nlohmann::json settings = Settings(options);
  REPHOTO_CHECK_USAGE(!store.FindDataset(options.name), "dataset '{}' exists already",
                      options.name);
  const fs::path& root = store.root();
  const fs::path public_folder = root / "public" / options.name;
  const fs::path secret_folder = root / "secret" / options.name;
  REPHOTO_CHECK(!fs::exists(public_folder) && !fs::exists(secret_folder),
                "{} or {} exists without a database record: remove it first",
                public_folder.string(), secret_folder.string());

  const scene::Scene scene = scene::ReadScene(options.scene, options.read_options);
  std::vector<std::string> names;
  for (const scene::View& view : scene.views) names.push_back(view.name);
  const split::Split split = split::MakeSplit(names, split::ParseScheme(options.scheme));
  REPHOTO_CHECK_USAGE(split.folds.size() == 1 && split.cross_validated,
                      "--scheme {}: a benchmark needs one fold with separate test photos "
                      "(every:N, fraction:F, lists:TRAIN,TEST)",
                      options.scheme);
  const scene::Scene train = split::SubsetScene(scene, split.folds[0].train, true);
  const scene::Scene original_test = split::SubsetScene(scene, split.folds[0].test, false);
  const scene::Scene test = ScaledScene(original_test, options.eval_short_side);
  const std::vector<std::string> stems = scene::OutputStems(test);
  for (const std::string& stem : stems) {
    REPHOTO_CHECK(stem.find('/') == std::string::npos,
                  "{}: test image stem '{}' needs a subfolder; renders are uploaded flat",
                  options.scene.string(), stem);
  }
  for (const scene::Scene* part : {&train, &test}) {
    for (const std::string& missing : scene::MissingImages(*part)) {
      ThrowError("{}: photo '{}' is missing on disk", options.scene.string(), missing);
    }
  }

  // Stage everything in hidden folders; rename into place, then record in the database.
  const std::string suffix = fmt::format(".staging-{}-{}", options.name, getpid());
  StagingFolder public_stage(root / "public" / suffix);
  StagingFolder secret_stage(root / "secret" / suffix);
  StagingFolder cameras_stage(root / (suffix + "-cameras"));
  const bool train_json = WriteCameras(train, cameras_stage.path / "train");
  const bool test_json = WriteCameras(test, cameras_stage.path / "test");

  std::vector<TarMember> training = CameraMembers(cameras_stage.path / "train", train_json);
  for (const scene::View& view : train.views) {
    training.push_back({"images/" + view.name, view.image_path});
  }
  WriteTar(public_stage.path / "training.tar", training);

  std::string stem_list;
  for (const std::string& stem : stems) stem_list += stem + "\n";
  WriteTextFileAtomically(cameras_stage.path / "test" / "test_images.txt", stem_list);
  std::vector<TarMember> test_cameras = CameraMembers(cameras_stage.path / "test", test_json);
  test_cameras.push_back({"test_images.txt", cameras_stage.path / "test" / "test_images.txt"});
  WriteTar(public_stage.path / "test-cameras.tar", test_cameras);

  std::vector<TarMember> shortcuts;
  for (const fs::path& shortcut : options.shortcuts) AddShortcutMembers(shortcut, &shortcuts);
  if (!shortcuts.empty()) WriteTar(public_stage.path / "shortcuts.tar", shortcuts);

  WriteSecretPhotos(original_test, test, stems, options, secret_stage.path);
  settings["masks"] = fs::exists(secret_stage.path / "masks");

  fs::rename(public_stage.path, public_folder);
  public_stage.path.clear();
  fs::rename(secret_stage.path, secret_folder);
  secret_stage.path.clear();
  std::vector<PublishedFile> files = {
      Publish(root, public_folder / "training.tar", "training.tar"),
      Publish(root, public_folder / "test-cameras.tar", "test-cameras.tar")};
  if (!shortcuts.empty()) {
    files.push_back(Publish(root, public_folder / "shortcuts.tar", "shortcuts.tar"));
  }
  nlohmann::json shortcut_names = nlohmann::json::array();
  for (const TarMember& member : shortcuts) shortcut_names.push_back(member.name);
  // A lists: scheme names host files; publish only its kind.
  const std::string scheme_text = split.scheme.kind == split::SchemeKind::kLists
                                      ? std::string("lists")
                                      : split.scheme.ToString();
  if (options.public_fraction < 1) {
    REPHOTO_CHECK_USAGE(stems.size() >= 2,
                        "--public-fraction {}: a split needs at least 2 test photos, the scheme "
                        "gives {}",
                        options.public_fraction, stems.size());
    settings["public_stems"] = PublicStems(stems, options.public_fraction);
  }
  const nlohmann::json info = {{"scheme", scheme_text},
                               {"settings", settings},
                               {"training_images", ImageList(train, nullptr)},
                               {"test_images", ImageList(test, &stems)},
                               {"shortcuts", shortcut_names}};
  return store.AddDataset(options.name, options.description, info, files);
}

}  // namespace rephoto::service
