// The types `rephoto evaluate`'s stages pass each other (internal to eval/; options.h holds the
// settings and results, evaluate.h the public entry points).
//
// An evaluation is a sequence of stages over one run folder (evaluate.cc sequences them); each
// is a function whose signature says what it reads (const) and what it produces:
//   inputs.h        ReadInputs, OpenRun, MakeSplit     -> RunContext (const afterwards)
//   prepare_fold.h  PrepareFold                        -> FoldPlan (const afterwards)
//                   RemoveStaleOutputs, TrainingScene
//   run_command.h   RunFoldCommand(FoldPlan)           -> CommandOutcome
//   fold_model.h    ResolveFoldModel(FoldPlan, CommandOutcome) -> FoldModel
//                   LoadFoldModel, MakeFoldRenderer    the render model and the renderer
//   rephoto_views.h PlanViews, EvaluateViews           -> the fold's ViewOutcomes
//   aggregate.h     Aggregate                          per_image.csv, per_fold.csv, summary.json
//   projection.h    ProjectFold, ProjectSharedModel, WriteReport
//   run_records.h   fold.json, views/<stem>.json, run.json, manifest.json
//   keys.h          the resume keys of every result
// A stage writes only its own outputs in the run folder (each file atomically) and adds what it
// did to the run's Tally. Every result a stage writes carries the key of what it depends on, so
// a stage run again (here, later, or by another process on the same run folder:
// EvaluateOptions::only) reuses what is still valid.
//
// Thread safety: one RunContext per evaluation, read-only once the inputs are read (its file
// hash cache is thread-safe). The command stage of different folds may run in worker threads at
// once (each produces its own CommandOutcome); the Tally takes its mutex for every change; every
// other stage runs on one thread.
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
#include "rephoto/eval/hash.h"
#include "rephoto/eval/options.h"
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
  // With --compat, when ok: the preset's values (CompatMetrics order; whole image).
  std::vector<compare::MetricValue> compat;
  std::string key;
  std::string render_key;     // built-in renderings: what the rendering depends on
  bool reuse_render = false;  // the rendering on disk has render_key: compare only
  double render_seconds = 0;
  double compare_seconds = 0;
  std::filesystem::path record;
  bool reused = false;
};

// What PrepareFold decides for a fold, from the split and the settings; const afterwards.
struct FoldPlan {
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
  // Where the fold's derived model is written (colours, texture, defects): dir/model.ply, or
  // dir/textured/model.obj with --texture and no defects; its key is dir/model.key.
  std::filesystem::path derived_model;
  std::string train_key, test_key;
  std::optional<Json> previous;  // fold.json of an earlier run
};

// What the command stage found for a fold (RunFoldCommand): run now, reused or failed.
struct CommandOutcome {
  std::string command;  // substituted
  std::string key;
  bool reused = false;
  bool ok = true;
  std::string status;   // "" (none), "running", "ok", "failed" (fold.json)
  std::string message;  // why it failed (when !ok)
  bool interrupted = false;
  double external_seconds = 0;  // this run
  double seconds = 0;           // recorded (this run or the reused one)
  double cpu_seconds = 0;       // its CPU time (user + system of its process tree)
  int exit_status = 0;
  std::filesystem::path model_path;  // --reconstruct: the model it wrote ({out}/<model>)
};

// What a fold renders (ResolveFoldModel; LoadFoldModel adds the colouring time).
struct FoldModel {
  std::filesystem::path path;  // the model file rendered ("" for ibr from depth maps alone)
  bool gaussians = false;      // path holds 3D Gaussians (splat/gaussians.h)
  std::string model_key;
  std::string colorize_key;  // of the derived model (colours, texture, defects)
  std::string base_key;      // what every rendering of the fold depends on (keys.h RenderBaseKey)
  double colorize_seconds = 0;
};

// What became of a fold in this invocation: its command, model, views and status.
struct FoldOutcome {
  CommandOutcome command;
  FoldModel model;
  std::vector<ViewOutcome> views;  // by FoldPlan::tests index (after PlanViews)
  bool ok = true;
  std::string message;  // the first failure (one line)
  double seconds = 0;   // this run's wall time of the rephoto stage
};

// The run as read and prepared by the first stages (inputs.h); const afterwards.
struct RunContext {
  EvaluateOptions options;
  ModelSource source = ModelSource::kModel;
  std::filesystem::path run;  // absolute, normal
  Clock::time_point start;
  double start_cpu = 0;  // ProcessCpuSeconds() at start
  // A worker invocation (EvaluateOptions::only): the run folder was prepared by the submitting
  // `rephoto evaluate`; this one computes the same plans without rewriting the split or the
  // fold folders and writes only the results of its task.
  bool worker = false;

  scene::Scene scene;
  scene::SceneSource scene_source;
  std::vector<std::string> missing_photos;
  std::map<std::string, std::string> stems;  // view name -> output stem
  std::map<std::string, size_t> view_index;  // view name -> index in scene.views
  std::vector<std::string> photo_names;      // views with a photo, scene order
  Json scene_identity;
  split::Split split;
  std::string scheme_text;
  std::unique_ptr<FileHashCache> hashes;  // thread-safe

  // EvaluateOptions::cache_dir, else RUN/cache.
  std::filesystem::path CacheDir() const;
  std::string CommandTemplate() const {
    return options.render.empty() ? options.reconstruct : options.render;
  }
  const char* CommandKind() const { return options.render.empty() ? "reconstruct" : "render"; }
  // Threads a command should use: all threads / jobs (at least 1).
  int CommandThreads() const;
  // The rendered model is made from the fold's model: coloured and/or degraded (model.ply).
  bool DerivesModel() const {
    return options.colorize || options.texture || HasDefects(options.degrade);
  }
  // A path inside RUN as written in the run folder's files ("folds/fold_00/renders/a.png").
  std::string Relative(const std::filesystem::path& path) const {
    return path.lexically_relative(run).generic_string();
  }
};

// What the run did (counters) and how long it took (timings), added to by the stages; the
// command worker threads add theirs at the same time, so every change takes the mutex.
class Tally {
 public:
  void Count(size_t EvaluateCounters::*counter, size_t n = 1) {
    std::lock_guard<std::mutex> lock(mutex_);
    counters_.*counter += n;
  }
  void AddSeconds(double EvaluateTimings::*field, double seconds) {
    std::lock_guard<std::mutex> lock(mutex_);
    timings_.*field += seconds;
  }
  EvaluateCounters counters() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return counters_;
  }
  EvaluateTimings timings() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return timings_;
  }

 private:
  mutable std::mutex mutex_;
  EvaluateCounters counters_;
  EvaluateTimings timings_;
};

// What run.json says beside the results: the run folder's lock, whether run.json is this
// scene's, and why a run or an output failed. Written by the sequencer and the last stages.
struct RunStatus {
  run::RunFolder run_folder;   // locked from OpenRun on (not by workers)
  bool run_json_ours = false;  // run.json is this scene's run (set once the identity matched)
  std::string failure;         // run.json's "error" of a failed run
  std::string projection_message, report_message;  // why they were not written
};

// Marks the fold failed with `message` (the first message is kept).
void FailFold(FoldOutcome& fold, const std::string& message);

// An image <folder>/<stem>.<ext> for any extension io::ReadImage handles; empty if none.
std::filesystem::path FindImageByStem(const std::filesystem::path& folder, const std::string& stem);

// `text` on one line, cut after `max_chars` characters ("...").
std::string Shorten(const std::string& text, size_t max_chars = 160);

}  // namespace rephoto::eval
