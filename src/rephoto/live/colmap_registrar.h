// Registering photos without a pose sidecar with COLMAP 3.8 (Debian `colmap`, CPU SIFT), driven
// as subprocesses (cluster::RunProgram: own process group, stdin /dev/null), each under
// coreutils `timeout` (`timeout_seconds`, then SIGKILL 10 s later), QT_QPA_PLATFORM=offscreen,
// COLMAP's own log files (glog) in W/logs instead of /tmp.
//
// Workspace W (inside the run folder, so resume keeps it):
//   W/images/<name>   hard links (or copies) of the photos added so far
//   W/database.db     COLMAP's database: one camera shared by all photos of one size and
//                     focal prior (see "One camera" below)
//   W/sparse/0        the model (binary)
//   W/logs/           COLMAP's log files (colmap.<host>.<user>.log.INFO.<time>.<pid>)
// Register(photo):
//   1. feature_extractor on the new image only (--image_list_path), into the database;
//   2. matching ("Matching" below);
//   3. before a model exists: kDeferred until `bootstrap` photos were added, then `mapper` on
//      all of them (the initial reconstruction); photos it placed are registered;
//   4. with a model: image_registrator (the new image into sparse/0, with COLMAP's local bundle
//      adjustment around it), point_triangulator (new tracks), and, when bundle_every > 0,
//      every bundle_every registrations a global bundle_adjuster; the photo is registered when
//      the model then holds it, else kFailed ("COLMAP could not register it");
//   5. re-map: when a photo of the workspace is still not in the model after 4, `mapper` runs
//      from scratch on the whole database (all features and matches at once, with global
//      bundle adjustment and re-triangulation), and its largest model that keeps every placed
//      photo replaces sparse/0 when it places more (the session then takes over the moved poses,
//      AllPlaced). The incremental model holds only the 3D points its photos triangulated as they
//      came: on a sparse ring, the photo that closes the ring sees too few of them
//      (templeSparseRing in ring order: 14 and 5 points where 15 are needed, 14 of 16 placed),
//      while the batch mapper on the same database places all 16 (about 2 s). It runs only when an
//      unplaced photo has a verified two-view geometry (15 inliers) with a placed one (read
//      from COLMAP's database): a photo of another scene never triggers one. A re-map that places
//      no more doubles the number of new photos before the next one, so
//      the re-maps' cost stays bounded by a few batch mappings over the capture. When the
//      capture pauses (Registrar::Idle) the re-map runs regardless of that wait, once per set
//      of photos: the last photos of a capture are otherwise left to the wait (templeSparseRing
//      shuffled, seed 1: 14 of 16 placed at the end, the batch mapper on the same database
//      places 16).
// Registration thresholds: a photo is placed with at least 15 absolute-pose inliers making 10 %
// of its 2D-3D correspondences (COLMAP's defaults: 30 and 25 %), and the initial pair needs 50
// two-view inliers (COLMAP: 100). COLMAP's defaults are tuned for batch reconstruction of
// dense collections; on a sparse ring of a faintly textured object (Middlebury templeSparseRing:
// 16 photos 22.5 degrees apart, 150-800 SIFT features each) its own batch `mapper` placed 13 of
// 16 and the live registration 12. With these thresholds the batch mapper places all 16, and
// their camera centres agree with the dataset's calibration within 1.5 % of the ring's radius
// after a similarity. A photo of another scene
// still gets no pose: its matches fail the two-view geometric verification (15 inliers) before
// any pose is tried (live_colmap_test). Pose accuracy is unchanged for photos with many
// inliers (the thresholds only decide whether a pose is accepted).
// Matching: while the database holds at most match_all_up_to (30) earlier photos, the new
// photo is matched with all of them (exhaustive_matcher, which skips pairs already matched).
// A pair costs 0.25-0.31 s on 2 cores at 1600 pixels and 5,000-6,500 SIFT features
// (instant_ngp_fox: 15 s for the 50th photo), so a capture of hundreds of photos cannot match
// every pair per photo. After that, only chosen pairs (matches_importer): the match_recent (8)
// photos added just before it (a photographer walking round sees what they just saw) and the
// match_recent placed photos nearest to the last placed one (viewing directions within 60
// degrees, nearest centres first); when image_registrator places it from those, the
// match_around (12) placed photos nearest to its pose, so point_triangulator has its tracks;
// when it does not, every remaining pair (exhaustive_matcher) and image_registrator again.
// The bootstrap mapper, when no model exists, always has every pair. COLMAP's pair list
// separates the names by a space, so a photo whose name has one is matched with every photo
// when it arrives and left out of later photos' chosen pairs.
// One camera: photos of the same size, camera model and initial intrinsics share one COLMAP
// camera, so bundle adjustment refines one focal length and distortion from all their
// observations. feature_extractor runs once per photo, and COLMAP's single_camera holds
// within one call only: each photo got its own camera whose focal length every adjustment
// refined on its own (the runs before 2026-11-28, fourth stop). After the extraction, the new
// photo's camera row is replaced in the database by the earliest camera with the same model,
// width, height and parameters (as COLMAP itself read the photo, so EXIF orientation or a
// decoder's view cannot differ). A photo of another size or another EXIF focal length keeps
// its own camera.
// Known intrinsics (`--colmap-camera "MODEL p1,p2,..."`, COLMAP's model names and parameter
// order): every photo's camera starts from them, and no bundle adjustment changes them
// (Mapper.ba_refine_* and BundleAdjustment.refine_* off). For a calibrated camera, and for
// lenses far from COLMAP's guess (1.2 x the larger side): Middlebury's dinoSparseRing has a
// focal length of 3310 pixels on 640 x 480 photos (about 4.3 x the guess); with the guess
// COLMAP's batch mapper builds no model of more than 3 photos, with the calibration it places
// every photo (docs/live.md). The parameters refer to photos of the calibrated size; COLMAP
// applies them to every photo.
// Small models are kept (Mapper.min_model_size 3; COLMAP's default keeps a model only with
// min(10, 0.8 x photos) photos when it finds several): a capture whose photos form separate
// groups is registered in its largest group rather than not at all.
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
#include <string_view>
#include <vector>

#include "rephoto/live/live_session.h"

namespace rephoto::live {

struct ColmapRegistrarOptions {
  std::filesystem::path workspace;
  std::string colmap = "colmap";
  int bootstrap = 5;             // photos before the first `mapper`
  int bundle_every = 0;          // registrations between global bundle adjustments (0 = never)
  double timeout_seconds = 600;  // per COLMAP call
  int max_image_size = 1600;     // SiftExtraction.max_image_size
  // Inlier counts a registration needs (mapper and image_registrator; see above).
  int min_inliers = 15;           // Mapper.abs_pose_min_num_inliers (COLMAP: 30)
  double min_inlier_ratio = 0.1;  // Mapper.abs_pose_min_inlier_ratio (COLMAP: 0.25)
  int init_min_inliers = 50;      // Mapper.init_min_num_inliers (COLMAP: 100)
  // Matching (above): every pair while the database holds at most match_all_up_to earlier
  // photos, then match_recent + match_recent chosen pairs and match_around after placing.
  int match_all_up_to = 30;
  int match_recent = 8;
  int match_around = 12;
  // Known intrinsics (above): empty = COLMAP guesses and refines them.
  std::string camera_model = "SIMPLE_RADIAL";
  std::vector<double> camera_params;
};

// Parses --colmap-camera: "MODEL p1,p2,..." (parameters separated by commas and/or spaces),
// e.g. "PINHOLE 3310.4,3325.5,316.73,200.55". Throws UsageError naming what is wrong (unknown
// model, wrong parameter count for the model, a value that is not a finite number, a focal
// length that is not positive).
void ParseColmapCamera(std::string_view text, ColmapRegistrarOptions* options);

std::unique_ptr<Registrar> MakeColmapRegistrar(const ColmapRegistrarOptions& options);

}  // namespace rephoto::live
