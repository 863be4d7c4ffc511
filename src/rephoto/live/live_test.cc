// rephoto live: sidecars, the folder watcher (partial files, temporary names), the per-photo
// pipeline on a simulated capture of the demo scene (statuses of bad files, prediction before
// joining, suggestions in the sidecar's shape), resume and the one-writer lock.
#include <fcntl.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/io/image_io.h"
#include "rephoto/live/demo_capture.h"
#include "rephoto/live/live_model.h"
#include "rephoto/live/live_session.h"
#include "rephoto/live/sidecar.h"
#include "rephoto/live/watcher.h"
#include "rephoto/render/render_model.h"
#include "rephoto/testing/testing.h"

namespace rephoto::live {
namespace {
namespace fs = std::filesystem;

TEST(SidecarTest, RoundTripAndErrors) {
  camera::Camera cam{camera::CameraModel::kPinhole, 640, 480, {600, 610, 320, 240}};
  const camera::Pose pose = LookAt({3, 0, 1.5}, {0, 0, 0.5});
  const PoseSidecar s = ParseSidecar(SidecarJson(cam, pose).dump(), "a.json");
  EXPECT_EQ(s.camera, cam);
  EXPECT_LT((s.cam_from_world.rotation - pose.rotation).norm(), 1e-12);
  EXPECT_LT((s.cam_from_world.translation - pose.translation).norm(), 1e-12);
  // Centre of the camera = (3, 0, 1.5) as given (COLMAP world-to-camera convention).
  EXPECT_LT((s.cam_from_world.Center() - Eigen::Vector3d(3, 0, 1.5)).norm(), 1e-12);
  EXPECT_NE(testing::ErrorOf([] { ParseSidecar("{", "b.json"); }).find("b.json: not valid JSON"),
            std::string::npos);
  std::string bad = SidecarJson(cam, pose).dump();
  bad = testing::Replace(bad, "PINHOLE", "PINHOLO");
  EXPECT_NE(testing::ErrorOf([&] { ParseSidecar(bad, "c.json"); }).find("unknown camera model"),
            std::string::npos);
  nlohmann::json j = SidecarJson(cam, pose);
  j["qvec"] = {2, 0, 0, 0};
  EXPECT_NE(testing::ErrorOf([&] { ParseSidecar(j.dump(), "d.json"); }).find("unit quaternion"),
            std::string::npos);
  j = SidecarJson(cam, pose);
  j["camera"]["params"] = {1, 2, 3};
  EXPECT_NE(testing::ErrorOf([&] { ParseSidecar(j.dump(), "e.json"); }).find("4 numbers"),
            std::string::npos);
}

TEST(WatcherTest, TemporaryNames) {
  for (const char* n : {".hidden.jpg", "~a.jpg", "a.jpg~", "a.jpg.part", "a.tmp", "a.png.tmp-123",
                        "a.crdownload"})
    EXPECT_TRUE(IsTemporaryName(n)) << n;
  for (const char* n : {"a.jpg", "IMG_0001.JPG", "a.json", "tmp.png"}) EXPECT_FALSE(IsTemporaryName(n)) << n;
}

TEST(WatcherTest, PartialFileIsNotReadUntilClosedOrStable) {
  const fs::path dir = testing::MakeTempDir();
  FolderWatcher w(dir, /*stable_seconds=*/1.5);
  // A file being written (open, not closed): not ready while it grows, nor before it is stable.
  const int fd = ::open((dir / "partial.jpg").c_str(), O_WRONLY | O_CREAT, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::write(fd, "abc", 3), 3);
  EXPECT_TRUE(w.Poll(0.2).empty());
  ASSERT_EQ(::write(fd, "def", 3), 3);
  EXPECT_TRUE(w.Poll(0.2).empty());
  // A temporary name is never delivered; a closed file at once.
  testing::WriteFile(dir / "x.jpg.part", "zz");
  testing::WriteFile(dir / "done.png", "12345");
  std::vector<std::string> r = w.Poll(0.2);
  ASSERT_EQ(r, std::vector<std::string>{"done.png"});
  // Closing the partial file makes it ready (IN_CLOSE_WRITE) with its full content.
  ::close(fd);
  r = w.Poll(0.5);
  EXPECT_EQ(r, std::vector<std::string>{"partial.jpg"});
  EXPECT_EQ(fs::file_size(dir / "partial.jpg"), 6u);
  // Size-stable rule: a file that existed before the watcher started is delivered once its size
  // stayed the same for stable_seconds (no event for it).
  const fs::path dir2 = testing::MakeTempDir() / "w2";
  fs::create_directories(dir2);
  testing::WriteFile(dir2 / "old.jpg", "1");
  FolderWatcher w2(dir2, 0.6);
  EXPECT_TRUE(w2.Poll(0.0).empty());
  usleep(700000);
  EXPECT_EQ(w2.Poll(0.0), std::vector<std::string>{"old.jpg"});
  EXPECT_TRUE(w2.Poll(0.0).empty());  // once per version
  // Renamed into the folder (IN_MOVED_TO): ready at once.
  WriteTextFileAtomically(dir2 / "moved.json", "{}");
  EXPECT_EQ(w2.Poll(0.5), std::vector<std::string>{"moved.json"});
}

TEST(EnvelopeTest, SphereDepthGivesSphereAndUnseenBackside) {
  // Depth maps of a sphere (radius 0.5 at the origin) seen by 6 cameras on one side: the
  // envelope's observed radii are 0.5 (closed form), its back side is unobserved.
  camera::Camera cam{camera::CameraModel::kPinhole, 160, 120, {160, 160, 80, 60}};
  std::vector<camera::Pose> poses;
  std::vector<Image> depths;
  for (int k = 0; k < 6; ++k) {
    const double a = k * 0.25;
    poses.push_back(LookAt({3 * std::cos(a), 3 * std::sin(a), 0.3}, {0, 0, 0}));
    Image d(160, 120, 1, std::nanf(""));
    const Eigen::Vector3d c = poses.back().Center();
    const Eigen::Matrix3d wfc = poses.back().rotation.transpose();
    for (int y = 0; y < 120; ++y)
      for (int x = 0; x < 160; ++x) {
        const Eigen::Vector3d ray = *cam.CamFromImg({x + 0.5, y + 0.5});
        const Eigen::Vector3d dir = (wfc * ray).normalized();
        const double b = dir.dot(c), disc = b * b - (c.squaredNorm() - 0.25);
        if (disc < 0) continue;
        const double t = -b - std::sqrt(disc);
        d.at(x, y) = static_cast<float>((t * dir).dot(wfc.col(2)));
      }
    depths.push_back(d);
  }
  std::vector<EnvelopeInput> in;
  for (size_t k = 0; k < poses.size(); ++k) in.push_back({cam, poses[k], &depths[k]});
  EnvelopeOptions eo;
  eo.stride = 1;
  const Envelope env = BuildEnvelope(poses, in, eo);
  EXPECT_LT(env.center.norm(), 0.05);  // axes meet at the origin
  size_t observed = 0;
  for (size_t v = 0; v < env.observed.size(); ++v) {
    if (!env.observed[v]) continue;
    ++observed;
    EXPECT_NEAR((env.mesh.positions[v].cast<double>() - env.center).norm(), 0.5, 0.03);
    // Observed directions lie on the part of the sphere some camera sees: within
    // acos(0.5 / 3) = 80.4 degrees of a camera's direction (closed form), give or take a
    // grid cell (7.5 degrees).
    const Eigen::Vector3d d = (env.mesh.positions[v].cast<double>() - env.center).normalized();
    double best = -1;
    for (const auto& p : poses) best = std::max(best, d.dot(p.Center().normalized()));
    EXPECT_GT(best, std::cos((80.4 + 8) * M_PI / 180));
  }
  EXPECT_GT(observed, 50u);
  EXPECT_GT(env.ObservedFraction(), 0.15);
  EXPECT_LT(env.ObservedFraction(), 0.6);
}

TEST(EnvelopeTest, UpFromLevelCamerasLookingDownFromOneSide) {
  // Four level cameras (x axis horizontal) on one side looking down 18 degrees at a point: up
  // is orthogonal to their x axes, (0, 0, 1) (closed form). The mean of their -y axes leans
  // toward their backs (here by about 17 degrees).
  std::vector<camera::Pose> poses;
  for (double a : {0.0, 20.0, 40.0, 60.0}) {
    const double r = a * M_PI / 180;
    poses.push_back(LookAt({3.2 * std::cos(r), 3.2 * std::sin(r), 1.5}, {0, 0, 0.45}));
  }
  const Eigen::Vector3d up = UpDirection(poses);
  EXPECT_NEAR(up.z(), 1.0, 1e-9);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : poses) mean -= p.rotation.row(1).transpose();
  EXPECT_LT(mean.normalized().z(), std::cos(10 * M_PI / 180));
}

TEST(PlanTest, ViewCoverageGivesALonePhotoItsPartnerFirst) {
  // No unseen surface left (need 0 everywhere): the planner chooses by view-space coverage.
  // Photos at azimuths 0, 20, 40 (partners of each other) and 180 (alone), all 18 degrees up.
  // With a stereo partner within 25 degrees required, the lone photo covers nothing until a
  // photo is taken beside it, so the first suggestion lies within 25 degrees of it. With every
  // photo counting (partner 0), the largest gap of view space is the side between 180 and 360
  // degrees, so the suggestion lies there, at least 45 degrees from every photo.
  const Eigen::Vector3d target(0, 0, 0.45);
  std::vector<camera::Pose> poses;
  std::vector<Eigen::Vector3d> dirs;
  for (double a : {0.0, 20.0, 40.0, 180.0}) {
    const double r = a * M_PI / 180;
    poses.push_back(LookAt({3.2 * std::cos(r), 3.2 * std::sin(r), 1.5}, target));
    dirs.push_back((poses.back().Center() - target).normalized());
  }
  const Envelope env = BuildEnvelope(poses, {}, EnvelopeOptions());
  ASSERT_NEAR((env.center - target).norm(), 0.0, 1e-6);
  const render::RenderModel surface(env.mesh);
  const camera::Camera cam{camera::CameraModel::kPinhole, 160, 120, {160, 160, 80, 60}};
  auto plan = [&](double partner, float need_value) {
    PlanOptions o;
    o.count = 1;
    o.stereo_partner_degrees = partner;
    const std::vector<float> need(env.mesh.positions.size(), need_value);
    const std::vector<PlannedView> p = PlanNextViews(surface, env, need, poses, cam, o);
    EXPECT_EQ(p.size(), 1u);
    return p.empty() ? PlannedView() : p[0];
  };
  auto degrees_to = [&](const PlannedView& v, size_t k) {
    const Eigen::Vector3d d = (v.cam_from_world.Center() - target).normalized();
    return std::acos(std::clamp(d.dot(dirs[k]), -1.0, 1.0)) * 180 / M_PI;
  };
  const PlannedView paired = plan(25, 0.f);
  EXPECT_TRUE(paired.view_coverage);
  EXPECT_GT(paired.coverage_gain, 0);
  EXPECT_LE(degrees_to(paired, 3), 25.0);
  const PlannedView open = plan(0, 0.f);
  EXPECT_TRUE(open.view_coverage);
  for (size_t k = 0; k < dirs.size(); ++k) EXPECT_GE(degrees_to(open, k), 45.0) << k;
  const Eigen::Vector3d c = open.cam_from_world.Center() - target;
  EXPECT_LT(c.y(), 0);  // between 180 and 360 degrees
  // All surface unseen (need 1): the surface rule chooses, not view coverage.
  EXPECT_FALSE(plan(25, 1.f).view_coverage);
}

// Exact depth maps (160 x 120, focal 160) of a sphere (radius 0.5 centred at (0, 0, 0.5))
// standing on the floor z = 0 over [-2, 2]^2, from 8 cameras on a ring (radius 3, height 1.5)
// looking at (0, 0, 0.45). `surface(c, dir, t_sphere, t_floor)` returns the ray parameter of the
// depth at camera centre c along the unit direction dir (infinite: no depth) from those of the
// sphere and the floor (infinite where the ray misses them); the default is the nearer one.
struct SphereOnFloor {
  camera::Camera camera{camera::CameraModel::kPinhole, 160, 120, {160, 160, 80, 60}};
  std::vector<camera::Pose> poses;
  std::vector<Image> depths;
  std::vector<EnvelopeInput> Inputs() const {
    std::vector<EnvelopeInput> in;
    for (size_t k = 0; k < poses.size(); ++k) in.push_back({camera, poses[k], &depths[k]});
    return in;
  }
};
SphereOnFloor MakeSphereOnFloor(
    const std::function<double(const Eigen::Vector3d&, const Eigen::Vector3d&, double, double)>&
        surface = [](const Eigen::Vector3d&, const Eigen::Vector3d&, double ts, double tf) {
          return std::min(ts, tf);
        }) {
  SphereOnFloor s;
  const Eigen::Vector3d centre(0, 0, 0.5);
  const double inf = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 8; ++k) {
    const double a = k * M_PI / 4;
    s.poses.push_back(LookAt({3 * std::cos(a), 3 * std::sin(a), 1.5}, {0, 0, 0.45}));
    Image d(160, 120, 1, std::nanf(""));
    const Eigen::Vector3d c = s.poses.back().Center();
    const Eigen::Matrix3d wfc = s.poses.back().rotation.transpose();
    for (int y = 0; y < 120; ++y)
      for (int x = 0; x < 160; ++x) {
        const Eigen::Vector3d dir = (wfc * *s.camera.CamFromImg({x + 0.5, y + 0.5})).normalized();
        const Eigen::Vector3d oc = c - centre;
        const double b = dir.dot(oc), disc = b * b - (oc.squaredNorm() - 0.25);
        const double ts = disc >= 0 ? -b - std::sqrt(disc) : inf;
        double tf = inf;
        if (dir.z() < 0) {
          const double t = -c.z() / dir.z();
          const Eigen::Vector3d hit = c + t * dir;
          if (std::abs(hit.x()) <= 2 && std::abs(hit.y()) <= 2) tf = t;
        }
        const double t = surface(c, dir, ts, tf);
        if (std::isfinite(t)) d.at(x, y) = static_cast<float>((t * dir).dot(wfc.col(2)));
      }
    s.depths.push_back(d);
  }
  return s;
}

TEST(EnvelopeTest, ObjectOnAFloorGivesSupportPlaneAndNoSpikes) {
  // Exact depth maps of a sphere (radius 0.5 centred at (0, 0, 0.5)) standing on the plane
  // z = 0, seen by 8 cameras on a ring (radius 3, height 1.5): the support plane is z = 0, its
  // cells cover the seen floor, no envelope vertex lies below the floor, and every observed
  // vertex lies on the sphere or on the floor (closed form).
  const SphereOnFloor scene = MakeSphereOnFloor();
  const Eigen::Vector3d centre(0, 0, 0.5);
  EnvelopeOptions eo;
  eo.stride = 2;
  const Envelope env = BuildEnvelope(scene.poses, scene.Inputs(), eo);
  ASSERT_FALSE(env.support.faces.empty());
  EXPECT_NEAR(env.support_plane.z(), 1.0, 1e-4);
  EXPECT_NEAR(env.support_plane[3], 0.0, 2e-3);
  size_t on_sphere = 0;
  for (size_t v = 0; v < env.mesh.positions.size(); ++v) {
    const Eigen::Vector3d x = env.mesh.positions[v].cast<double>();
    EXPECT_GT(x.z(), -2e-3);
    if (!env.observed[v] || x.z() < 0.01) continue;
    ++on_sphere;
    // Observed directions away from the floor: on the sphere, give or take the grid's chord
    // and the 20th-percentile radius within a bin (7.5 degree cells).
    EXPECT_NEAR((x - centre).norm(), 0.5, 0.03) << x.transpose();
  }
  EXPECT_GT(on_sphere, 500u);
  // The floor cells: every support vertex lies on z = 0 within [-2, 2]^2 (plus one cell).
  for (const auto& p : env.support.positions) {
    EXPECT_NEAR(p.z(), 0.0, 2e-3);
    EXPECT_LT(std::max(std::abs(p.x()), std::abs(p.y())), 2.0 + 4.5 / 96 + 1e-3);
  }
}

// What plane sweep did on the demo at 560 x 420: where the sphere's underside near the floor is
// missing from the depth maps (here at azimuths 40-100 degrees), a patch of wrong floor depths
// (here a raised patch of floor at z = 0.15, 0.8-1.1 from the axis, azimuths 65-70 degrees, in
// every depth map that sees it) fills a bin of directions with points twice as far as the
// sphere. Its vertex has fewer than 3 observed grid neighbours (the missing underside beside it
// is not observed); compared with the observed vertices within two grid steps it takes their
// radius, so no vertex off the floor reaches beyond the sphere (0.5 from the axis; 0.7 leaves
// room for the grid) toward the patch. Skipped as too thinly surrounded to judge (the rule
// before the seventh stop of 2026-11-28), it stays 0.88 from the axis.
TEST(EnvelopeTest, SpikesAtTheEdgeOfWhatWasSeenAreRemoved) {
  auto in_sector = [](const Eigen::Vector3d& p, double from, double to) {
    const double az = std::atan2(p.y(), p.x()) * 180 / M_PI;
    return az >= from && az <= to;
  };
  const SphereOnFloor scene = MakeSphereOnFloor(
      [&](const Eigen::Vector3d& c, const Eigen::Vector3d& dir, double ts, double tf) {
        const double inf = std::numeric_limits<double>::infinity();
        double t = tf;
        if (dir.z() < 0) {  // the raised patch of floor
          const double tp = (0.15 - c.z()) / dir.z();
          const Eigen::Vector3d patch = c + tp * dir;
          const double hd = std::hypot(patch.x(), patch.y());
          if (hd >= 0.8 && hd <= 1.1 && in_sector(patch, 65, 70)) t = std::min(t, tp);
        }
        if (ts < t) {  // the sphere in front: no depth on its underside in the sector
          const Eigen::Vector3d hit = c + ts * dir;
          return hit.z() < 0.35 && in_sector(hit, 40, 100) ? inf : ts;
        }
        return t;
      });
  const Envelope env = BuildEnvelope(scene.poses, scene.Inputs(), EnvelopeOptions{});
  ASSERT_FALSE(env.support.faces.empty());
  size_t observed_in_sector = 0;
  for (size_t v = 0; v < env.mesh.positions.size(); ++v) {
    const Eigen::Vector3d x = env.mesh.positions[v].cast<double>();
    if (x.z() < 0.01) continue;  // on the floor
    EXPECT_LT(std::hypot(x.x(), x.y()), 0.7) << "vertex " << v << " at " << x.transpose();
    if (env.observed[v] && in_sector(x, 65, 70) && x.z() < 0.35) ++observed_in_sector;
  }
  // The patch's bins were observed (the test covers the spike rule, not the point filters).
  EXPECT_GT(observed_in_sector, 0u);
}

TEST(EnvelopeTest, SupportPlaneOfPlaneSweepDepthIsTheFloor) {
  // Plane-sweep depth of demo photos (the live session's settings: 320 px, 64 planes, NCC 0.3,
  // each photo against the others) of a ring on one side (radius 3.2, height 1.5, azimuths
  // 0-140 degrees): its floor points are noisiest far from the cameras, at grazing angles. The
  // demo's floor is z = 0 exactly (independent of the code under test): the support plane is
  // within 0.05 degree and 2 mm of it. (A single least-squares refit of RANSAC's inlier band
  // was 0.2-0.5 degree and 2-6 mm off on such captures.)
  const fs::path dir = testing::MakeTempDir();
  DemoCapture capture(320, 240);
  std::vector<camera::Pose> poses;
  std::vector<ibr::TrainingView> views;
  for (int k = 0; k < 8; ++k) {
    const double a = k * 20 * M_PI / 180;
    poses.push_back(LookAt({3.2 * std::cos(a), 3.2 * std::sin(a), 1.5}, {0, 0, 0.45}));
    const std::string stem = "p" + std::to_string(k);
    views.push_back({stem, capture.camera(), poses.back(),
                     capture.Drop(dir, stem, poses.back(), static_cast<uint64_t>(k) + 1), {}, {}});
  }
  ibr::ImageBasedOptions o;
  o.plane_sweep.max_width = 320;
  o.plane_sweep.num_planes = 64;
  o.plane_sweep.min_ncc = 0.3;
  o.sweep_min_consistent = 0;
  std::vector<Image> depths(views.size());
  for (size_t k = 0; k < views.size(); ++k) {
    std::vector<ibr::TrainingView> set{views[k]};
    for (size_t j = 0; j < views.size(); ++j)
      if (j != k) set.push_back(views[j]);
    std::vector<bool> estimate(set.size(), false);
    estimate[0] = true;
    depths[k] = std::move(ibr::EstimateDepthMaps(set, estimate, o)[0]);
  }
  std::vector<EnvelopeInput> in;
  for (size_t k = 0; k < poses.size(); ++k) in.push_back({capture.camera(), poses[k], &depths[k]});
  const Envelope env = BuildEnvelope(poses, in, EnvelopeOptions{});
  ASSERT_FALSE(env.support.faces.empty());
  const double tilt =
      std::acos(std::min(1.0, env.support_plane.head<3>().normalized().z())) * 180 / M_PI;
  std::printf("support plane (%.6f, %.6f, %.6f, %.6f): tilt %.3f degrees\n", env.support_plane[0],
              env.support_plane[1], env.support_plane[2], env.support_plane[3], tilt);
  EXPECT_LT(tilt, 0.05);
  EXPECT_NEAR(env.support_plane[3], 0.0, 2e-3);
  fs::remove_all(dir);
}

void WriteSidecarOnly(const fs::path& path, const camera::Camera& cam, const camera::Pose& pose) {
  WriteTextFileAtomically(path, SidecarJson(cam, pose).dump());
}

std::string StatusOf(const nlohmann::json& api, const std::string& name) {
  for (const auto& p : api["photos"])
    if (p["name"] == name) return p["status"];
  return "(none)";
}

TEST(LiveSessionTest, SimulatedCaptureStatusesPredictionsSuggestionsResume) {
  const fs::path base = testing::MakeTempDir();
  const fs::path watch = base / "watch", run = base / "run";
  fs::create_directories(watch);
  DemoCapture capture(240, 180);
  const Eigen::Vector3d target(0, 0, 0.45);
  LiveOptions o;
  o.watch = watch;
  o.out = run;
  o.predict_width = 240;
  o.depth_width = 240;
  o.candidates = 100;
  o.sidecar_wait = 0;
  std::vector<std::string> order;
  {
    LiveSession session(o);
    // One writer per run folder.
    EXPECT_NE(testing::ErrorOf([&] { LiveSession second(o); }).find("another rephoto live"),
              std::string::npos);
    for (int k = 0; k < 5; ++k) {
      const double a = k * 0.3;
      const std::string stem = fmt::format("ring_{}", k);
      capture.Drop(watch, stem, LookAt({3.2 * std::cos(a), 3.2 * std::sin(a), 1.5}, target), k);
      session.HandleReady(stem + ".json");  // sidecar first: nothing happens
      session.HandleReady(stem + ".png");
      order.push_back(stem + ".png");
    }
    // Bad files.
    testing::WriteFile(watch / "notes.txt", "not a photo");
    session.HandleReady("notes.txt");
    testing::WriteFile(watch / "broken.png", "\x89PNG\r\n\x1a\n truncated");
    session.HandleReady("broken.png");
    fs::copy_file(watch / "ring_1.png", watch / "copy_of_ring_1.png");
    session.HandleReady("copy_of_ring_1.png");
    // A blurred photo: the view of ring_2 box-filtered (15 px).
    {
      const Image sharp = io::ReadImage(watch / "ring_2.png");
      Image blurred = sharp;
      const int r = 7;
      for (int y = 0; y < sharp.height(); ++y)
        for (int x = 0; x < sharp.width(); ++x)
          for (int c = 0; c < 3; ++c) {
            double s = 0;
            int n = 0;
            for (int dy = -r; dy <= r; ++dy)
              for (int dx = -r; dx <= r; ++dx) {
                const int xx = std::clamp(x + dx, 0, sharp.width() - 1),
                          yy = std::clamp(y + dy, 0, sharp.height() - 1);
                s += sharp.at(xx, yy, c);
                ++n;
              }
            blurred.at(x, y, c) = static_cast<float>(s / n);
          }
      fs::copy_file(watch / "ring_2.json", watch / "shaky.json");
      io::WritePng(watch / "shaky.png", blurred);
      session.HandleReady("shaky.png");
    }
    // No sidecar and no registration engine: no_pose once the wait ran out.
    fs::copy_file(watch / "ring_3.png", watch / "lost.png");
    {
      // different content so it is not a duplicate
      Image im = io::ReadImage(watch / "lost.png");
      im.at(0, 0, 0) = 1 - im.at(0, 0, 0);
      io::WritePng(watch / "lost.png", im);
    }
    session.HandleReady("lost.png");
    EXPECT_EQ(session.waiting(), 1u);
    EXPECT_TRUE(session.Tick());
    // A sidecar whose camera does not match the photo.
    fs::copy_file(watch / "ring_4.png", watch / "odd.png");
    {
      Image im = io::ReadImage(watch / "odd.png");
      im.at(1, 1, 1) = 1 - im.at(1, 1, 1);
      io::WritePng(watch / "odd.png", im);
      camera::Camera wrong = capture.camera();
      wrong.width = 100;
      wrong.height = 100;
      wrong.params = {100, 100, 50, 50};
      WriteSidecarOnly(watch / "odd.json", wrong, LookAt({3, 0, 1}, target));
    }
    session.HandleReady("odd.png");

    // The photo first, its sidecar a moment later: the photo waits, the sidecar releases it.
    {
      const camera::Pose pose = LookAt({3.2 * std::cos(1.5), 3.2 * std::sin(1.5), 1.5}, target);
      io::WritePng(watch / "late.png", capture.Photograph(pose, 77));
      session.HandleReady("late.png");
      EXPECT_EQ(session.waiting(), 1u);
      EXPECT_EQ(StatusOf(session.Api(), "late.png"), "(none)");
      WriteSidecarOnly(watch / "late.json", capture.camera(), pose);
      session.HandleReady("late.json");
      EXPECT_EQ(session.waiting(), 0u);
      EXPECT_EQ(StatusOf(session.Api(), "late.png"), "registered");
    }
    // A registered photo rewritten with other content keeps its registration.
    {
      const std::string jsonl = ReadFileToString(run / "live.jsonl");
      fs::copy_file(watch / "ring_3.png", watch / "ring_0.png", fs::copy_options::overwrite_existing);
      session.HandleReady("ring_0.png");
      EXPECT_EQ(ReadFileToString(run / "live.jsonl"), jsonl);
      EXPECT_EQ(StatusOf(session.Api(), "ring_0.png"), "registered");
    }

    const nlohmann::json api = session.Api();
    EXPECT_EQ(StatusOf(api, "notes.txt"), "not_an_image");
    EXPECT_EQ(StatusOf(api, "broken.png"), "unreadable");
    EXPECT_EQ(StatusOf(api, "copy_of_ring_1.png"), "duplicate");
    EXPECT_EQ(StatusOf(api, "shaky.png"), "blurred");
    EXPECT_EQ(StatusOf(api, "lost.png"), "no_pose");
    EXPECT_EQ(StatusOf(api, "odd.png"), "bad_sidecar");
    // Registered photos in arrival order; the first has nothing to predict from, later ones
    // are predicted (completeness > 0.1 on a ring with 17 degree steps: plane-sweep depth at
    // 240 x 180 leaves holes) with a finite error.
    std::vector<nlohmann::json> reg;
    for (const auto& p : api["photos"])
      if (p["status"] == "registered") reg.push_back(p);
    ASSERT_EQ(reg.size(), 6u);  // the ring and late.png
    for (size_t k = 0; k < 5; ++k) EXPECT_EQ(reg[k]["name"], order[k]);
    EXPECT_EQ(reg[5]["name"], "late.png");
    EXPECT_EQ(reg[0]["completeness"], 0.0);
    EXPECT_TRUE(reg[0]["error"].is_null());
    for (size_t k = 2; k < 5; ++k) {
      EXPECT_GT(reg[k]["completeness"].get<double>(), 0.1) << reg[k].dump();
      EXPECT_GT(reg[k]["error"].get<double>(), 0.0);
      EXPECT_LT(reg[k]["error"].get<double>(), 0.6);
      EXPECT_TRUE(fs::exists(run / "predictions" / (order[k] + ".png")));
      EXPECT_TRUE(fs::exists(run / "errors" / (order[k] + ".1-ncc.exr")));
    }
    // Suggestions: K = 3, each in the sidecar's shape. The first one lies in the planner's
    // band, 8-90 degrees (seen from the look-at point) from the nearest photo, outside the
    // ring's own directions, and it newly sees unseen model surface.
    ASSERT_EQ(api["suggestions"].size(), 3u);
    const PoseSidecar s = ParseSidecar(api["suggestions"][0].dump(), "suggestion");
    const Eigen::Vector3d look(api["model"]["center"][0], api["model"]["center"][1],
                               api["model"]["center"][2]);
    const Eigen::Vector3d d = (s.cam_from_world.Center() - look).normalized();
    double nearest = 180;
    for (double a : {0.0, 0.3, 0.6, 0.9, 1.2, 1.5}) {  // the ring and late.png
      const Eigen::Vector3d p = (Eigen::Vector3d(3.2 * std::cos(a), 3.2 * std::sin(a), 1.5) - look).normalized();
      nearest = std::min(nearest, std::acos(std::clamp(d.dot(p), -1.0, 1.0)) * 180 / M_PI);
    }
    EXPECT_GE(nearest, 8 - 0.5);
    EXPECT_LE(nearest, 90 + 0.5);
    EXPECT_GT(api["suggestions"][0]["unseen_area_fraction"].get<double>(), 0.0);
    // One side photographed: the first suggestion is for the unseen surface.
    EXPECT_EQ(api["suggestions"][0]["chosen_by"], "surface");
    EXPECT_TRUE(fs::exists(run / "suggestions" / "sparse" / "images.txt"));
    EXPECT_TRUE(fs::exists(run / "suggestions" / "transforms.json"));
    EXPECT_TRUE(fs::exists(run / "model.ply"));
    EXPECT_GT(api["model"]["unseen_fraction"].get<double>(), 0.2);
  }
  // Resume: a new session reads live.jsonl; handing it the same files again redoes nothing.
  const std::string before = ReadFileToString(run / "live.jsonl");
  {
    LiveSession session(o);
    for (const std::string& n : order) session.HandleReady(n);
    session.HandleReady("notes.txt");
    EXPECT_EQ(ReadFileToString(run / "live.jsonl"), before);
    const nlohmann::json api = session.Api();
    size_t registered = 0;
    for (const auto& p : api["photos"]) registered += p["status"] == "registered";
    EXPECT_EQ(registered, 6u);
    EXPECT_EQ(api["suggestions"].size(), 3u);  // restored from suggestions/suggestions.json
    EXPECT_GT(api["model"]["unseen_fraction"].get<double>(), 0.2);
  }
  // Compaction: the log holds records appended again (depth maps estimated when a later photo
  // came); a copy of the run opened with no slack is rewritten at resume to the last record of
  // each name, in the order the names first appear, and resumes the same state.
  std::vector<nlohmann::json> records;
  {
    std::istringstream in(before);
    for (std::string line; std::getline(in, line);) records.push_back(nlohmann::json::parse(line));
  }
  std::vector<nlohmann::json> expected;
  std::map<std::string, size_t> slot;
  for (const nlohmann::json& r : records) {
    const std::string name = r["name"];
    if (!slot.count(name)) {
      slot[name] = expected.size();
      expected.push_back(r);
    } else {
      expected[slot[name]] = r;
    }
  }
  ASSERT_GT(records.size(), expected.size());  // something to compact
  const fs::path copy = base / "run-copy";
  fs::copy(run, copy, fs::copy_options::recursive);
  LiveOptions oc = o;
  oc.out = copy;
  oc.log_compaction_slack = 0;
  {
    LiveSession session(oc);
    auto lines = [&] {
      std::vector<nlohmann::json> out;
      std::istringstream in(ReadFileToString(copy / "live.jsonl"));
      for (std::string line; std::getline(in, line);) out.push_back(nlohmann::json::parse(line));
      return out;
    };
    EXPECT_EQ(lines(), expected);
    EXPECT_FALSE(fs::exists(copy / "live.jsonl.compact"));
    for (const std::string& n : order) session.HandleReady(n);  // nothing redone
    EXPECT_EQ(lines(), expected);
    const nlohmann::json api = session.Api();
    size_t registered = 0;
    for (const auto& p : api["photos"]) registered += p["status"] == "registered";
    EXPECT_EQ(registered, 6u);
  }
}

}  // namespace
}  // namespace rephoto::live
