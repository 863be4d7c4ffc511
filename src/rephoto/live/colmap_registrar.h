// Registering photos without a pose sidecar with COLMAP 3.8 (Debian `colmap`, CPU SIFT), driven
// as subprocesses (cluster::RunProgram: own process group, stdin /dev/null), each under
// coreutils `timeout` (`timeout_seconds`, then SIGKILL 10 s later), QT_QPA_PLATFORM=offscreen.
//
// Workspace W (inside the run folder, so resume keeps it):
//   W/images/<name>   hard links (or copies) of the photos added so far
//   W/database.db     COLMAP's database: one camera shared by all photos (single_camera,
//                     SIMPLE_RADIAL, focal length from the image size as COLMAP guesses it)
//   W/sparse/0        the model (binary)
// Register(photo):
//   1. feature_extractor on the new image only (--image_list_path), into the database;
//   2. exhaustive_matcher (COLMAP skips pairs already matched, so each call matches only the
//      new image's pairs: cost linear in the photos so far);
//   3. before a model exists: kDeferred until `bootstrap` photos were added, then `mapper` on
//      all of them (the initial reconstruction); photos it placed are registered;
//   4. with a model: image_registrator (the new image into sparse/0, with COLMAP's local bundle
//      adjustment around it), point_triangulator (new tracks), and, when bundle_every > 0,
//      every bundle_every registrations a global bundle_adjuster; the photo is registered when
//      the model then holds it, else kFailed ("COLMAP could not register it").
// Poses are read from W/sparse/0 (scene/colmap.h) in COLMAP's world frame. AllPlaced returns
// every photo of that model with its current pose: image_registrator's local bundle adjustment
// and a global bundle_adjuster refine the poses of photos placed earlier, and the session takes
// them over (live_session.h, pose_update.h). Global bundle adjustment is off by default (it
// moves the whole frame: gauge and scale are free). Before the poses were taken over, with
// bundle_every = 10 every fern photo after the 10th was predicted with 1-NCC 0.73-0.81
// (unrelated content: the frame had moved), against 0.21-0.35 without it (docs/live.md).
// Thread safety: one registrar per workspace, used from one thread.
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "rephoto/live/live_session.h"

namespace rephoto::live {

struct ColmapRegistrarOptions {
  std::filesystem::path workspace;
  std::string colmap = "colmap";
  int bootstrap = 5;            // photos before the first `mapper`
  int bundle_every = 0;         // registrations between global bundle adjustments (0 = never)
  double timeout_seconds = 600; // per COLMAP call
  int max_image_size = 1600;    // SiftExtraction.max_image_size
};

std::unique_ptr<Registrar> MakeColmapRegistrar(const ColmapRegistrarOptions& options);

}  // namespace rephoto::live
