#include "rephoto/live/colmap_registrar.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>

#include "rephoto/camera/camera.h"
#include "rephoto/cluster/subprocess.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/core/sqlite.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/scene/reader_util.h"

namespace rephoto::live {
namespace fs = std::filesystem;

namespace {

class ColmapRegistrar : public Registrar {
 public:
  explicit ColmapRegistrar(const ColmapRegistrarOptions& o) : o_(o) {
    REPHOTO_CHECK_USAGE(o.bootstrap >= 2 && o.bundle_every >= 0 && o.timeout_seconds > 0 &&
                            o.min_inliers >= 4 && o.min_inlier_ratio >= 0 &&
                            o.min_inlier_ratio <= 1 && o.init_min_inliers >= 4,
                        "--colmap: invalid registration settings");
    setenv("QT_QPA_PLATFORM", "offscreen", 1);
    // The workspace is made at the first photo (the run folder is opened, and locked, first).
    std::error_code ec;
    for (fs::directory_iterator it(o_.workspace / "images", ec), end; !ec && it != end;
         it.increment(ec))
      ++added_;
  }

  Result Register(const fs::path& photo) override {
    const std::string name = photo.filename().string();
    bool matched_all = true;  // every pair of the new photo is matched (else MatchNew's choice)
    std::string error;
    const fs::path image = o_.workspace / "images" / name;
    Result r;
    fs::create_directories(o_.workspace / "images");
    fs::create_directories(o_.workspace / "sparse" / "0");
    // The model as it is before this photo, read once: nothing below changes it before
    // image_registrator or the mapper runs.
    const std::vector<Placed> before = AllPlaced();
    if (!fs::exists(image)) {
      LinkOrCopyFileAtomically(photo, image);
      ++added_;
      const fs::path list = o_.workspace / "new_image.txt";
      WriteTextFileAtomically(list, name + "\n");
      std::vector<std::string> extract = {
          "feature_extractor", "--database_path", Db(), "--image_path", Images(),
          "--image_list_path", list.string(), "--ImageReader.single_camera", "1",
          "--ImageReader.camera_model", o_.camera_model, "--SiftExtraction.use_gpu", "0",
          "--SiftExtraction.max_image_size", std::to_string(o_.max_image_size)};
      if (!o_.camera_params.empty())
        extract.insert(extract.end(), {"--ImageReader.camera_params", CameraParams()});
      if (!Run(extract, &error)) {
        r.message = error;
        return r;
      }
      ShareCamera(name);
      if (!MatchNew(name, before, &matched_all, &error)) {
        r.message = error;
        return r;
      }
    }
    if (!HasModel() && !matched_all && !MatchAll(&matched_all, &error)) {
      r.message = error;
      return r;
    }
    if (!HasModel()) {
      if (added_ < o_.bootstrap) {
        r.status = Result::kDeferred;
        return r;
      }
      const fs::path tmp = o_.workspace / "mapper";
      fs::remove_all(tmp);
      fs::create_directories(tmp);
      if (!Run(WithThresholds({"mapper", "--database_path", Db(), "--image_path", Images(),
                               "--output_path", tmp.string(), "--Mapper.num_threads", "2"}),
               &error)) {
        r.status = Result::kDeferred;  // try again with more photos
        r.message = error;
        return r;
      }
      if (!fs::exists(tmp / "0" / "images.bin")) {
        r.status = Result::kDeferred;
        return r;
      }
      for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"})
        fs::rename(tmp / "0" / f, Model() / f);
      return Lookup(name);
    }
    if (Result placed = Find(before, name); placed.status == Result::kRegistered) return placed;
    const auto registrator = [&] {
      return Run(WithThresholds({"image_registrator", "--database_path", Db(), "--input_path",
                                 Model().string(), "--output_path", Model().string()}),
                 &error);
    };
    if (!registrator()) {
      r.message = error;
      return r;
    }
    if (!matched_all) {
      const std::vector<Placed> placed = AllPlaced();
      const auto self = std::find_if(placed.begin(), placed.end(),
                                     [&](const Placed& p) { return p.name == name; });
      if (self == placed.end()) {
        // Not placed with the chosen pairs: all of them, and again.
        LogInfo(fmt::format("COLMAP: {} not placed from the chosen pairs; matching every pair",
                            name));
        if (!MatchAll(&matched_all, &error) || !registrator()) {
          r.message = error;
          return r;
        }
      } else {
        // Its pairs with the placed photos that look at the same part of the scene (viewing
        // directions within 60 degrees, nearest centres first), so that point_triangulator
        // makes its tracks from more than the chosen few.
        std::string ignored;
        MatchPairs(name, Nearest(placed, self->cam_from_world, name, o_.match_around), &ignored);
      }
    }
    Run({"point_triangulator", "--database_path", Db(), "--image_path", Images(), "--input_path",
         Model().string(), "--output_path", Model().string()},
        &error);
    if (o_.bundle_every > 0 && ++registrations_ % o_.bundle_every == 0) {
      std::vector<std::string> adjust = {"bundle_adjuster", "--input_path", Model().string(),
                                         "--output_path", Model().string()};
      if (!o_.camera_params.empty())
        adjust.insert(adjust.end(), {"--BundleAdjustment.refine_focal_length", "0",
                                     "--BundleAdjustment.refine_principal_point", "0",
                                     "--BundleAdjustment.refine_extra_params", "0"});
      Run(adjust, &error);
    }
    RemapIfUnplaced();
    r = Lookup(name);
    if (r.status != Result::kRegistered) {
      r.status = Result::kFailed;
      r.message = "COLMAP could not register it (too few matches with the registered photos)";
    }
    return r;
  }

  Result Lookup(const std::string& name) override {
    Result r;
    if (!HasModel()) {
      r.status = Result::kDeferred;
      return r;
    }
    return Find(AllPlaced(), name);
  }

  // The model's cameras and images only (COLMAP writes it binary here): the points, the
  // largest file, are not needed to know where the photos are.
  std::vector<Placed> AllPlaced() override {
    if (!HasModel()) return {};
    return PlacedIn(Model());
  }

 private:
  // `name` among the placed photos: registered with its camera and pose, else failed.
  static Result Find(const std::vector<Placed>& placed, const std::string& name) {
    Result r;
    for (const Placed& p : placed) {
      if (p.name != name) continue;
      r.status = Result::kRegistered;
      r.camera = p.camera;
      r.cam_from_world = p.cam_from_world;
      return r;
    }
    r.status = Result::kFailed;
    r.message = "not in the COLMAP model";
    return r;
  }

  std::vector<Placed> PlacedIn(const fs::path& model) const {
    std::vector<Placed> out;
    auto open = [](const fs::path& path) {
      std::ifstream in(path, std::ios::binary);
      REPHOTO_CHECK(in.good(), "{}: cannot open", path.string());
      return in;
    };
    std::ifstream cameras_file = open(model / "cameras.bin");
    const std::map<uint32_t, camera::Camera> cameras =
        scene::ReadColmapCamerasBinary(cameras_file, (model / "cameras.bin").string());
    std::ifstream images_file = open(model / "images.bin");
    for (const scene::ColmapImage& im :
         scene::ReadColmapImagesBinary(images_file, (model / "images.bin").string())) {
      const auto camera = cameras.find(im.camera_id);
      REPHOTO_CHECK(camera != cameras.end(), "{}: image {} refers to camera {}, which is missing",
                    (model / "images.bin").string(), im.name, im.camera_id);
      out.push_back(
          {im.name, camera->second,
           camera::Pose::FromQuaternion(im.quaternion[0], im.quaternion[1], im.quaternion[2],
                                        im.quaternion[3], im.translation)});
    }
    return out;
  }

  std::string Db() const { return (o_.workspace / "database.db").string(); }
  std::string Images() const { return (o_.workspace / "images").string(); }
  fs::path Model() const { return o_.workspace / "sparse" / "0"; }
  bool HasModel() const { return fs::exists(Model() / "images.bin"); }

  // The re-map (colmap_registrar.h): when a photo of the workspace is still not in the model,
  // `mapper` from scratch on the whole database; its largest model replaces sparse/0 when it
  // holds more photos. A re-map that places no more waits twice as many new photos as the
  // last one before the next.
  void RemapIfUnplaced() {
    if (added_ >= remap_at_) Remap();
  }

  // The capture paused: the re-map runs whatever the wait after a re-map that placed nothing
  // (that wait bounds the cost per photo while photos arrive; a pause costs no photo anything),
  // once per set of photos.
  bool Idle() override {
    if (!HasModel() || idle_tried_at_ == added_) return false;
    idle_tried_at_ = added_;
    return Remap();
  }

  // Returns true when sparse/0 was replaced by a model placing more photos.
  bool Remap() {
    std::set<std::string> placed;
    for (const Placed& p : AllPlaced()) placed.insert(p.name);
    const size_t before = placed.size();
    if (before >= static_cast<size_t>(added_) || !UnplacedMatchPlaced(placed)) return false;
    std::string error;
    const fs::path tmp = o_.workspace / "remap";
    fs::remove_all(tmp);
    fs::create_directories(tmp);
    // A model replaces sparse/0 only when it keeps every photo placed so far (the session
    // moves their poses into its frame; a photo it dropped would keep a pose of the old frame)
    // and places more.
    size_t best = 0;
    fs::path best_model;
    try {
      if (Run(WithThresholds({"mapper", "--database_path", Db(), "--image_path", Images(),
                              "--output_path", tmp.string(), "--Mapper.num_threads", "2"}),
              &error)) {
        std::error_code ec;
        for (fs::directory_iterator it(tmp, ec), end; !ec && it != end; it.increment(ec)) {
          if (!fs::exists(it->path() / "images.bin")) continue;
          std::set<std::string> names;
          for (const Placed& p : PlacedIn(it->path())) names.insert(p.name);
          if (names.size() > best &&
              std::includes(names.begin(), names.end(), placed.begin(), placed.end()))
            best = names.size(), best_model = it->path();
        }
      }
      if (best > before) {
        LogInfo(fmt::format("COLMAP: the whole database mapped again places {} photos (was {})",
                            best, before));
        ReplaceModel(best_model);
      }
    } catch (const std::exception& e) {  // the model as it was; the photo stays unplaced
      LogWarning(fmt::format("COLMAP: mapping the whole database again failed: {}", e.what()));
      best = 0;
    }
    remap_wait_ = best > before ? 1 : 2 * remap_wait_;
    remap_at_ = added_ + remap_wait_;
    std::error_code ec;
    fs::remove_all(tmp, ec);
    return best > before;
  }

  // Whether a photo outside `placed` has a verified two-view geometry with at least
  // min_inliers inliers with a photo in `placed` (COLMAP's database, read-only; pair_id =
  // 2147483647 image_id1 + image_id2). A photo of another scene has none: no re-map for it.
  bool UnplacedMatchPlaced(const std::set<std::string>& placed) const {
    try {
      const SqliteConnection db(Db(), SQLITE_OPEN_READONLY);
      SqliteStatement query(db,
                            "SELECT a.name, b.name FROM two_view_geometries g "
                            "JOIN images a ON a.image_id = g.pair_id / 2147483647 "
                            "JOIN images b ON b.image_id = g.pair_id % 2147483647 WHERE g.rows >= ?");
      query.Bind(int64_t{o_.min_inliers});
      while (query.Step())
        if ((placed.count(query.Text(0)) > 0) != (placed.count(query.Text(1)) > 0)) return true;
    } catch (const Error& e) {
      LogWarning(fmt::format("cannot read the matches: {}", e.what()));
    }
    return false;
  }

  // Matching (colmap_registrar.h, "Matching"). Matches the new photo `name` with every photo
  // before it while there are at most match_all_up_to of them (exhaustive_matcher; *all =
  // true); after that with the photos chosen below only (matches_importer; *all = false).
  bool MatchNew(const std::string& name, const std::vector<Placed>& placed, bool* all,
                std::string* error) {
    const std::vector<std::string> order = ImagesInOrder();
    // COLMAP's pair list separates the two names by a space: a name with one takes every pair.
    *all = static_cast<int>(order.size()) <= o_.match_all_up_to + 1 ||
           name.find(' ') != std::string::npos;
    if (*all) return MatchAll(all, error);
    std::vector<std::string> chosen;
    const auto choose = [&](const std::string& other) {
      if (other != name && std::find(chosen.begin(), chosen.end(), other) == chosen.end())
        chosen.push_back(other);
    };
    // The photos that came just before it (a photographer walking round sees what they saw).
    for (size_t i = order.size(); i-- > 0 && chosen.size() < static_cast<size_t>(o_.match_recent);)
      choose(order[i]);
    // The placed photos nearest to the last placed one (where the photographer was last placed).
    const Placed* last = nullptr;
    for (auto it = order.rbegin(); it != order.rend() && !last; ++it)
      for (const Placed& p : placed)
        if (p.name == *it && *it != name) last = &p;
    if (last)
      for (const std::string& other : Nearest(placed, last->cam_from_world, name, o_.match_recent))
        choose(other);
    return MatchPairs(name, chosen, error);
  }

  bool MatchAll(bool* all, std::string* error) {
    *all = Run({"exhaustive_matcher", "--database_path", Db(), "--SiftMatching.use_gpu", "0"},
               error);
    return *all;
  }

  bool MatchPairs(const std::string& name, const std::vector<std::string>& others,
                  std::string* error) {
    if (others.empty()) return true;
    std::string list;
    for (const std::string& other : others)  // (a name with a space cannot be listed)
      if (other.find(' ') == std::string::npos) list += name + " " + other + "\n";
    if (list.empty()) return true;
    const fs::path pairs = o_.workspace / "pairs.txt";
    WriteTextFileAtomically(pairs, list);
    return Run({"matches_importer", "--database_path", Db(), "--match_list_path", pairs.string(),
                "--match_type", "pairs", "--SiftMatching.use_gpu", "0"},
               error);
  }

  // Up to `count` placed photos (not `except`) whose viewing direction is within 60 degrees of
  // `pose`'s, nearest camera centre first.
  static std::vector<std::string> Nearest(const std::vector<Placed>& placed,
                                          const camera::Pose& pose, const std::string& except,
                                          int count) {
    std::vector<std::pair<double, std::string>> ranked;
    for (const Placed& p : placed) {
      if (p.name == except ||
          p.cam_from_world.ViewDirection().dot(pose.ViewDirection()) < std::cos(M_PI / 3))
        continue;
      ranked.emplace_back((p.cam_from_world.Center() - pose.Center()).norm(), p.name);
    }
    std::sort(ranked.begin(), ranked.end());
    std::vector<std::string> out;
    for (size_t i = 0; i < ranked.size() && static_cast<int>(i) < count; ++i)
      out.push_back(ranked[i].second);
    return out;
  }

  // The photos of COLMAP's database in the order they were added (image_id). Empty when the
  // database cannot be read (a warning): then every pair is matched.
  std::vector<std::string> ImagesInOrder() const {
    std::vector<std::string> out;
    try {
      const SqliteConnection db(Db(), SQLITE_OPEN_READONLY);
      SqliteStatement query(db, "SELECT name FROM images ORDER BY image_id");
      while (query.Step()) out.push_back(query.Text(0));
    } catch (const Error& e) {
      LogWarning(fmt::format("cannot read the photos: {}", e.what()));
      out.clear();
    }
    return out;
  }

  // "One camera" (colmap_registrar.h): the camera COLMAP just made for `name` is replaced by
  // the earliest camera with the same model, size and parameters, if there is one. COLMAP's
  // database, written while no COLMAP process runs (the registrar runs them one at a time); a
  // failure leaves the photo its own camera (a warning).
  void ShareCamera(const std::string& name) const {
    try {
      SqliteConnection db(Db(), SQLITE_OPEN_READWRITE);
      SqliteTransaction transaction(db);
      SqliteStatement share(
          db,
          "UPDATE images SET camera_id = (SELECT MIN(o.camera_id) FROM cameras o, cameras c "
          "  WHERE c.camera_id = images.camera_id AND o.model = c.model AND o.width = c.width "
          "  AND o.height = c.height AND o.params = c.params) WHERE name = ?");
      share.Bind(name).Step();
      db.Execute("DELETE FROM cameras WHERE camera_id NOT IN (SELECT camera_id FROM images)");
      transaction.Commit();
    } catch (const Error& e) {
      LogWarning(fmt::format("cannot give {} the camera of earlier photos: {}", name, e.what()));
    }
  }

  std::string CameraParams() const {
    std::string out;
    for (double v : o_.camera_params) out += fmt::format("{}{}", out.empty() ? "" : ",", v);
    return out;
  }

  // sparse/0 := `model` (a folder of cameras.bin, images.bin, points3D.bin): the new folder is
  // renamed in after the old one is moved aside, so sparse/0 is always one whole model or
  // absent (then the next photo maps from scratch).
  void ReplaceModel(const fs::path& model) {
    const fs::path old = o_.workspace / "sparse" / "old";
    fs::remove_all(old);
    if (fs::exists(Model())) fs::rename(Model(), old);
    fs::rename(model, Model());
    fs::remove_all(old);
  }

  // The registration thresholds (colmap_registrar.h) appended to a mapper or
  // image_registrator call.
  std::vector<std::string> WithThresholds(std::vector<std::string> args) const {
    args.insert(args.end(),
                {"--Mapper.abs_pose_min_num_inliers", std::to_string(o_.min_inliers),
                 "--Mapper.abs_pose_min_inlier_ratio", fmt::format("{}", o_.min_inlier_ratio),
                 "--Mapper.init_min_num_inliers", std::to_string(o_.init_min_inliers)});
    if (args[0] == "mapper") args.insert(args.end(), {"--Mapper.min_model_size", "3"});
    if (!o_.camera_params.empty())
      args.insert(args.end(), {"--Mapper.ba_refine_focal_length", "0",
                               "--Mapper.ba_refine_principal_point", "0",
                               "--Mapper.ba_refine_extra_params", "0"});
    return args;
  }

  bool Run(std::vector<std::string> args, std::string* error) {
    // COLMAP's glog writes a log file per run of mapper, image_registrator, ... into /tmp
    // unless told otherwise (about 6 per photo, left behind for good); they go to W/logs, where
    // a failed registration can be looked into and which goes with the run folder.
    const fs::path logs = o_.workspace / "logs";
    std::error_code ec;
    fs::create_directories(logs, ec);
    std::vector<std::string> argv = {"env",
                                     "GLOG_log_dir=" + logs.string(),
                                     "timeout",
                                     "-k",
                                     "10",
                                     fmt::format("{}", o_.timeout_seconds),
                                     o_.colmap};
    argv.insert(argv.end(), args.begin(), args.end());
    const cluster::ProgramOutput out = cluster::RunProgram(argv);
    if (!out.ok()) {
      *error =
          fmt::format("colmap {} failed (exit {}): {}", args[0], out.exit_code, out.FirstLine());
      LogWarning(*error);
      return false;
    }
    return true;
  }

  ColmapRegistrarOptions o_;
  int added_ = 0;
  int registrations_ = 0;
  int remap_at_ = 0;    // photos added before the next re-map may run
  int remap_wait_ = 1;  // photos between re-maps (doubles while they place nothing new)
  int idle_tried_at_ = -1;  // photos added when Idle last re-mapped
};

}  // namespace

void ParseColmapCamera(std::string_view text, ColmapRegistrarOptions* options) {
  std::string spaced(text);
  std::replace(spaced.begin(), spaced.end(), ',', ' ');
  std::vector<std::string> fields;
  for (std::string_view token : scene::SplitTokens(spaced)) fields.emplace_back(token);
  REPHOTO_CHECK_USAGE(!fields.empty(), "--colmap-camera: empty (expected \"MODEL p1,p2,...\")");
  const std::optional<camera::CameraModel> model = camera::ParseCameraModel(fields[0]);
  REPHOTO_CHECK_USAGE(model.has_value(), "--colmap-camera: unknown camera model '{}' (COLMAP's names: PINHOLE, SIMPLE_RADIAL, OPENCV, ...)", fields[0]);
  const int count = camera::CameraModelParamCount(*model);
  REPHOTO_CHECK_USAGE(static_cast<int>(fields.size()) - 1 == count,
                      "--colmap-camera: {} takes {} parameters, got {}", fields[0], count,
                      fields.size() - 1);
  std::vector<double> params;
  for (size_t i = 1; i < fields.size(); ++i) {
    size_t used = 0;
    double v = 0;
    try {
      v = std::stod(fields[i], &used);
    } catch (const std::exception&) {
      used = 0;
    }
    REPHOTO_CHECK_USAGE(used == fields[i].size() && std::isfinite(v),
                        "--colmap-camera: parameter {} '{}' is not a finite number", i, fields[i]);
    params.push_back(v);
  }
  camera::Camera camera;
  camera.model = *model;
  camera.params = params;
  REPHOTO_CHECK_USAGE(camera.FocalLengthX() > 0 && camera.FocalLengthY() > 0,
                      "--colmap-camera: the focal length must be positive");
  options->camera_model = fields[0];
  options->camera_params = std::move(params);
}

std::unique_ptr<Registrar> MakeColmapRegistrar(const ColmapRegistrarOptions& options) {
  return std::make_unique<ColmapRegistrar>(options);
}

}  // namespace rephoto::live
