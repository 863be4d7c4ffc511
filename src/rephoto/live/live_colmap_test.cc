// rephoto live with COLMAP registration (colmap_registrar.h) on real photos
// (../shared/data/llff_fern/images_8): 6 photos in a shuffled order register (the first ones are
// deferred until the initial reconstruction, then placed), and a photo of another scene (the
// demo scene) cannot register and gets the status "unregistered", not a crash. The relative
// poses COLMAP finds are checked against the dataset's own COLMAP model up to a similarity:
// camera-centre distance ratios agree within 10 %. Needs `colmap` (scripts/install-deps.sh).
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <sstream>

#include <Eigen/Geometry>

#include "rephoto/camera/camera.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/sqlite.h"
#include "rephoto/io/image_io.h"
#include "rephoto/live/colmap_registrar.h"
#include "rephoto/live/demo_capture.h"
#include "rephoto/live/live_session.h"
#include "rephoto/live/sidecar.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/testing/testing.h"

namespace rephoto::live {
namespace {
namespace fs = std::filesystem;

TEST(LiveColmapTest, ShuffledRealPhotosRegisterAndAStrangerDoesNot) {
  REPHOTO_REQUIRE_DATA("llff_fern/images_8");
  ASSERT_EQ(std::system("command -v colmap >/dev/null"), 0) << "install colmap (scripts/install-deps.sh)";
  const fs::path images = testing::SharedDataDir() / "llff_fern" / "images_8";
  const fs::path base = testing::MakeTempDir();
  const fs::path watch = base / "watch", run = base / "run";
  fs::create_directories(watch);
  std::vector<std::string> names = {"image000.png", "image003.png", "image006.png",
                                    "image009.png", "image012.png", "image015.png"};
  std::shuffle(names.begin(), names.end(), std::mt19937_64(7));
  ColmapRegistrarOptions co;
  co.workspace = run / "colmap";
  co.bootstrap = 4;
  const std::unique_ptr<Registrar> registrar = MakeColmapRegistrar(co);
  LiveOptions o;
  o.watch = watch;
  o.out = run;
  o.registrar = registrar.get();
  o.predict_width = 252;
  o.depth_width = 252;
  o.candidates = 100;
  LiveSession session(o);
  for (const std::string& n : names) {
    fs::copy_file(images / n, watch / n);
    session.HandleReady(n);
  }
  // A photo of another scene.
  DemoCapture capture(504, 378);
  io::WritePng(watch / "stranger.png", capture.Photograph(LookAt({3, 0, 1.5}, {0, 0, 0.45}), 1));
  session.HandleReady("stranger.png");
  const nlohmann::json api = session.Api();
  std::map<std::string, nlohmann::json> by;
  for (const auto& p : api["photos"]) by[p["name"]] = p;
  for (const std::string& n : names) {
    ASSERT_TRUE(by.count(n)) << n;
    EXPECT_EQ(by[n]["status"], "registered") << by[n].dump();
    EXPECT_EQ(by[n]["pose_source"], "colmap");
  }
  ASSERT_TRUE(by.count("stranger.png"));
  EXPECT_EQ(by["stranger.png"]["status"], "unregistered") << by["stranger.png"].dump();
  EXPECT_FALSE(by["stranger.png"]["message"].get<std::string>().empty());
  // Reference: the dataset's poses (LLFF poses_bounds.npy converted to COLMAP text beside it;
  // independent of this run's COLMAP).
  const scene::ColmapModel ref =
      scene::ReadColmapModel(testing::SharedDataDir() / "llff_fern" / "sparse_text_images_8_derived");
  std::map<std::string, Eigen::Vector3d> ref_centre, live_centre;
  for (const auto& im : ref.images)
    ref_centre[im.name] = camera::Pose::FromQuaternion(im.quaternion[0], im.quaternion[1],
                                                       im.quaternion[2], im.quaternion[3],
                                                       im.translation).Center();
  for (const std::string& n : names)
    live_centre[n] = ParseSidecar(by[n].dump(), n).cam_from_world.Center();
  auto ref_of = [&](const std::string& n) { return ref_centre.at(n); };
  std::vector<double> ratios;
  for (size_t a = 0; a < names.size(); ++a)
    for (size_t b = a + 1; b < names.size(); ++b) {
      const std::string& sa = names[a];
      const std::string& sb = names[b];
      ratios.push_back((live_centre[sa] - live_centre[sb]).norm() / (ref_of(sa) - ref_of(sb)).norm());
    }
  std::sort(ratios.begin(), ratios.end());
  const double median = ratios[ratios.size() / 2];
  for (double r : ratios) EXPECT_NEAR(r / median, 1.0, 0.1);
}

TEST(LiveColmapTest, PosesRefinedByBundleAdjustmentAreTakenOver) {
  // 8 fern photos, a global bundle adjustment after every 2nd registration (besides
  // image_registrator's local one): after each photo, the session holds every photo's pose as
  // it is in COLMAP's model now (read back independently from the workspace), and the photos
  // are still predicted from the earlier ones (before the poses were taken over, every photo
  // after a global bundle adjustment was predicted with 1-NCC 0.73-0.81: the frame had moved).
  REPHOTO_REQUIRE_DATA("llff_fern/images_8");
  ASSERT_EQ(std::system("command -v colmap >/dev/null"), 0) << "install colmap (scripts/install-deps.sh)";
  const fs::path images = testing::SharedDataDir() / "llff_fern" / "images_8";
  const fs::path base = testing::MakeTempDir();
  const fs::path watch = base / "watch", run = base / "run";
  fs::create_directories(watch);
  std::vector<std::string> names;
  for (int k = 0; k < 16; k += 2) names.push_back(fmt::format("image{:03d}.png", k));
  std::shuffle(names.begin(), names.end(), std::mt19937_64(3));
  ColmapRegistrarOptions co;
  co.workspace = run / "colmap";
  co.bootstrap = 4;
  co.bundle_every = 2;
  const std::unique_ptr<Registrar> registrar = MakeColmapRegistrar(co);
  LiveOptions o;
  o.watch = watch;
  o.out = run;
  o.registrar = registrar.get();
  o.predict_width = 252;
  o.depth_width = 252;
  o.candidates = 100;
  o.suggestions = 1;
  LiveSession session(o);
  // Two photos of another scene last: COLMAP cannot place them, but the second call's global
  // bundle adjustment (the 6th call after the bootstrap) still moves the poses, which the
  // session must take over too.
  DemoCapture capture(504, 378);
  std::vector<std::string> order = names;
  for (int k = 0; k < 2; ++k) {
    const std::string stranger = fmt::format("stranger{}.png", k);
    io::WritePng(watch / stranger,
                 capture.Photograph(LookAt({3.0 - k, 0.5 * k, 1.5}, {0, 0, 0.45}), 1 + k));
    order.push_back(stranger);
  }
  for (const std::string& n : order) {
    if (!fs::exists(watch / n)) fs::copy_file(images / n, watch / n);
    session.HandleReady(n);
    if (!fs::exists(run / "colmap" / "sparse" / "0" / "images.bin")) continue;  // bootstrapping
    const scene::ColmapModel m = scene::ReadColmapModel(run / "colmap" / "sparse" / "0");
    const nlohmann::json api = session.Api();
    for (const auto& p : api["photos"]) {
      if (p["status"] != "registered") continue;
      const auto im = std::find_if(m.images.begin(), m.images.end(),
                                   [&](const scene::ColmapImage& i) { return i.name == p["name"]; });
      ASSERT_NE(im, m.images.end()) << p["name"];
      for (int i = 0; i < 3; ++i)
        EXPECT_NEAR(p["tvec"][i].get<double>(), im->translation[i], 1e-9) << n << " " << p["name"];
    }
  }
  const nlohmann::json api = session.Api();
  size_t predicted = 0;
  for (const auto& p : api["photos"]) {
    if (p["name"].get<std::string>().rfind("stranger", 0) == 0) {
      EXPECT_EQ(p["status"], "unregistered") << p.dump();
      continue;
    }
    EXPECT_EQ(p["status"], "registered") << p.dump();
    if (!p["error"].is_number()) continue;
    ++predicted;
    std::printf("%s: completeness %.3f, 1-NCC %.3f\n", p["name"].get<std::string>().c_str(),
                p["completeness"].get<double>(), p["error"].get<double>());
    EXPECT_LT(p["error"].get<double>(), 0.6) << p["name"];
  }
  EXPECT_GE(predicted, 5u);
}

// Middlebury's templeSR_par.txt: "name k11..k33 r11..r33 t1 t2 t3" per photo (x ~ K [R | t] X,
// world to camera): the camera centres -R^T t. Independent of COLMAP (the dataset's own
// calibration).
std::map<std::string, Eigen::Vector3d> MiddleburyCentres(const fs::path& par) {
  std::istringstream in(ReadFileToString(par));
  int count = 0;
  in >> count;
  std::map<std::string, Eigen::Vector3d> centres;
  for (int i = 0; i < count; ++i) {
    std::string name;
    double k[9];
    Eigen::Matrix3d r;
    Eigen::Vector3d t;
    in >> name;
    for (double& v : k) in >> v;
    for (int row = 0; row < 3; ++row)
      for (int col = 0; col < 3; ++col) in >> r(row, col);
    in >> t.x() >> t.y() >> t.z();
    EXPECT_TRUE(in.good()) << par << ": line " << i + 2;
    centres[name] = -r.transpose() * t;
  }
  return centres;
}

// The distance of each placed photo's centre from the calibration's, after the similarity that
// best maps the first onto the second (Umeyama), over the calibration's mean distance from its
// centroid (the ring's radius when the whole ring is placed); sorted.
std::vector<double> CentreResiduals(const std::vector<Registrar::Placed>& placed,
                                    const std::map<std::string, Eigen::Vector3d>& truth) {
  Eigen::Matrix3Xd live(3, placed.size()), reference(3, placed.size());
  for (size_t i = 0; i < placed.size(); ++i) {
    live.col(i) = placed[i].cam_from_world.Center();
    reference.col(i) = truth.at(placed[i].name);
  }
  const Eigen::Matrix4d similarity = Eigen::umeyama(live, reference, true);
  const Eigen::Matrix3Xd aligned =
      (similarity.topLeftCorner<3, 3>() * live).colwise() + similarity.topRightCorner<3, 1>();
  const Eigen::Vector3d centre = reference.rowwise().mean();
  const double radius = (reference.colwise() - centre).colwise().norm().mean();
  std::vector<double> residuals;
  for (size_t i = 0; i < placed.size(); ++i) {
    residuals.push_back((aligned.col(i) - reference.col(i)).norm() / radius);
    std::printf("%s: centre %.4f of the ring's radius from the calibration\n",
                placed[i].name.c_str(), residuals.back());
  }
  std::sort(residuals.begin(), residuals.end());
  return residuals;
}

TEST(LiveColmapTest, EveryPhotoOfASparseRingRegisters) {
  // Middlebury templeSparseRing: 16 photos 22.5 degrees apart around a faintly textured plaster
  // temple (150-800 SIFT features each). With COLMAP's default thresholds its own batch
  // `mapper` placed 13 of them and the live registration 12; the registrar's thresholds
  // (colmap_registrar.h) place all 16, with camera centres that agree with the dataset's
  // calibration after a similarity (Umeyama). The photos go to the registrar in the order of a
  // capture walking round the temple from the 5th photo (the registrar tries every unplaced
  // photo again with each new one).
  REPHOTO_REQUIRE_DATA("middlebury_temple_dino/templeSparseRing");
  ASSERT_EQ(std::system("command -v colmap >/dev/null"), 0) << "install colmap (scripts/install-deps.sh)";
  const fs::path images = testing::SharedDataDir() / "middlebury_temple_dino" / "templeSparseRing";
  const std::map<std::string, Eigen::Vector3d> truth =
      MiddleburyCentres(images / "templeSR_par.txt");
  ASSERT_EQ(truth.size(), 16u);
  ColmapRegistrarOptions co;
  co.workspace = testing::MakeTempDir() / "colmap";
  // COLMAP's log files (glog: colmap.<host>.<user>.log.<level>.<time>.<pid>, in $TMPDIR or
  // /tmp unless GLOG_log_dir is set) go to the workspace, none to the temporary folders.
  auto colmap_logs = [](const fs::path& dir) {
    std::set<std::string> found;
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
      if (it->path().filename().string().starts_with("colmap.")) found.insert(it->path().string());
    return found;
  };
  const std::set<std::string> tmp_before = colmap_logs("/tmp"),
                              tmpdir_before = colmap_logs(fs::temp_directory_path());
  const std::unique_ptr<Registrar> registrar = MakeColmapRegistrar(co);
  std::vector<std::string> names;
  for (int k = 0; k < 16; ++k) names.push_back(fmt::format("templeSR{:04d}.png", (k + 4) % 16 + 1));
  for (const std::string& n : names) registrar->Register(images / n);
  EXPECT_EQ(colmap_logs("/tmp"), tmp_before);
  EXPECT_EQ(colmap_logs(fs::temp_directory_path()), tmpdir_before);
  EXPECT_GE(colmap_logs(co.workspace / "logs").size(), 16u);  // mapper, registrator, ... runs
  const std::vector<Registrar::Placed> placed = registrar->AllPlaced();
  std::vector<std::string> unplaced = names;
  for (const Registrar::Placed& p : placed) std::erase(unplaced, p.name);
  EXPECT_EQ(placed.size(), 16u);
  EXPECT_TRUE(unplaced.empty()) << fmt::format("{}", fmt::join(unplaced, " "));
  const std::vector<double> residuals = CentreResiduals(placed, truth);
  // With one camera shared by the photos (colmap_registrar.h, "One camera"): median 0.004,
  // largest 0.015 of the radius. When each photo had its own camera (before 2026-11-28, fourth
  // stop) incremental registration drifted round the ring: median 0.027, largest 0.074 here and
  // 0.03 / 0.125 in the live run of docs/live.md. A photo placed in a wrong place is off by a
  // large part of the radius.
  EXPECT_LT(residuals[residuals.size() / 2], 0.015);
  EXPECT_LT(residuals.back(), 0.05);
  // One camera: the photos are all 640 x 480 from one camera, and share its intrinsics.
  for (const Registrar::Placed& p : placed) EXPECT_EQ(p.camera.params, placed[0].camera.params) << p.name;
}

TEST(LiveColmapTest, ChosenPairsPlaceACaptureWithoutMatchingEveryPair) {
  // Past match_all_up_to earlier photos, a new photo is matched with chosen photos only
  // (colmap_registrar.h, "Matching"). Here from the 6th photo on, with 3 recent photos, 3
  // placed near the last placed one and 3 near its own pose: the 20 fern photos in the order
  // they were taken are all placed, from fewer pairs than every pair (190), with camera centres
  // that agree with the dataset's poses (distance ratios within 10 % of their median, as in
  // the shuffled test above). Measured: 116 pairs (97 without the two
  // names with a space), ratios 0.922-1.080 of their median; with every pair matched (190)
  // 0.921-1.082.
  REPHOTO_REQUIRE_DATA("llff_fern/images_8");
  ASSERT_EQ(std::system("command -v colmap >/dev/null"), 0) << "install colmap (scripts/install-deps.sh)";
  const fs::path images = testing::SharedDataDir() / "llff_fern" / "images_8";
  ColmapRegistrarOptions co;
  co.workspace = testing::MakeTempDir() / "colmap";
  co.match_all_up_to = 5;
  co.match_recent = 3;
  co.match_around = 3;
  const std::unique_ptr<Registrar> registrar = MakeColmapRegistrar(co);
  // Two photos have a space in their name, which COLMAP's pair list cannot hold: they are
  // matched with every photo instead (one before the 6th photo, one after).
  const fs::path copies = testing::MakeTempDir();
  for (int k = 0; k < 20; ++k) {
    const std::string name = fmt::format("image{:03d}.png", k);
    const std::string as = k == 3 || k == 12 ? fmt::format("image {:03d}.png", k) : name;
    fs::copy_file(images / name, copies / as);
    registrar->Register(copies / as);
  }
  const std::vector<Registrar::Placed> placed = registrar->AllPlaced();
  EXPECT_EQ(placed.size(), 20u);
  // The pairs COLMAP matched (its database).
  const SqliteConnection db(co.workspace / "database.db", SQLITE_OPEN_READONLY);
  SqliteStatement count(db, "SELECT COUNT(*) FROM matches");
  ASSERT_TRUE(count.Step());
  const int pairs = static_cast<int>(count.Int(0));
  std::printf("%d of 190 pairs matched\n", pairs);
  EXPECT_LT(pairs, 150);
  const scene::ColmapModel ref = scene::ReadColmapModel(
      testing::SharedDataDir() / "llff_fern" / "sparse_text_images_8_derived");
  std::map<std::string, Eigen::Vector3d> ref_centre, live_centre;
  for (const auto& im : ref.images)
    ref_centre[im.name] = camera::Pose::FromQuaternion(im.quaternion[0], im.quaternion[1],
                                                       im.quaternion[2], im.quaternion[3],
                                                       im.translation).Center();
  for (const Registrar::Placed& p : placed) {
    std::string name = p.name;  // "image 003.png" is the dataset's "image003.png"
    std::erase(name, ' ');
    live_centre[name] = p.cam_from_world.Center();
  }
  std::vector<double> ratios;
  for (const auto& [a, ca] : live_centre)
    for (const auto& [b, cb] : live_centre)
      if (a < b) ratios.push_back((ca - cb).norm() / (ref_centre.at(a) - ref_centre.at(b)).norm());
  std::sort(ratios.begin(), ratios.end());
  const double median = ratios[ratios.size() / 2];
  std::printf("distance ratios / median: %.3f .. %.3f\n", ratios.front() / median, ratios.back() / median);
  for (double r : ratios) EXPECT_NEAR(r / median, 1.0, 0.1);
}

TEST(LiveColmapTest, KnownIntrinsicsPlaceWhatTheGuessCannot) {
  // Middlebury dinoSparseRing: 16 photos 22.5 degrees apart round a plaster dinosaur on black
  // (150-370 SIFT features each), taken with a focal length of 3310 pixels on 640 x 480
  // photos, 4.3 x COLMAP's guess (1.2 x 640). With the guess COLMAP builds no model of more
  // than 3 photos (docs/live.md). With the dataset's calibration given as known intrinsics
  // (--colmap-camera), the live registration places the largest group the ring's matches
  // connect (photos 7-12 in ring order; 6 measured), every placed photo keeps the given
  // intrinsics exactly (no adjustment refines them) and the centres agree with the calibration.
  REPHOTO_REQUIRE_DATA("middlebury_temple_dino/dinoSparseRing");
  ASSERT_EQ(std::system("command -v colmap >/dev/null"), 0) << "install colmap (scripts/install-deps.sh)";
  const fs::path images = testing::SharedDataDir() / "middlebury_temple_dino" / "dinoSparseRing";
  const std::map<std::string, Eigen::Vector3d> truth =
      MiddleburyCentres(images / "dinoSR_par.txt");
  ASSERT_EQ(truth.size(), 16u);
  // K of the first photo (all 16 share it): fx 0 cx / 0 fy cy / 0 0 1. Middlebury's pixel
  // centres are at integers, COLMAP's at .5 (camera.h): + 0.5 (0.01 degrees at this focal length).
  std::istringstream par(ReadFileToString(images / "dinoSR_par.txt"));
  int count = 0;
  std::string name;
  double k[9];
  par >> count >> name;
  for (double& v : k) par >> v;
  ASSERT_TRUE(par.good());
  ColmapRegistrarOptions co;
  co.workspace = testing::MakeTempDir() / "colmap";
  ParseColmapCamera(fmt::format("PINHOLE {},{},{},{}", k[0], k[4], k[2] + 0.5, k[5] + 0.5), &co);
  const std::vector<double> given = co.camera_params;
  const std::unique_ptr<Registrar> registrar = MakeColmapRegistrar(co);
  for (int i = 0; i < 16; ++i) registrar->Register(images / fmt::format("dinoSR{:04d}.png", (i + 4) % 16 + 1));
  const std::vector<Registrar::Placed> placed = registrar->AllPlaced();
  EXPECT_GE(placed.size(), 6u);
  for (const Registrar::Placed& p : placed) {
    EXPECT_EQ(p.camera.model, camera::CameraModel::kPinhole) << p.name;
    EXPECT_EQ(p.camera.params, given) << p.name;
  }
  if (placed.size() < 3) return;
  // Relative to the placed photos' own spread (an arc of about 110 degrees of the ring, seen
  // through an 11-degree field of view, which constrains the distance along each axis weakly):
  // measured median 0.032, largest 0.075. A photo placed in a wrong place is off by a large
  // part of the spread.
  const std::vector<double> residuals = CentreResiduals(placed, truth);
  EXPECT_LT(residuals[residuals.size() / 2], 0.06);
  EXPECT_LT(residuals.back(), 0.15);
}

TEST(LiveColmapTest, PhotosOfOneSizeShareOneCamera) {
  // COLMAP's single_camera holds within one feature_extractor call, and the registrar makes
  // one call per photo (colmap_registrar.h, "One camera"): three fern photos (504 x 378) share
  // one camera row of COLMAP's database, a temple photo (640 x 480) has its own. Read from the
  // database with SQLite, independently of the registrar.
  REPHOTO_REQUIRE_DATA("llff_fern/images_8");
  REPHOTO_REQUIRE_DATA("middlebury_temple_dino/templeSparseRing");
  ASSERT_EQ(std::system("command -v colmap >/dev/null"), 0) << "install colmap (scripts/install-deps.sh)";
  ColmapRegistrarOptions co;
  co.workspace = testing::MakeTempDir() / "colmap";
  co.bootstrap = 100;  // features and matches only
  const std::unique_ptr<Registrar> registrar = MakeColmapRegistrar(co);
  const fs::path fern = testing::SharedDataDir() / "llff_fern" / "images_8";
  for (const char* n : {"image000.png", "image005.png"}) registrar->Register(fern / n);
  registrar->Register(testing::SharedDataDir() / "middlebury_temple_dino" / "templeSparseRing" /
                      "templeSR0001.png");
  registrar->Register(fern / "image010.png");
  const SqliteConnection db(co.workspace / "database.db", SQLITE_OPEN_READONLY);
  SqliteStatement rows(db,
                       "SELECT i.name, c.camera_id, c.width, c.height FROM images i "
                       "JOIN cameras c ON c.camera_id = i.camera_id ORDER BY i.image_id");
  std::map<std::string, std::pair<int, int>> camera_of;  // name -> (camera id, width)
  while (rows.Step())
    camera_of[rows.Text(0)] = {static_cast<int>(rows.Int(1)), static_cast<int>(rows.Int(2))};
  SqliteStatement count(db, "SELECT COUNT(*) FROM cameras");
  ASSERT_TRUE(count.Step());
  const int cameras = static_cast<int>(count.Int(0));
  ASSERT_EQ(camera_of.size(), 4u);
  EXPECT_EQ(cameras, 2);
  EXPECT_EQ(camera_of["image000.png"].first, camera_of["image005.png"].first);
  EXPECT_EQ(camera_of["image000.png"].first, camera_of["image010.png"].first);
  EXPECT_NE(camera_of["templeSR0001.png"].first, camera_of["image000.png"].first);
  EXPECT_EQ(camera_of["image000.png"].second, 504);
  EXPECT_EQ(camera_of["templeSR0001.png"].second, 640);
}

TEST(LiveColmapTest, KnownIntrinsicsAreCheckedWhenRead) {
  ColmapRegistrarOptions co;
  ParseColmapCamera("SIMPLE_RADIAL 800, 320 240,-0.01", &co);
  EXPECT_EQ(co.camera_model, "SIMPLE_RADIAL");
  EXPECT_EQ(co.camera_params, (std::vector<double>{800, 320, 240, -0.01}));
  for (const char* bad : {"", "PINHOL 1,2,3,4", "PINHOLE 1,2,3", "PINHOLE 1,2,3,4,5",
                          "PINHOLE 1,2,x,4", "PINHOLE 1,nan,3,4", "PINHOLE 1,inf,3,4",
                          "SIMPLE_PINHOLE 0,3,4", "PINHOLE 800,-800,3,4", "pinhole 1,2,3,4"})
    EXPECT_THROW(ParseColmapCamera(bad, &co), UsageError) << bad;
  EXPECT_EQ(co.camera_params, (std::vector<double>{800, 320, 240, -0.01}));  // unchanged
}

}  // namespace
}  // namespace rephoto::live
