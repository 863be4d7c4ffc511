// `rephoto live`: follows a capture while it happens (paper Sections 3 and 6.2). Every new
// photo is predicted from the photos before it (prequential evaluation: the paper's
// rephotography applied in time order), then joins them; after each photo the per-photo
// errors are projected onto the current model and the next views are suggested.
//
// Per photo, in arrival order (docs/live.md has the reasons and the measurements):
//   1. Checks, each ending in a status instead of a crash (RUN/live.jsonl and the page):
//      not_an_image (extension not .png/.jpg/.jpeg/.exr/.pfm), unreadable (cannot be decoded),
//      bad_name (control characters), duplicate (same SHA-256 as a registered photo),
//      bad_sidecar (its <stem>.json is invalid or its camera's aspect ratio is not the photo's),
//      no_pose (no sidecar after `sidecar_wait` seconds and no registration engine),
//      unregistered (the registration engine could not place it; photos it defers, e.g.
//      before COLMAP's first reconstruction, wait and are looked up again after every later
//      registered photo), blurred (sharpness, the
//      variance of the Laplacian of its grey image at 256 pixels wide, below blur_ratio times
//      the median of the registered photos', once 3 are registered).
//      A file rewritten later is processed again, except a registered photo: it keeps its
//      registration and the new content is ignored with a warning (its depth map and
//      prediction belong to the first content).
//   2. Pose: the sidecar <stem>.json (sidecar.h), else the registration engine (Registrar).
//   3. Prediction (the live prediction, Predict below): image-based rendering
//      (ibr/image_based_renderer.h, IBR) from the `neighbors` registered photos nearest to it
//      (camera distance plus viewing-angle difference), each with its live depth map. In an
//      object-centred capture (the photos' optical axes converge, Envelope::converging) that is
//      the proxy of the last update (the envelope plus the support plane, live_model.h, fused
//      from all plane-sweep depth maps) ray-cast at its camera: a photo predicts from the moment
//      it joins, even without a close neighbour, and one photo's stereo outliers do not reach
//      the prediction (the proxy keeps only multi-view consistent depth). In a forward-facing
//      capture (nearly parallel axes, which the star-shaped envelope does not model) it is the
//      photo's own plane-sweep depth map. Rendered at the photo's
//      camera scaled to at most `predict_width` pixels wide and compared with the photo reduced
//      to that size (compare::CompareInMemory, 1-NCC, default window): completeness (windows
//      the prediction covers / valid photo windows) and mean 1-NCC over the covered windows.
//      The first photos have nothing to predict from (no depth point yet): completeness 0,
//      error null.
//   4. Joining: its depth map by plane sweep (ibr::EstimateDepthMaps at `depth_width`) against
//      the registered photos nearest to it, the depth maps of registered photos that had none
//      yet (no neighbour when they came), and again the depth map of the one earlier photo for
//      which the new photo is the largest improvement of its nearest neighbour (viewing
//      direction under half the angle to its nearest neighbour when its depth was estimated);
//      then the record is appended to live.jsonl.
//   5. Model and suggestions: the envelope and support plane of all depth maps (live_model.h),
//      the per-photo error images projected onto the envelope (project::ProjectErrors), and
//      PlanNextViews on it with the need of unobserved envelope directions forced to 1 (they
//      stand for unseen surface; once those are used up, by view-space coverage, see
//      PlanOptions): K suggestions, each rendered by the live prediction.
// Poses refined by the engine: after every call of the registration engine (also one that did
// not place its photo; before that photo is predicted) and at resume, the poses of all
// engine-placed photos (not sidecar ones) are read again (Registrar::AllPlaced) and taken over
// when they changed. pose_update.h tells the frame's
// move (a similarity: each depth map is multiplied by its scale) from a photo's own refinement
// (moved more than 1 % of the cameras' spread or turned more than 0.5 degrees: its depth map is
// dropped and estimated again with the photo's next join step). The proxy is rebuilt before the
// prediction, and the changed photos' records are appended again (resume keeps the new poses).
// Cost per photo is bounded by the neighbour counts and working widths, except the envelope
// and the projection, which grow linearly with the photos (small: depth maps are subsampled,
// error images are at predict_width).
//
// Run folder RUN (one writer: run::OpenRunFolder kind "live"; kill -9 and restart resume):
//   live.jsonl             one JSON record per processed file version, appended (a torn last
//                          line is ignored at restart); the last record of a name counts;
//                          rewritten with those alone when it grows long (log_compaction_slack)
//   live.json              the state the page shows (= GET /api/live), replaced atomically
//   photos/<name>.png      the photo at predict_width;  predictions/<name>.png its prediction
//   errors/<name>.1-ncc.exr / .png   per-pixel error (NaN = not covered) and its colours
//   depth/<name>.bin       plane-sweep depth (COLMAP .bin) as estimated; times the record's
//                          depth_scale it is in the current frame (bundle adjustments)
//   model.ply              the envelope with projected errors (project::WriteProjectedPly)
//   suggestions/suggestions.json, suggest_XX.png, suggest_XX.json (sidecar shape),
//   suggestions/sparse/{cameras,images,points3D}.txt, suggestions/transforms.json
// <name> is the photo's file name in the watched folder.
//
// Thread safety: HandleReady/Tick from one thread; Api() and FilePath() from any thread.
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/live/live_model.h"
#include "rephoto/live/pose_update.h"

namespace rephoto::live {

// A registration engine for photos without a sidecar (colmap_registrar.h). Register adds the
// photo and returns its camera and pose when it could be placed; kDeferred when the engine
// cannot tell yet (e.g. before its initial reconstruction: the session asks again with
// Lookup after later photos); kFailed with `message` set when it cannot place the photo.
class Registrar {
 public:
  virtual ~Registrar() = default;
  struct Result {
    enum Status { kRegistered, kDeferred, kFailed } status = kFailed;
    camera::Camera camera;
    camera::Pose cam_from_world;
    std::string message;
  };
  virtual Result Register(const std::filesystem::path& photo) = 0;
  // The pose of a photo added before, once the engine has placed it (kRegistered), else
  // kDeferred or kFailed.
  virtual Result Lookup(const std::string& name) = 0;
  // Every photo the engine has placed, with its current camera and pose. An engine that
  // refines poses after placing a photo (bundle adjustment) returns the refined ones; the
  // session takes them over after each registration (see "Poses refined by the engine" in
  // LiveSession). Empty (the default): the engine never changes a pose it gave.
  struct Placed {
    std::string name;
    camera::Camera camera;
    camera::Pose cam_from_world;
  };
  virtual std::vector<Placed> AllPlaced() { return {}; }
  // Called while no photo arrives (LiveSession::Idle: the photographer paused) and photos wait
  // for a pose: an engine may do work here that it spreads out or skips per photo (COLMAP: the
  // re-map of the whole database, which waits for more photos after one that placed nothing).
  // Returns true when it may have placed or moved photos. Default: nothing to do.
  virtual bool Idle() { return false; }
};

// The image-based rendering settings of the predictions and suggestion rephotos.
ibr::ImageBasedOptions PredictionIbrOptions();

struct LiveOptions {
  std::filesystem::path watch;
  std::filesystem::path out;
  int suggestions = 3;      // K
  int candidates = 200;     // suggest candidates
  int predict_width = 640;  // prediction and error images (pixels, >= 16)
  int depth_width = 320;    // plane-sweep working width
  int depth_planes = 64;
  int neighbors = 6;        // photos per prediction / suggestion rephoto
  double blur_ratio = 0.2;  // see "blurred" above; 0 = never
  double sidecar_wait = 10; // seconds
  PlanOptions plan;         // next views (count and candidates come from the two above)
  EnvelopeOptions envelope;
  PoseUpdateOptions pose_update;  // when the engine's refined poses need new depth maps
  // live.jsonl is rewritten with the current record of each name (in arrival order; temp file,
  // fsync, rename) when it holds more than names + log_compaction_slack records, checked after
  // an append and at resume: the records a bundle adjustment appends again would otherwise
  // grow it as photos^2 / interval. >= 0.
  int log_compaction_slack = 256;
  Registrar* registrar = nullptr;  // not owned; null = sidecars only
  bool show_progress = false;
  void Check() const;
};

class LiveSession {
 public:
  // Opens (creates) the run folder with its lock and resumes from live.jsonl. Throws Error when
  // the folder is locked by another writer or holds something else.
  explicit LiveSession(const LiveOptions& options);
  ~LiveSession();

  // One file of the watched folder became ready (watcher.h). Never throws for a bad photo (it
  // gets a status); throws Error only when the run folder cannot be written.
  void HandleReady(const std::string& name);
  // Photos whose sidecar wait ran out become no_pose. Returns true when something changed.
  bool Tick();
  // No photo arrived for a while: lets the registration engine work for the photos it has not
  // placed (Registrar::Idle), then places those it has placed now, as after a registration.
  // Returns true when something changed. Never throws for an engine's failure (a warning).
  bool Idle();
  // Photos waiting for their sidecar.
  size_t waiting() const;

  // The /api/live document (see docs/live.md).
  nlohmann::json Api() const;
  // The file of the page's image `kind` ("photo", "prediction", "error", "suggestion") for
  // `name` when the state has it (names are looked up, never joined unchecked).
  std::optional<std::filesystem::path> FilePath(const std::string& kind,
                                                const std::string& name) const;
  // Number of state updates so far (the page polls for a change).
  uint64_t version() const;

  // The live prediction at any camera and pose with the photos registered so far (the one the
  // session uses for every new photo and for the suggestions' rephotos; see "Live prediction"
  // above): IBR from the `neighbors` nearest registered photos, each with its live depth map.
  // nullopt when no photo has one yet. Call from the thread that calls HandleReady.
  std::optional<render::Rephoto> Predict(const camera::Camera& camera,
                                         const camera::Pose& cam_from_world);

  struct State;

 private:
  std::unique_ptr<State> state_;
};

}  // namespace rephoto::live
