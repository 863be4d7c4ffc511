// Poses refined by the registration engine (pose_update.h, live_session.h): the frame's move
// (a similarity) against a photo's own refinement, closed form; and a session whose engine moves
// the whole frame (and turns one photo) between two photos takes the new poses over: the
// records hold them, depth maps are scaled with the frame or estimated again, and the next
// photo is predicted in the new frame.
#include "rephoto/live/pose_update.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <set>

#include "rephoto/ibr/depth_map_io.h"
#include "rephoto/live/demo_capture.h"
#include "rephoto/live/live_session.h"
#include "rephoto/testing/testing.h"

namespace rephoto::live {
namespace {
namespace fs = std::filesystem;

// The pose after the world moves by X' = s Q X + t (the camera frame scales with it):
// R' = R Q^T, T' = s T - R Q^T t, so that C' = s Q C + t.
camera::Pose Moved(const camera::Pose& p, double s, const Eigen::Matrix3d& Q,
                   const Eigen::Vector3d& t) {
  camera::Pose m;
  m.rotation = p.rotation * Q.transpose();
  m.translation = s * p.translation - m.rotation * t;
  return m;
}

// A pose turned by `degrees` about its own vertical axis (centre kept).
camera::Pose Turned(const camera::Pose& p, double degrees) {
  const Eigen::Vector3d c = p.Center();
  camera::Pose m;
  m.rotation =
      Eigen::AngleAxisd(degrees * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix() *
      p.rotation;
  m.translation = -m.rotation * c;
  return m;
}

std::vector<camera::Pose> Ring(int n) {
  std::vector<camera::Pose> poses;
  for (int k = 0; k < n; ++k) {
    const double a = k * 2 * M_PI / n;
    poses.push_back(
        LookAt({3 * std::cos(a), 3 * std::sin(a), 1 + 0.2 * std::sin(3 * a)}, {0, 0, 0.4}));
  }
  return poses;
}

const Eigen::Matrix3d kQ = (Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()))
                               .toRotationMatrix();
const Eigen::Vector3d kT(1, -2, 0.5);

TEST(PoseUpdateTest, FrameMoveIsAScaleAndNoRefresh) {
  const std::vector<camera::Pose> before = Ring(8);
  std::vector<camera::Pose> after;
  for (const auto& p : before) after.push_back(Moved(p, 1.7, kQ, kT));
  const std::vector<PoseChange> c = ComparePoses(before, after);
  ASSERT_EQ(c.size(), 8u);
  for (const PoseChange& x : c) {
    EXPECT_NEAR(x.scale, 1.7, 1e-9);
    EXPECT_NEAR(x.moved, 0, 1e-9);
    EXPECT_NEAR(x.rotated_degrees, 0, 1e-5);
    EXPECT_FALSE(x.refresh_depth);
  }
}

// IntrinsicsChange: the largest parameter change relative to max(1, |before|); 1 when the
// cameras are not comparable (closed form).
TEST(PoseUpdateTest, IntrinsicsChangeIsTheLargestRelativeParameterChange) {
  const camera::Camera a{camera::CameraModel::kPinhole, 640, 480, {1000, 1000, 320, 240}};
  EXPECT_EQ(IntrinsicsChange(a, a), 0.0);
  camera::Camera b = a;
  b.params = {1004, 1000, 320, 239};  // fx +0.4 %, cy -1/240
  EXPECT_DOUBLE_EQ(IntrinsicsChange(a, b), 1.0 / 240);
  b.params = {1004, 1000, 320, 240};
  EXPECT_DOUBLE_EQ(IntrinsicsChange(a, b), 0.004);
  b = a;
  b.width = 641;
  EXPECT_EQ(IntrinsicsChange(a, b), 1.0);
  b = a;
  b.model = camera::CameraModel::kSimpleRadial;
  b.params = {1000, 320, 240, 0};
  EXPECT_EQ(IntrinsicsChange(a, b), 1.0);
}

TEST(PoseUpdateTest, OnePhotoTurnedOrMovedIsRefreshed) {
  const std::vector<camera::Pose> before = Ring(12);
  std::vector<camera::Pose> after;
  for (const auto& p : before) after.push_back(Moved(p, 0.6, kQ, kT));
  // Photo 3 turns by 2 degrees about its centre: the centres (and so the similarity) are
  // unchanged, its residual rotation is exactly 2 degrees.
  after[3] = Turned(after[3], 2.0);
  // Photo 7's centre moves by 5 % of the centres' RMS spread (the spread of a ring of radius
  // 3 * 0.6 with small height changes is about 1.8).
  std::vector<PoseChange> c = ComparePoses(before, after);
  EXPECT_NEAR(c[3].rotated_degrees, 2.0, 1e-6);
  EXPECT_TRUE(c[3].refresh_depth);
  for (size_t i = 0; i < c.size(); ++i)
    if (i != 3) {
      EXPECT_FALSE(c[i].refresh_depth) << i;
    }
  double spread = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : after) mean += p.Center() / 12.0;
  for (const auto& p : after) spread += (p.Center() - mean).squaredNorm() / 12.0;
  spread = std::sqrt(spread);
  const Eigen::Vector3d c7 = after[7].Center() + Eigen::Vector3d(0, 0, 0.05 * spread);
  after[7].translation = -after[7].rotation * c7;
  c = ComparePoses(before, after);
  // The least-squares similarity absorbs a share of the move (about 1/12 of it).
  EXPECT_GT(c[7].moved, 0.04);
  EXPECT_TRUE(c[7].refresh_depth);
  for (size_t i = 0; i < c.size(); ++i)
    if (i != 3 && i != 7) {
      EXPECT_FALSE(c[i].refresh_depth) << i << " moved " << c[i].moved;
    }
  EXPECT_NE(testing::ErrorOf([&] { ComparePoses(before, {}); }), "");
}

// An engine that returns the poses of a table (the test moves them between photos).
class TableRegistrar : public Registrar {
 public:
  std::map<std::string, Placed> table;
  std::set<std::string> added;
  std::string defer;  // non-empty: no model yet, every photo deferred with this message
  std::map<std::string, Placed> on_idle;  // placed when the session is idle
  int idle_calls = 0;
  bool Idle() override {
    ++idle_calls;
    const bool any = !on_idle.empty();
    table.merge(on_idle);
    return any;
  }
  Result Register(const fs::path& photo) override {
    added.insert(photo.filename().string());
    if (!defer.empty()) {
      Result r;
      r.status = Result::kDeferred;
      r.message = defer;
      return r;
    }
    return Lookup(photo.filename().string());
  }
  Result Lookup(const std::string& name) override {
    Result r;
    if (!defer.empty()) {
      r.status = Result::kDeferred;
      return r;
    }
    const auto it = table.find(name);
    if (it == table.end() || !added.count(name)) {
      r.message = "unknown";
      return r;
    }
    r.status = Result::kRegistered;
    r.camera = it->second.camera;
    r.cam_from_world = it->second.cam_from_world;
    return r;
  }
  std::vector<Placed> AllPlaced() override {
    std::vector<Placed> out;
    for (const auto& [name, p] : table)
      if (added.count(name)) out.push_back(p);
    return out;
  }
};

// A capture the engine places (TableRegistrar): photos p<k>.png of the demo scene on a ring,
// dropped without a sidecar, and the session's options on a fresh run folder.
struct EngineCapture {
  explicit EngineCapture(int photos) {
    const fs::path base = testing::MakeTempDir();
    watch = base / "watch";
    fs::create_directories(watch);
    options.watch = watch;
    options.out = base / "run";
    options.predict_width = 240;
    options.depth_width = 240;
    options.candidates = 60;
    options.suggestions = 1;
    options.registrar = &engine;
    const Eigen::Vector3d target(0, 0, 0.45);
    for (int k = 0; k < photos; ++k) {
      const double a = k * 0.3;
      truth.push_back(LookAt({3.2 * std::cos(a), 3.2 * std::sin(a), 1.5 - 0.1 * (k % 2)}, target));
    }
  }
  EngineCapture(const EngineCapture&) = delete;
  static std::string Name(int k) { return fmt::format("p{}.png", k); }
  // The engine places photo k at its true pose.
  void Place(int k) { engine.table[Name(k)] = {Name(k), capture.camera(), truth[k]}; }
  void Drop(int k) const {
    capture.Drop(watch, fmt::format("p{}", k), truth[k], k);
    fs::remove(watch / fmt::format("p{}.json", k));  // no sidecar: the engine places it
  }

  fs::path watch;
  DemoCapture capture{240, 180};
  TableRegistrar engine;
  LiveOptions options;
  std::vector<camera::Pose> truth;
};

nlohmann::json FindPhoto(const nlohmann::json& api, const std::string& name) {
  for (const auto& p : api["photos"])
    if (p["name"] == name) return p;
  return nlohmann::json();
}

TEST(PoseUpdateTest, SessionTakesOverAFrameMovedByBundleAdjustment) {
  EngineCapture c(7);
  const LiveOptions& o = c.options;
  const fs::path& run = o.out;
  const DemoCapture& capture = c.capture;
  TableRegistrar& engine = c.engine;
  const std::vector<camera::Pose>& truth = c.truth;
  const auto name = &EngineCapture::Name;
  auto drop = [&](int k) { c.Drop(k); };
  const auto find = &FindPhoto;
  const double s = 2.0;
  std::map<std::string, Image> old_depth;
  Image before_restart;
  {
    LiveSession session(o);
    for (int k = 0; k < 6; ++k) {
      engine.table[name(k)] = {name(k), capture.camera(), truth[k]};
      drop(k);
      session.HandleReady(name(k));
    }
    for (int k = 0; k < 6; ++k) {
      const fs::path d = run / "depth" / (name(k) + ".bin");
      ASSERT_TRUE(fs::exists(d)) << name(k);
      old_depth[name(k)] = ibr::ReadDepthMap(d);
    }
    // The engine's bundle adjustment: the whole frame moves (scale 2, turned, shifted), and
    // photo 2 turns by 1 degree more (a refinement of that photo against the others).
    for (int k = 0; k < 7; ++k)
      engine.table[name(k)] = {name(k), capture.camera(), Moved(truth[k], s, kQ, kT)};
    engine.table[name(2)].cam_from_world = Turned(engine.table[name(2)].cam_from_world, 1.0);
    // The next photo arrives in the new frame.
    drop(6);
    session.HandleReady(name(6));
    const nlohmann::json api = session.Api();
    for (int k = 0; k < 7; ++k) {
      const nlohmann::json p = find(api, name(k));
      ASSERT_FALSE(p.is_null()) << name(k);
      EXPECT_EQ(p["status"], "registered") << name(k) << " " << p["message"];
      const camera::Pose want = engine.table[name(k)].cam_from_world;
      const Eigen::Vector4d q = want.Quaternion();
      for (int i = 0; i < 3; ++i)
        EXPECT_NEAR(p["tvec"][i].get<double>(), want.translation[i], 1e-9);
      for (int i = 0; i < 4; ++i) EXPECT_NEAR(p["qvec"][i].get<double>(), q[i], 1e-9);
      EXPECT_TRUE(p["has_depth"].get<bool>()) << name(k);
      EXPECT_FALSE(p["depth_stale"].get<bool>()) << name(k);  // photo 2 estimated again
    }
    // Photos that only moved with the frame: depth x 2 (camera-frame z scales with it). The
    // file stays as estimated; the record says by how much it is scaled now.
    for (int k : {0, 1, 3, 4, 5}) {
      const Image d = ibr::ReadDepthMap(run / "depth" / (name(k) + ".bin"));
      const Image& b = old_depth[name(k)];
      ASSERT_EQ(d.pixel_count(), b.pixel_count());
      EXPECT_EQ(0, std::memcmp(d.data(), b.data(), d.pixel_count() * sizeof(float))) << name(k);
      EXPECT_NEAR(find(api, name(k))["depth_scale"].get<double>(), s, 1e-9) << name(k);
    }
    EXPECT_EQ(find(api, name(2))["depth_scale"].get<double>(), 1.0);  // estimated again
    EXPECT_EQ(find(api, name(6))["depth_scale"].get<double>(), 1.0);
    // Photo 2 was estimated again in the new frame: about twice as deep, but not the old map
    // scaled (its pose changed relative to the others).
    {
      const Image d = ibr::ReadDepthMap(run / "depth" / (name(2) + ".bin"));
      const Image& b = old_depth[name(2)];
      double ratio_sum = 0;
      size_t n = 0, differ = 0;
      for (size_t i = 0; i < d.pixel_count(); ++i) {
        if (!std::isfinite(b.data()[i]) || !std::isfinite(d.data()[i])) continue;
        ratio_sum += d.data()[i] / b.data()[i];
        ++n;
        differ += std::abs(d.data()[i] - s * b.data()[i]) > 1e-4 * s * b.data()[i];
      }
      ASSERT_GT(n, 100u);
      EXPECT_NEAR(ratio_sum / n, s, 0.2);
      EXPECT_GT(differ, n / 10);
    }
    // The new photo is predicted from the earlier ones in the new frame.
    const nlohmann::json last = find(api, name(6));
    std::printf("p6 after the frame moved: completeness %.3f, 1-NCC %.3f\n",
                last["completeness"].get<double>(), last["error"].get<double>());
    EXPECT_GT(last["completeness"].get<double>(), 0.3);
    EXPECT_LT(last["error"].get<double>(), 0.6);
    // The live prediction at photo 6's pose with the scaled depth maps, kept for the comparison
    // after the restart below.
    const std::optional<render::Rephoto> r =
        session.Predict(capture.camera(), engine.table[name(6)].cam_from_world);
    ASSERT_TRUE(r.has_value());
    before_restart = r->color;
  }
  // A restart keeps the new poses and the scaled depth: the same prediction, bit for bit.
  LiveSession resumed(o);
  {
    const std::optional<render::Rephoto> r =
        resumed.Predict(capture.camera(), engine.table[name(6)].cam_from_world);
    ASSERT_TRUE(r.has_value());
    ASSERT_EQ(r->color.size(), before_restart.size());
    EXPECT_EQ(0, std::memcmp(r->color.data(), before_restart.data(),
                             before_restart.size() * sizeof(float)));
  }
  const nlohmann::json api = resumed.Api();
  for (int k = 0; k < 7; ++k) {
    const nlohmann::json p = find(api, name(k));
    const camera::Pose want = engine.table[name(k)].cam_from_world;
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(p["tvec"][i].get<double>(), want.translation[i], 1e-9);
  }
}

// A photo the engine cannot place when it arrives is unregistered, and looked up again after
// every later registration (COLMAP's image_registrator tries every unplaced image of its
// database with each new photo): once the engine places it, it is predicted from the photos
// registered by then and added under its first arrival number. A restart retries it too.
TEST(PoseUpdateTest, PhotosWaitingForTheEngineSayWhy) {
  // An engine that cannot build its first model yet (COLMAP's failed bootstrap `mapper`): the
  // photos wait, and the API (and so the page) says why; once it places them they are listed.
  EngineCapture c(3);
  TableRegistrar& engine = c.engine;
  const auto name = &EngineCapture::Name;
  LiveSession session(c.options);
  engine.defer = "colmap mapper failed (exit 1): ERROR: failed to create sparse model";
  for (int k : {0, 1}) {
    c.Place(k);
    c.Drop(k);
    session.HandleReady(name(k));
  }
  nlohmann::json api = session.Api();
  EXPECT_EQ(api["waiting"], 2);
  EXPECT_EQ(api["photos"].size(), 0u);
  EXPECT_EQ(api["waiting_reason"],
            "2 photos wait for the registration engine: " + engine.defer);
  engine.defer.clear();
  c.Place(2);
  c.Drop(2);
  session.HandleReady(name(2));
  api = session.Api();
  EXPECT_EQ(api["waiting"], 0);
  EXPECT_EQ(api["waiting_reason"], "");
  EXPECT_EQ(api["photos"].size(), 3u);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(FindPhoto(api, name(k))["status"], "registered") << k;
}

TEST(PoseUpdateTest, SessionPlacesAPhotoTheEngineCouldNotPlaceAtFirst) {
  EngineCapture c(8);
  const LiveOptions& o = c.options;
  const DemoCapture& capture = c.capture;
  TableRegistrar& engine = c.engine;
  const std::vector<camera::Pose>& truth = c.truth;
  const auto name = &EngineCapture::Name;
  auto drop = [&](int k, bool placed) {
    if (placed) c.Place(k);
    c.Drop(k);
  };
  const auto find = &FindPhoto;
  int64_t arrival = -1;
  {
    LiveSession session(o);
    for (int k : {0, 1, 2, 3}) {
      drop(k, true);
      session.HandleReady(name(k));
    }
    drop(4, false);  // the engine cannot place it yet
    session.HandleReady(name(4));
    nlohmann::json p = find(session.Api(), name(4));
    ASSERT_EQ(p["status"], "unregistered") << p.dump();
    arrival = p["arrival"].get<int64_t>();
    // A later photo connects it: the engine places both with the next registration.
    engine.table[name(4)] = {name(4), capture.camera(), truth[4]};
    drop(5, true);
    session.HandleReady(name(5));
    const nlohmann::json api = session.Api();
    p = find(api, name(4));
    EXPECT_EQ(p["status"], "registered") << p.dump();
    EXPECT_EQ(p["arrival"].get<int64_t>(), arrival);
    EXPECT_GT(p["completeness"].get<double>(), 0.3) << p.dump();
    EXPECT_LT(p["error"].get<double>(), 0.6) << p.dump();
    for (int i = 0; i < 3; ++i)
      EXPECT_NEAR(p["tvec"][i].get<double>(), truth[4].translation[i], 1e-9);
    EXPECT_EQ(find(api, name(5))["status"], "registered");
    // Another photo the engine cannot place, then a stop.
    drop(6, false);
    session.HandleReady(name(6));
    ASSERT_EQ(find(session.Api(), name(6))["status"], "unregistered");
  }
  // After a restart it is retried with the next registration as well.
  engine.table[name(6)] = {name(6), capture.camera(), truth[6]};
  LiveSession resumed(o);
  drop(7, true);
  resumed.HandleReady(name(7));
  const nlohmann::json api = resumed.Api();
  EXPECT_EQ(find(api, name(6))["status"], "registered") << find(api, name(6)).dump();
  EXPECT_EQ(find(api, name(7))["status"], "registered");
  EXPECT_EQ(api["photos"].size(), 8u);
}

TEST(PoseUpdateTest, AnIdleEnginePlacesWhatItCouldNotPlaceWhilePhotosArrived) {
  // COLMAP's re-map waits for more photos after one that placed nothing; when the capture
  // pauses it runs anyway (colmap_registrar.h). The session asks the engine only when photos
  // wait for a pose, and places what the engine placed then as after a registration.
  EngineCapture c(5);
  TableRegistrar& engine = c.engine;
  const auto name = &EngineCapture::Name;
  LiveSession session(c.options);
  for (int k : {0, 1, 2, 3}) {
    c.Place(k);
    c.Drop(k);
    session.HandleReady(name(k));
  }
  EXPECT_FALSE(session.Idle());
  EXPECT_EQ(engine.idle_calls, 0);  // nothing waits: the engine is not asked
  c.Drop(4);
  session.HandleReady(name(4));
  nlohmann::json p = FindPhoto(session.Api(), name(4));
  ASSERT_EQ(p["status"], "unregistered") << p.dump();
  const int64_t arrival = p["arrival"].get<int64_t>();
  EXPECT_FALSE(session.Idle());  // the engine placed nothing
  EXPECT_EQ(engine.idle_calls, 1);
  engine.on_idle[name(4)] = {name(4), c.capture.camera(), c.truth[4]};
  EXPECT_TRUE(session.Idle());
  p = FindPhoto(session.Api(), name(4));
  EXPECT_EQ(p["status"], "registered") << p.dump();
  EXPECT_EQ(p["arrival"].get<int64_t>(), arrival);
  EXPECT_GT(p["completeness"].get<double>(), 0.3) << p.dump();
  EXPECT_LT(p["error"].get<double>(), 0.6) << p.dump();
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(p["tvec"][i].get<double>(), c.truth[4].translation[i], 1e-9);
  EXPECT_EQ(session.Api()["photos"].size(), 5u);
  EXPECT_FALSE(session.Idle());  // nothing waits any more
  EXPECT_EQ(engine.idle_calls, 2);
}

}  // namespace
}  // namespace rephoto::live
