#include "rephoto/eval/prepare_fold.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "rephoto/compare/resample.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/keys.h"
#include "rephoto/io/image_io.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/scene/transforms_json.h"
#include "rephoto/split/random.h"
#include "rephoto/split/split_writer.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

namespace {

// The name of each view's downscaled training photo: "dir/a.jpg" -> "dir/a.png", or, when two
// views of the scene would share one ("a.jpg" and "a.png"), "a.jpg.png" for every view.
std::map<std::string, std::string> PngNames(const scene::Scene& scene) {
  std::map<std::string, std::string> png_names;
  std::set<std::string> seen;
  bool distinct = true;
  for (const scene::View& view : scene.views) {
    const std::string png = fs::path(view.name).replace_extension(".png").generic_string();
    distinct &= seen.insert(png).second;
    png_names[view.name] = png;
  }
  if (!distinct) {
    for (const scene::View& view : scene.views) png_names[view.name] = view.name + ".png";
  }
  return png_names;
}

std::string JoinLines(const std::vector<std::string>& names) {
  std::string text;
  for (const std::string& name : names) text += name + "\n";
  return text;
}

// Makes `dir` hold exactly `files` (relative name -> source file), each a hard link to its
// source (a symbolic link when hard links are impossible, e.g. across file systems); other
// files in `dir` are removed. Existing links to the right file are kept.
void SyncLinkedFolder(const fs::path& dir, const std::map<std::string, fs::path>& files) {
  std::set<fs::path> expected;
  std::error_code ec;
  for (const auto& [name, source] : files) {
    // Names passed the scene boundary's rule; checked again because this removes files.
    REPHOTO_CHECK(scene::CheckedImageName(name, dir.string()) == name,
                  "{}: image name '{}' is not in normal form", dir.string(), name);
    const fs::path target = (dir / name).lexically_normal();
    expected.insert(target);
    if (fs::exists(target, ec) && fs::equivalent(target, source, ec)) continue;
    fs::create_directories(target.parent_path(), ec);
    fs::remove(target, ec);
    ec.clear();
    fs::create_hard_link(source, target, ec);
    if (ec) {
      ec.clear();
      fs::create_symlink(fs::absolute(source).lexically_normal(), target, ec);
    }
    if (ec) {
      ec.clear();
      fs::copy_file(source, target, fs::copy_options::overwrite_existing, ec);
    }
    REPHOTO_CHECK(!ec, "{}: cannot link or copy {} there: {}", dir.string(), source.string(),
                  ec.message());
  }
  std::vector<fs::path> stale;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_directory() && !expected.count(it->path().lexically_normal())) {
      stale.push_back(it->path());
    }
  }
  for (const fs::path& path : stale) fs::remove(path, ec);
}

void WriteFoldScene(const scene::Scene& part, const fs::path& dir, const std::string& list_name,
                    const std::vector<std::string>& names) {
  scene::WriteColmap(part, dir / "sparse", scene::ColmapFormat::kText);
  try {
    scene::WriteTransformsJson(part, dir / "transforms.json");
  } catch (const Error& e) {
    LogWarning(fmt::format("{}: not written: {}", (dir / "transforms.json").string(), e.what()));
  }
  WriteTextFileAtomically(dir / list_name, JoinLines(names));
}

// The fold's training views: all, or a seeded subset of train_count.
std::vector<std::string> TrainingViews(const RunContext& s, const FoldPlan& fold,
                                       const split::Fold& sf) {
  std::vector<std::string> names = sf.train;
  if (s.options.train_count > 0 && static_cast<size_t>(s.options.train_count) < names.size()) {
    split::SeededShuffle(names, s.options.train_seed + fold.index);
    names.resize(static_cast<size_t>(s.options.train_count));
    std::sort(names.begin(), names.end());
  } else if (s.options.train_count > 0 && !s.worker) {
    LogWarning(fmt::format("{}: --train-count {} >= the fold's {} training views: using all",
                           fold.name, s.options.train_count, names.size()));
  }
  return names;
}

// Downscaled photos as PNG in the fold's images/ folder (hard links to one shared cache, so a
// photo is decoded and filtered once for all folds); cameras and observations scaled with them.
void DownscaleTrainingPhotos(const RunContext& s, Tally& tally, FoldPlan& fold,
                             scene::Scene& train) {
  fold.images_dir = fold.train_dir / "images";
  const fs::path cache_dir = s.CacheDir() / fmt::format("train_photos_s{}", s.options.train_short_side);
  std::map<int, std::pair<int, int>> new_sizes;
  for (const auto& [id, camera] : train.cameras) {
    new_sizes[id] = rephoto::camera::ScaledSize(camera.width, camera.height, s.options.train_short_side);
  }
  std::map<std::string, fs::path> links;
  const std::map<std::string, std::string> png_names = PngNames(s.scene);
  Image photo;
  for (scene::View& view : train.views) {
    const camera::Camera& camera = train.CameraOf(view);
    const auto [w, h] = new_sizes.at(view.camera_id);
    if (w == camera.width && h == camera.height) {
      // Already at most that size: the pipeline gets the original file, not a re-encoding.
      links[view.name] = view.image_path;
      view.image_path = fold.images_dir / view.name;
      continue;
    }
    const std::string png_name = png_names.at(view.name);
    const fs::path cached = cache_dir / png_name;
    const fs::path cached_key = cache_dir / (png_name + ".key");
    const std::string key = Hasher().Add(s.hashes->Hash(view.image_path)).AddInt(w).AddInt(h).Hex();
    std::error_code ec;
    if (!s.worker && !(fs::is_regular_file(cached, ec) && fs::is_regular_file(cached_key, ec) &&
                       ReadFileToString(cached_key) == key)) {
      fs::remove(cached_key, ec);
      io::ReadImage(view.image_path, &photo);
      REPHOTO_CHECK(photo.width() == camera.width && photo.height() == camera.height,
                    "{}: photo is {}x{} but its camera is {}x{}", view.image_path.string(),
                    photo.width(), photo.height(), camera.width, camera.height);
      Image scaled;
      compare::ResizeImage(photo, w, h, &scaled);
      io::WritePng(cached, scaled, io::PngDepth::k8, io::PngCompression::kNone);
      WriteTextFileAtomically(cached_key, key);
      tally.Count(&EvaluateCounters::photos_downscaled);
    }
    links[png_name] = cached;
    view.name = png_name;
    view.image_path = fold.images_dir / png_name;
  }
  if (!s.worker) SyncLinkedFolder(fold.images_dir, links);
  for (auto& [id, camera] : train.cameras) {
    const auto [w, h] = new_sizes.at(id);
    const double sx = static_cast<double>(w) / camera.width;
    const double sy = static_cast<double>(h) / camera.height;
    for (scene::Point3D& point : train.points) {
      for (scene::Observation& obs : point.track) {
        if (train.views[obs.view_index].camera_id == id) {
          obs.pixel = Eigen::Vector2d(obs.pixel.x() * sx, obs.pixel.y() * sy);
        }
      }
    }
    camera = camera.Scaled(w, h);
  }
  train.image_root = fold.images_dir;
}

// The fold's test views at the evaluation resolution, their scene folder and test key.
void PrepareTestViews(const RunContext& s, FoldPlan& fold, const split::Fold& sf,
                      const fs::path& split_dir) {
  scene::Scene test = split::SubsetScene(s.scene, sf.test, /*keep_points=*/false);
  bool scaled_test = false;
  for (auto& [id, camera] : test.cameras) {
    const auto [w, h] =
        rephoto::camera::ScaledSize(camera.width, camera.height, s.options.eval_short_side);
    if (w != camera.width || h != camera.height) {
      camera = camera.Scaled(w, h);
      scaled_test = true;
    }
  }
  if (scaled_test) {
    fold.test_dir = fold.dir / "test";
    fold.test_list = fold.test_dir / "test.txt";
    if (!s.worker) WriteFoldScene(test, fold.test_dir, "test.txt", sf.test);
  } else {
    fold.test_dir = split_dir / "test";
    fold.test_list = split_dir / "test.txt";
  }
  Hasher test_key;
  test_key.Add(kKeyVersion).Add("test");
  for (const scene::View& view : test.views) {
    TestView t;
    t.name = view.name;
    t.stem = s.stems.at(view.name);
    t.view_index = s.view_index.at(view.name);
    t.camera = test.CameraOf(view);
    t.pose = view.cam_from_world;
    t.photo = fs::absolute(view.image_path).lexically_normal();
    t.photo_hash = s.hashes->Hash(t.photo);
    if (!s.options.photo_masks.empty()) {
      t.mask = FindImageByStem(s.options.photo_masks, t.stem);
      REPHOTO_CHECK(!t.mask.empty(), "{}: no mask named '{}' for photo {}",
                    s.options.photo_masks.string(), t.stem, t.photo.string());
    } else if (view.mask_path) {
      t.mask = *view.mask_path;
    }
    if (!t.mask.empty()) t.mask_hash = s.hashes->Hash(t.mask);
    test_key.Add(t.name).Add(t.stem);
    AddCamera(test_key, t.camera);
    AddPose(test_key, t.pose);
    fold.tests.push_back(std::move(t));
  }
  fold.test_key = test_key.Hex();
}

}  // namespace

FoldPlan PrepareFold(const RunContext& s, size_t index, Tally& tally) {
  FoldPlan fold;
  fold.index = index;
  fold.name = split::FoldFolderName(index, s.split.folds.size());
  const split::Fold& sf = s.split.folds[fold.index];
  const fs::path split_dir = s.run / "split" / fold.name;
  fold.dir = s.run / "folds" / fold.name;
  fold.out_dir = fold.dir / "reconstruction";
  fold.log_file = s.run / "logs" / fmt::format("{}.{}.log", fold.name, s.CommandKind());
  fold.derived_model = s.options.texture && !HasDefects(s.options.degrade)
                           ? fold.dir / "textured" / "model.obj"
                           : fold.dir / "model.ply";
  fold.previous = run::ReadJsonRecord(fold.dir / "fold.json");
  fold.train_names = TrainingViews(s, fold, sf);

  scene::Scene train = split::SubsetScene(s.scene, fold.train_names, /*keep_points=*/true);
  Hasher photos;
  for (const std::string& name : fold.train_names) {
    photos.Add(name).Add(s.hashes->Hash(s.scene.views[s.view_index.at(name)].image_path));
  }
  // Commands see a folder with only the fold's training photos (links), so that a pipeline
  // that takes every image of {images} cannot see a test photo.
  const bool commands = s.source != ModelSource::kModel;
  const bool own_train = s.options.train_count > 0 || s.options.train_short_side > 0;  // else the split's
  fold.images_dir = s.scene.image_root;
  if (commands && s.options.train_short_side == 0) {
    fold.images_dir = fold.dir / "train" / "images";
    std::map<std::string, fs::path> links;
    for (scene::View& view : train.views) {
      links[view.name] = view.image_path;
      view.image_path = fold.images_dir / view.name;
    }
    if (!s.worker) SyncLinkedFolder(fold.images_dir, links);
    train.image_root = fold.images_dir;
  }
  if (!own_train) {
    fold.train_dir = split_dir / "train";
    fold.train_list = split_dir / "train.txt";
  } else {
    fold.train_dir = fold.dir / "train";
    fold.train_list = fold.train_dir / "train.txt";
    if (s.options.train_short_side > 0) DownscaleTrainingPhotos(s, tally, fold, train);
    std::vector<std::string> listed;
    for (const scene::View& view : train.views) listed.push_back(view.name);
    if (!s.worker) WriteFoldScene(train, fold.train_dir, "train.txt", listed);
  }
  fold.train_key = Hasher().Add(TrainKey(train, s.options.train_short_side)).Add(photos.Hex()).Hex();
  PrepareTestViews(s, fold, sf, split_dir);
  return fold;
}

scene::Scene TrainingScene(const RunContext& s, const FoldPlan& fold) {
  if (s.options.train_short_side > 0) {
    scene::ReadSceneOptions read;
    read.format = scene::SceneFormat::kColmap;
    read.image_root = fold.images_dir;
    return scene::ReadScene(fold.train_dir / "sparse", read);
  }
  return split::SubsetScene(s.scene, fold.train_names, /*keep_points=*/true);
}

void RemoveStaleOutputs(const RunContext& s, const std::vector<FoldPlan>& plans) {
  std::set<std::string> fold_names;
  for (const FoldPlan& fold : plans) fold_names.insert(fold.name);
  std::error_code ec;
  for (const fs::path& parent : {s.run / "folds", s.run / "split"}) {
    std::vector<fs::path> stale;
    for (fs::directory_iterator it(parent, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (it->is_directory() && name.rfind("fold_", 0) == 0 && !fold_names.count(name)) {
        stale.push_back(it->path());
      }
    }
    for (const fs::path& path : stale) fs::remove_all(path, ec);
  }
  std::vector<fs::path> stale_logs;
  for (fs::directory_iterator it(s.run / "logs", ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!fold_names.count(name.substr(0, name.find('.')))) stale_logs.push_back(it->path());
  }
  for (const fs::path& path : stale_logs) fs::remove(path, ec);
  for (const FoldPlan& fold : plans) {
    std::set<fs::path> allowed;
    for (const TestView& test : fold.tests) {
      allowed.insert(fold.dir / "views" / (test.stem + ".json"));
      allowed.insert(fold.dir / "renders" / (test.stem + ".png"));
      allowed.insert(fold.dir / "renders" / (test.stem + ".depth.exr"));
      for (metrics::Metric metric : metrics::AllMetrics()) {
        const std::string base = test.stem + "." + std::string(metrics::MetricName(metric));
        allowed.insert(fold.dir / "errors" / (base + ".exr"));
        allowed.insert(fold.dir / "errors" / (base + ".png"));
      }
    }
    for (const char* folder : {"views", "renders", "errors"}) {
      std::vector<fs::path> stale;
      for (fs::recursive_directory_iterator it(fold.dir / folder, ec), end; !ec && it != end;
           it.increment(ec)) {
        if (it->is_regular_file() && !allowed.count(it->path().lexically_normal())) {
          stale.push_back(it->path());
        }
      }
      for (const fs::path& path : stale) fs::remove(path, ec);
    }
  }
}

}  // namespace rephoto::eval
