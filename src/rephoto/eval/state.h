// The state `rephoto evaluate`'s stages share (internal to eval/; evaluate.h is the public API).
//
// An evaluation is a sequence of stages over one run folder (evaluate.cc sequences them):
//   inputs.h        ReadInputs, OpenRun, MakeSplit        the scene, the run folder, the split
//   prepare_fold.h  PrepareFold, RemoveStaleOutputs      each fold's training/test scenes
//   run_command.h   RunFoldCommand                        a fold's --reconstruct/--render command
//   fold_model.h    PrepareFoldModel                      a fold's model: key, colours, defects
//   rephoto_views.h RephotoViews                          render + compare the held-out views
//   aggregate.h     Aggregate                             per_image.csv, per_fold.csv, summary.json
//   projection.h    ProjectFold, ProjectSharedModel, WriteReport
//   records.h       fold.json, views/<stem>.json, run.json, manifest.json
//   keys.h          the resume keys of every result
// A stage reads the RunState and its fold, writes only its own outputs in the run folder (each
// file atomically) and records what it did in the state. Every result a stage writes carries
// the key of what it depends on, so a stage run again (here, later, or by another process on
// the same run folder: EvaluateOptions::only) reuses what is still valid.
//
// Thread safety: one RunState per evaluation. The command stage of different folds may run in
// worker threads at once (each touches only its own FoldState; shared counters and timings go
// through RunState::timings_mutex); every other stage runs on one thread.
#pragma once

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/compare/compare.h"
#include "rephoto/eval/evaluate.h"
#include "rephoto/eval/hash.h"
#include "rephoto/render/view_renderer.h"
#include "rephoto/run/records.h"
#include "rephoto/run/run_folder.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/scene/scene.h"
#include "rephoto/split/split.h"

namespace rephoto::eval {

using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

// Bumped when the meaning of a stored result changes, so old records are recomputed.
inline constexpr const char* kKeyVersion = "rephoto.evaluate.key/1";
inline constexpr const char* kSchema = "rephoto.evaluate/1";

inline double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// One held-out view of a fold.
struct TestView {
  std::string name;  // scene name
  std::string stem;
  size_t view_index = 0;  // into the full scene
  camera::Camera camera;  // at the evaluation resolution
  camera::Pose pose;
  std::filesystem::path photo;  // original photo
  std::string photo_hash;
  std::filesystem::path mask;  // photo mask (original resolution), empty = none
  std::string mask_hash;
};

// The outcome of one (fold, test view).
struct ViewOutcome {
  std::string stem;
  std::string name;
  bool ok = false;
  std::string message;         // when !ok
  compare::ImageResult image;  // when ok
  std::string key;
  std::string render_key;     // built-in renderings: what the rendering depends on
  bool reuse_render = false;  // the rendering on disk has render_key: compare only
  double render_seconds = 0;
  double compare_seconds = 0;
  std::filesystem::path record;
  bool reused = false;
};

struct FoldState {
  size_t index = 0;
  std::string name;                      // fold_00
  std::filesystem::path dir;             // RUN/folds/fold_00
  std::vector<std::string> train_names;  // the views the fold trains on
  std::vector<TestView> tests;
  // Folders and files the commands see.
  std::filesystem::path train_dir, images_dir, train_list;
  std::filesystem::path test_dir, test_list;
  std::filesystem::path out_dir;  // RUN/folds/fold_00/reconstruction
  std::filesystem::path log_file;
  std::string train_key, test_key;
  std::optional<Json> previous;  // fold.json of an earlier run

  // Command stage (worker thread).
  std::string command;  // substituted
  std::string command_key;
  bool command_reused = false;
  bool command_ok = true;
  std::string command_status;  // "" (none), "running", "ok", "failed"
  bool interrupted = false;
  double external_seconds = 0;     // this run
  double command_seconds = 0;      // recorded (this run or the reused one)
  double command_cpu_seconds = 0;  // its CPU time (user + system of its process tree)
  int exit_status = 0;

  // Model and rephoto stages.
  bool ok = true;
  std::string message;
  std::filesystem::path model_path;  // the model file rendered
  bool gaussians = false;            // model_path holds 3D Gaussians (splat/gaussians.h)
  std::string model_key;
  std::string colorize_key;
  std::string base_key;  // what every rendering of the fold depends on (keys.h RenderBaseKey)
  double colorize_seconds = 0;
  std::vector<ViewOutcome> views;
  double seconds = 0;  // this run's wall time of the rephoto stage
};

struct RunState {
  explicit RunState(const EvaluateOptions& options) : o(options) {}

  EvaluateOptions o;
  ModelSource source = ModelSource::kModel;
  // EvaluateOptions::representation, parsed (Check accepted it).
  render::ViewRepresentation representation = render::ViewRepresentation::kAuto;
  std::filesystem::path run;  // absolute, normal
  Clock::time_point start;
  double start_cpu = 0;  // ProcessCpuSeconds() at start
  // A worker invocation (EvaluateOptions::only): the run folder was prepared by the submitting
  // `rephoto evaluate`; this one computes the same state without rewriting the split or the
  // fold folders and writes only the results of its task.
  bool worker = false;

  scene::Scene scene;
  scene::SceneSource scene_source;
  std::vector<std::string> missing_photos;
  std::map<std::string, std::string> stems;  // view name -> output stem
  std::map<std::string, size_t> view_index;  // view name -> index in scene.views
  std::vector<std::string> photo_names;      // views with a photo, scene order
  run::RunFolder run_folder;                 // locked from OpenRun on (not by workers)
  std::string failure;                       // run.json's "error" of a failed run
  bool run_json_ours = false;  // run.json is this scene's run (set once the identity matched)
  Json scene_identity;
  split::Split split;
  std::string scheme_text;
  std::unique_ptr<FileHashCache> hashes;
  std::vector<FoldState> folds;

  EvaluateCounters counters;
  EvaluateTimings timings;
  std::mutex timings_mutex;
  std::string projection_message, report_message;  // why they were not written

  // EvaluateOptions::cache_dir, else RUN/cache.
  std::filesystem::path CacheDir() const;
  std::string CommandTemplate() const { return o.render.empty() ? o.reconstruct : o.render; }
  const char* CommandKind() const { return o.render.empty() ? "reconstruct" : "render"; }
  // Threads a command should use: all threads / jobs (at least 1).
  int CommandThreads() const;
  // The rendered model is made from the fold's model: coloured and/or degraded (model.ply).
  bool DerivesModel() const { return o.colorize || HasDefects(o.degrade); }
  // A path inside RUN as written in the run folder's files ("folds/fold_00/renders/a.png").
  std::string Relative(const std::filesystem::path& path) const {
    return path.lexically_relative(run).generic_string();
  }
};

// Marks the fold failed with `message` (the first message is kept).
void FailFold(FoldState& fold, const std::string& message);

// An image <folder>/<stem>.<ext> for any extension io::ReadImage handles; empty if none.
std::filesystem::path FindImageByStem(const std::filesystem::path& folder, const std::string& stem);

// `text` on one line, cut after `max_chars` characters ("...").
std::string Shorten(const std::string& text, size_t max_chars = 160);

}  // namespace rephoto::eval
