#include "rephoto/live/colmap_registrar.h"

#include <fmt/format.h>

#include <cstdlib>
#include <fstream>
#include <map>

#include "rephoto/cluster/subprocess.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/scene/colmap.h"

namespace rephoto::live {
namespace fs = std::filesystem;

namespace {

class ColmapRegistrar : public Registrar {
 public:
  explicit ColmapRegistrar(const ColmapRegistrarOptions& o) : o_(o) {
    REPHOTO_CHECK_USAGE(o.bootstrap >= 2 && o.bundle_every >= 0 && o.timeout_seconds > 0,
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
    const fs::path image = o_.workspace / "images" / name;
    Result r;
    fs::create_directories(o_.workspace / "images");
    fs::create_directories(o_.workspace / "sparse" / "0");
    if (!fs::exists(image)) {
      LinkOrCopyFileAtomically(photo, image);
      ++added_;
      const fs::path list = o_.workspace / "new_image.txt";
      WriteTextFileAtomically(list, name + "\n");
      std::string error;
      if (!Run({"feature_extractor", "--database_path", Db(), "--image_path", Images(),
                "--image_list_path", list.string(), "--ImageReader.single_camera", "1",
                "--ImageReader.camera_model", "SIMPLE_RADIAL", "--SiftExtraction.use_gpu", "0",
                "--SiftExtraction.max_image_size", std::to_string(o_.max_image_size)},
               &error) ||
          !Run({"exhaustive_matcher", "--database_path", Db(), "--SiftMatching.use_gpu", "0"},
               &error)) {
        r.message = error;
        return r;
      }
    }
    if (!HasModel()) {
      if (added_ < o_.bootstrap) {
        r.status = Result::kDeferred;
        return r;
      }
      std::string error;
      const fs::path tmp = o_.workspace / "mapper";
      fs::remove_all(tmp);
      fs::create_directories(tmp);
      if (!Run({"mapper", "--database_path", Db(), "--image_path", Images(), "--output_path",
                tmp.string(), "--Mapper.num_threads", "2"},
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
    if (Result placed = Lookup(name); placed.status == Result::kRegistered) return placed;
    std::string error;
    if (!Run({"image_registrator", "--database_path", Db(), "--input_path", Model().string(),
              "--output_path", Model().string()},
             &error)) {
      r.message = error;
      return r;
    }
    Run({"point_triangulator", "--database_path", Db(), "--image_path", Images(), "--input_path",
         Model().string(), "--output_path", Model().string()},
        &error);
    if (o_.bundle_every > 0 && ++registrations_ % o_.bundle_every == 0) {
      Run({"bundle_adjuster", "--input_path", Model().string(), "--output_path", Model().string()},
          &error);
    }
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
    for (Placed& p : AllPlaced()) {
      if (p.name != name) continue;
      r.status = Result::kRegistered;
      r.camera = std::move(p.camera);
      r.cam_from_world = p.cam_from_world;
      return r;
    }
    r.status = Result::kFailed;
    r.message = "not in the COLMAP model";
    return r;
  }

  // The model's cameras and images only (COLMAP writes it binary here): the points, the
  // largest file, are not needed to know where the photos are.
  std::vector<Placed> AllPlaced() override {
    std::vector<Placed> out;
    if (!HasModel()) return out;
    auto open = [](const fs::path& path) {
      std::ifstream in(path, std::ios::binary);
      REPHOTO_CHECK(in.good(), "{}: cannot open", path.string());
      return in;
    };
    std::ifstream cameras_file = open(Model() / "cameras.bin");
    const std::map<uint32_t, camera::Camera> cameras =
        scene::ReadColmapCamerasBinary(cameras_file, (Model() / "cameras.bin").string());
    std::ifstream images_file = open(Model() / "images.bin");
    for (const scene::ColmapImage& im :
         scene::ReadColmapImagesBinary(images_file, (Model() / "images.bin").string())) {
      const auto camera = cameras.find(im.camera_id);
      REPHOTO_CHECK(camera != cameras.end(), "{}: image {} refers to camera {}, which is missing",
                    (Model() / "images.bin").string(), im.name, im.camera_id);
      out.push_back({im.name, camera->second,
                     camera::Pose::FromQuaternion(im.quaternion[0], im.quaternion[1],
                                                  im.quaternion[2], im.quaternion[3],
                                                  im.translation)});
    }
    return out;
  }

 private:
  std::string Db() const { return (o_.workspace / "database.db").string(); }
  std::string Images() const { return (o_.workspace / "images").string(); }
  fs::path Model() const { return o_.workspace / "sparse" / "0"; }
  bool HasModel() const { return fs::exists(Model() / "images.bin"); }

  bool Run(std::vector<std::string> args, std::string* error) {
    std::vector<std::string> argv = {"timeout", "-k", "10", fmt::format("{}", o_.timeout_seconds),
                                     o_.colmap};
    argv.insert(argv.end(), args.begin(), args.end());
    const cluster::ProgramOutput out = cluster::RunProgram(argv);
    if (!out.ok()) {
      *error = fmt::format("colmap {} failed (exit {}): {}", args[0], out.exit_code,
                           out.FirstLine());
      LogWarning(*error);
      return false;
    }
    return true;
  }

  ColmapRegistrarOptions o_;
  int added_ = 0;
  int registrations_ = 0;
};

}  // namespace

std::unique_ptr<Registrar> MakeColmapRegistrar(const ColmapRegistrarOptions& options) {
  return std::make_unique<ColmapRegistrar>(options);
}

}  // namespace rephoto::live
