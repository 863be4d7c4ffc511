// `rephoto evaluate`: virtual rephotography end to end (paper Section 3.1): split the photos,
// obtain each fold's reconstruction from its training photos, rephotograph it at the fold's
// held-out cameras, compare with the photos, aggregate per image / fold / dataset, project the
// error onto the model and write a report. The run directory layout is the contract in
// docs/run-folder.md (mirrored in the comments below).
//
// Model sources (exactly one):
//   kModel        EvaluateOptions::model alone: one model file for every fold (a global method,
//                 no cross-validation needed, paper Section 4.4), rendered by the built-in
//                 renderer. With `colorize`, each fold's copy is coloured from that fold's
//                 TRAINING photos only (render::ColorizeMesh), which makes it a proper
//                 cross-validated reconstruction of the colours.
//   kReconstruct  `reconstruct` = a command template run once per fold through /bin/sh -c, then
//                 `model` (a path relative to {out}) is read as the fold's model (mesh or point
//                 cloud; PLY or OBJ) and rendered by the built-in renderer.
//   kRender       `render` = a command template of an external renderer (NeRF, 3DGS, IBR) that
//                 writes one RGBA image per test view, named <test stem>.<png|jpg|jpeg|exr|pfm>,
//                 into {out}; compared as they are (alpha = coverage; without alpha pure black =
//                 not covered).
// Placeholders of both templates (each value shell-quoted; syntax in eval/command.h):
//   {train}            the fold's training scene folder: {train}/sparse (COLMAP text model of
//                      the training views with their sparse points), {train}/transforms.json
//   {sparse} {transforms} those two paths
//   {images}           the folder the training image names are relative to; it holds only the
//                      fold's training photos (RUN/folds/fold_XX/train/images: hard links, or
//                      symbolic links across file systems, to the photos; the downscaled PNGs
//                      with train_short_side), so a pipeline that takes every image in it cannot
//                      see a test photo
//   {train_list}       train.txt: the training image names, one per line
//   {test} {test_sparse} {test_transforms} {test_list}   the same for the held-out cameras (no
//                      points); at the evaluation resolution when eval_short_side is set
//   {out}              the fold's empty output folder RUN/folds/fold_XX/reconstruction
//   {fold}             the fold index (0-based)
//   {threads}          threads the command should use: all threads / jobs (at least 1)
// A command fails its fold (other folds go on) when it cannot be started, exits non-zero, is
// killed by a signal, writes nothing into {out}, writes no model at {out}/model or a model that
// cannot be read, or (render) misses a test image or writes one of the wrong size. The message
// names the fold, the command and its log file RUN/logs/fold_XX.<reconstruct|render>.log
// (stdout and stderr of the command). The run then returns ExitCode::kIncomplete and lists
// the failed folds in summary.json and per_fold.csv.
//
// Split scheme: split/split.h syntax. Default: "none" for a model alone without colorize (all
// photos are test photos of the one model: a fit error, paper 4.4), otherwise "kfold:5" (or
// "loo" when there are fewer than 5 photos).
//
// Photos missing on disk (a view whose image file does not exist) are left out of the split:
// they can neither train nor be compared. They are listed as warnings, in run.json and in
// summary.json "missing", and the run returns ExitCode::kIncomplete; the rest is evaluated.
//
// Sweeps (paper Section 4.2):
//   train_count N > 0: each fold trains on a deterministic subset of N of its training views
//     (the sorted names shuffled by split::SeededShuffle with seed train_seed + fold index).
//   train_short_side PX > 0: the fold's training photos are downscaled (area filter, see
//     compare/resample.h) so that the shorter side is PX (never upscaled), written as 8-bit PNG
//     RUN/folds/fold_XX/train/images/<name without extension>.png, and the training scene's
//     cameras are scaled with Camera::Scaled (observations too); the training scene then names
//     the PNGs. A photo whose shorter side is already at most PX is linked as it is (no
//     re-encoding), under its own name. Either option writes the fold's own training scene
//     RUN/folds/fold_XX/train/ (sparse, transforms.json, train.txt, images/), which {train} etc.
//     then point to.
//   eval_short_side PX > 0: rephotos are rendered and photos compared at the size whose shorter
//     side is PX (never upscaled): the test cameras are scaled (Camera::Scaled) and the photos
//     (and photo masks, conservatively) downscaled once with the area filter into
//     RUN/cache/eval_photos/<stem>.png (16-bit PNG, reused while the photo is unchanged).
//
// Parallelism: the built-in renderer and the metrics are multi-threaded (TBB). External
// commands run `jobs` folds at a time in background threads ({threads} = all threads / jobs);
// rephoto's own work (colouring, rendering, comparing) runs on the calling thread fold after
// fold, overlapping with the commands of the next folds. The results do not depend on `jobs`.
//
// Resume: every result carries a key, the XXH3 hash (eval/hash.h) of everything it depends on
// (scene cameras and poses, photo and mask contents, model file content incl. textures, the
// command template, and the settings that change it). A rerun with the same --out skips
// folds whose reconstruction key matches (fold.json) and views whose record
// (folds/fold_XX/views/<stem>.json, written last) holds the matching key; changed inputs or
// settings recompute exactly what they affect. An interrupted run (SIGINT/SIGTERM with
// handle_interrupts, or InterruptRequested()) stops the running commands, finishes the view
// in flight and throws Error "interrupted ... rerun the same command to resume". A run
// directory that holds a run of another scene (different set of image names) is an Error.
//
// Outputs in `out` (every file written atomically; the full contract with all fields is
// docs/run-folder.md):
//   run.json       schema "rephoto.evaluate/1": tool version, command line, resolved settings
//                  (eval/settings.h names), scene identity, inputs with XXH3 content hashes
//                  (scene, model, photos, missing photos), the split, timings in seconds
//                  {total, external, rephoto: {total, split, prepare, colorize, render, compare,
//                  aggregate, project, report}}, counters, per-fold status, outputs (projected
//                  PLYs, report, or why they are missing). status: running | interrupted | ok |
//                  incomplete.
//   manifest.json  the independent tasks: one "<fold>/reconstruct" or "<fold>/render" task per
//                  fold when a command is used, one "<fold>/<stem>" task per test view, each with
//                  its key, inputs, outputs and dependencies, so a scheduler could run them
//                  elsewhere and this command would then reuse their records.
//   split/         exactly what split::WriteSplit writes (photos that exist only).
//   folds/fold_XX/ reconstruction/ (the command's {out}), model.ply + model.key (the coloured
//                  model, --colorize), train/ and test/ (only when they differ from split/, see
//                  Sweeps), renders/<stem>.png (RGBA 8-bit, alpha = coverage) and
//                  <stem>.depth.exr (built-in renderer), errors/<stem>.<metric>.exr|png,
//                  views/<stem>.json (the view's result and key, written last), fold.json.
//                  <stem>: the view name's file name without extension, or its relative path
//                  without extension when two views share a file name.
//   logs/fold_XX.reconstruct.log, logs/fold_XX.render.log
//   per_image.csv  fold, then compare's per_image.csv columns, sorted by fold then name; status
//                  ok | failed (the fold or the view failed; measurements empty); photo = the
//                  absolute path of the photo compared (the cached downscaled copy with
//                  eval_short_side), render relative to RUN.
//   per_fold.csv   fold, status, test_images, evaluated_images, seconds (recorded compute time),
//                  completeness, <metric>... (means over the fold's images), message.
//   summary.json   schema "rephoto.evaluate/1": scene, scheme, folds, failed_folds, missing,
//                  "completeness" and "metrics"/<metric>, each {across_folds, over_images: {mean,
//                  min, q1, median, q3, max, count}, pooled}.
//   projected/<metric>.ply  the `projection_metric` error projected onto the model
//                  (project::ProjectErrors; one model for all folds, else per fold
//                  fold_XX.<metric>.ply when there are several), mesh and point models only.
//   report.html    report::WriteRunReport of the run directory.
//   cache/         file hashes and downscaled photos (safe to delete: only costs time; a sweep
//                  shares SWEEP/cache among its settings instead, EvaluateOptions::cache_dir).
// Outputs of an earlier run with another split (folds, test views) are removed.
//
// The run folder it writes (files, columns, units, schemas): docs/run-folder.md.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/cluster/slurm.h"
#include "rephoto/core/error.h"
#include "rephoto/core/stats.h"
#include "rephoto/degrade/degrade.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/metrics/validity.h"

namespace rephoto::eval {

enum class ModelSource { kModel, kReconstruct, kRender };

struct EvaluateOptions {
  // ---- inputs
  std::filesystem::path scene;       // scene file or folder (scene/read_scene.h)
  std::string format;                // "" = detect
  std::filesystem::path image_root;  // "" = the format's default
  std::string scheme;                // split/split.h syntax; "" = the default above
  std::filesystem::path model;       // a model file, or with `reconstruct` a path inside {out}
  std::string reconstruct;           // command template (see above)
  std::string render;                // command template (see above)
  // Built-in representation (the paper's Table I):
  //   "auto"  the model as it is: mesh (vertex colours or texture) or point cloud
  //   "vdt"   view-dependent texturing: the fold's training photos reprojected through the
  //           model (a mesh), ibr/image_based_renderer.h
  //   "ibr"   image-based rendering: the fold's training photos warped by per-view depth maps
  //           (from depth_maps, else plane-sweep stereo over the training photos); needs no
  //           model (model may be empty)
  // vdt and ibr use only the fold's training photos: with a cross-validating scheme a test
  // photo never contributes to its own rephoto.
  std::string representation = "auto";
  // ibr: folder of per-view depth maps (ibr/training_views.h names: COLMAP
  // stereo/depth_maps/<name>.geometric.bin, <stem>.pfm, <stem>.exr, ...); "" = estimate.
  std::filesystem::path depth_maps;
  bool colorize = false;  // colour the model from each fold's training photos
  // Texture the model (a mesh) from each fold's training photos (texture/texture_mesh.h, default
  // options): RUN/folds/fold_XX/textured/model.obj + model.mtl + atlases and texture.json, the
  // paper's best representation (Table I), cross-validated like --colorize. Not with --colorize.
  bool texture = false;

  // ---- sweeps
  // Synthetic defects (paper Section 4.1, degrade/degrade.h) applied to each fold's model after
  // it was obtained (and coloured), before it is rendered: texture_noise, geometry_noise,
  // simplify, seed. All zero = none. The degraded model is RUN/folds/fold_XX/model.ply (noisy
  // textures in RUN/folds/fold_XX/textures/) and is what the error is projected onto. Not with
  // an external renderer.
  degrade::DegradeOptions degrade;
  int train_count = 0;  // 0 = all training views
  uint64_t train_seed = 0;
  int train_short_side = 0;  // 0 = original resolution
  int eval_short_side = 0;   // 0 = original resolution

  // ---- comparison (as `rephoto compare`)
  std::vector<metrics::Metric> metrics = metrics::AllMetrics();
  metrics::MetricOptions metric_options;
  metrics::ExposureOptions exposure;
  std::filesystem::path photo_masks;  // folder of masks by photo stem ("" = the scene's masks)
  bool resize = false;                // rescale external renders of another size
  bool error_images = true;
  // Of `metrics`, those whose error images are written (empty = all); the projection metric's
  // are always written, since the projection reads them (ErrorImageMetrics).
  std::vector<metrics::Metric> error_image_metrics;

  // ---- built-in rendering (as `rephoto render`)
  int samples_per_pixel = 4;
  bool backfaces = true;
  float point_radius = 0;  // 0 = from the file or the density
  int point_neighbors = 6;
  // 3D Gaussian splatting models (splat/rasterize.h): a model file holding Gaussians (detected
  // with representation "auto", or forced with "gaussians") is rasterized as the reference
  // CUDA rasterizer does, "classic" or "antialiased" (gsplat's mode), its RGB composited over
  // `background` (RGB in [0, 1]; 3DGS trains black or white). Completeness counts the pixels
  // whose alpha (1 - transmittance) reaches `min_alpha`: a splat's soft edge covers a pixel
  // only partly, and 0.5 counts a pixel as the model's when the model makes most of its colour.
  // Not with --colorize or defects (they change meshes).
  std::string gaussian_mode = "classic";
  std::array<float, 3> background = {0, 0, 0};
  double min_alpha = 0.5;

  // ---- run
  std::filesystem::path out;
  // Where file hashes and downscaled photos are cached ("" = RUN/cache). Entries are keyed by
  // the photo's content hash and size, so runs of one scene can share a folder (sweeps do).
  std::filesystem::path cache_dir;
  int jobs = 1;  // folds whose external commands run at once
  // Seconds a fold's --reconstruct/--render command may run (0 = no limit). A command that runs
  // longer is stopped with its whole process group (SIGTERM, SIGKILL 5 s later) and its fold
  // fails with "timed out after N s"; the other folds go on.
  double command_timeout = 0;
  // Metric projected onto the model after the folds ("none" = no projection).
  std::string projection_metric = "1-ncc";
  bool report = true;              // write report.html
  bool handle_interrupts = false;  // install SIGINT/SIGTERM handlers (the CLI does)
  // One task of a run instead of the whole run ("" = everything), for executors that run the
  // tasks elsewhere (a cluster job) on the same run folder, which a whole run with the same
  // settings prepared first (split, fold folders). Tasks:
  //   fold:F               fold F's command (--reconstruct/--render) and derived model
  //                        (--colorize, defects): RUN/folds/fold_FF/{reconstruction,model.ply}
  //   views:F:FIRST:COUNT  render and compare views FIRST..FIRST+COUNT-1 of fold F (the fold's
  //                        test views in name order); needs the fold's finished command
  //   aggregate            per_image.csv, per_fold.csv, summary.json, projection, report from
  //                        the view records; views without a valid record count as failed
  // A task takes no run-folder lock and writes only its own outputs (atomically), so tasks of
  // one run can run at once; each reuses what is already done, like a whole run. Its exit code:
  // kOk, or kIncomplete when its fold or a view failed (the reason is in fold.json / logged);
  // aggregate exits kOk once the tables are written (the run's state is in summary.json).
  std::string only;
  // Where the work runs: "local" (this process) or "slurm" (eval/slurm_executor.h: the tasks
  // above as Slurm job arrays; `slurm` holds the resources and --wait). `program` is the
  // rephoto binary the jobs run (absolute, the same path on every node; "" = this process's
  // executable, /proc/self/exe).
  std::string executor = "local";
  cluster::SlurmOptions slurm;
  int views_per_task = 16;  // held-out views per Slurm task (a task of minutes, not seconds)
  std::filesystem::path program;
  // Recorded in run.json only.
  std::vector<std::string> command_line;
  std::filesystem::path config_file;

  ModelSource source() const;
  // Throws UsageError (eval/command.h) for inconsistent settings: not exactly one model source,
  // unknown placeholders, bad numbers, unknown representation, no scene or output folder.
  void Check() const;
};

struct FoldResult {
  size_t index = 0;
  std::string name;  // "fold_00"
  bool ok = true;
  std::string message;  // one line when !ok
  size_t test_images = 0;
  size_t evaluated_images = 0;
  double seconds = 0;                // wall-clock seconds spent on the fold in this run
  double external_seconds = 0;       // of which in its command (0 when reused)
  double completeness = 0;           // mean over the fold's evaluated images (NaN if none)
  std::vector<double> metric_means;  // per metric: mean of the images' means (NaN if none)
};

struct MetricAggregate {
  metrics::Metric metric = metrics::Metric::kOneMinusNcc;
  Summary across_folds;  // of the folds' means
  Summary over_images;   // of the images' means
  double pooled = 0;     // over all evaluated positions (psnr: of the pooled MSE)
};

// What this run did (resume can be checked from these).
struct EvaluateCounters {
  size_t commands_run = 0;  // reconstruct/render commands started
  size_t folds_reused = 0;  // folds whose command result was reused
  size_t models_colorized = 0;
  size_t views_rendered = 0;  // built-in renderings
  size_t views_compared = 0;
  size_t views_reused = 0;  // view records whose key matched
  size_t photos_downscaled = 0;
  size_t projections = 0;  // projected PLYs written (not reused)
};

// rephoto's fraction of the seconds it and the external commands took together (0 if none).
inline double RephotoShare(double rephoto, double external) {
  return rephoto + external > 0 ? rephoto / (rephoto + external) : 0.0;
}

struct EvaluateTimings {
  double total = 0;
  double external = 0;  // sum over commands (may overlap rephoto's own work)
  double split = 0, prepare = 0, colorize = 0, render = 0, compare = 0, aggregate = 0, project = 0,
         report = 0;
  // The view stage is a pipeline (eval/rephoto_views.h): render (render and write the
  // rendering), photos (decode, downscale, masks), compare (the metrics) and write (error
  // images and view records) are summed over views and overlap; views is the stage's wall time.
  double photos = 0, write = 0, views = 0;
  // CPU seconds (user + system, all threads) of this invocation: the commands' (their whole
  // process trees, from wait4) and rephoto's own process. Unlike wall-clock sums these do not
  // depend on what overlapped what, nor much on other load on the machine.
  double external_cpu = 0, rephoto_cpu = 0;
  double rephoto_cpu_share() const { return RephotoShare(rephoto_cpu, external_cpu); }
  double rephoto() const {
    return split + prepare + colorize + render + photos + compare + write + aggregate + project +
           report;
  }
};

struct EvaluateResult {
  std::vector<FoldResult> folds;
  std::vector<std::string> missing_photos;  // view names whose photo does not exist
  Summary completeness_across_folds;
  Summary completeness_over_images;
  std::vector<MetricAggregate> metrics;  // in EvaluateOptions::metrics order
  EvaluateCounters counters;
  EvaluateTimings timings;
  size_t images = 0;                   // test images over all folds
  size_t evaluated_images = 0;         // with a result
  ExitCode exit_code = ExitCode::kOk;  // kIncomplete: failed folds/views or missing photos
};

// The metrics whose error images an evaluation writes: empty = all of options.metrics, else
// options.error_image_metrics and the projection metric (when it is one of options.metrics).
std::vector<metrics::Metric> ErrorImageMetrics(const EvaluateOptions& options);

// Runs the evaluation described above and writes the run directory. Throws UsageError for bad
// settings, Error for bad input that stops everything (unreadable scene, another scene's run
// directory, interrupt); failures of single folds or views are recorded, not thrown.
EvaluateResult RunEvaluate(const EvaluateOptions& options);

// One task of a run (EvaluateOptions::only) and whether its results are already in the run
// folder with valid keys.
struct EvaluateTask {
  enum class Kind { kFold, kViews, kAggregate };
  Kind kind = Kind::kAggregate;
  std::string id;     // the --only value: "fold:2", "views:2:0:8", "aggregate"
  size_t fold = 0;    // kFold, kViews
  size_t views = 0;   // kViews: views in the task
  std::string key;    // what its results depend on (changes when it must run again)
  bool done = false;  // nothing to do: every result it writes is there with a matching key
};

struct EvaluatePlan {
  std::filesystem::path run;        // absolute
  std::vector<EvaluateTask> tasks;  // fold tasks, then view tasks, then "aggregate"
  size_t folds = 0, views = 0;
};

// Prepares the run folder as a whole run does before its work (inputs, split, fold folders,
// run.json; with the run folder's lock while it does) and lists the tasks of the run: a fold
// task for each fold with a command or a derived model (--colorize, defects), its views in
// chunks of at most `views_per_task`, and "aggregate". Throws as RunEvaluate.
EvaluatePlan PlanEvaluate(const EvaluateOptions& options, size_t views_per_task);

// The split scheme a run uses: options.scheme, or the default described above for
// `photo_count` photos on disk.
std::string ResolvedScheme(const EvaluateOptions& options, size_t photo_count);

// True when options.degrade asks for any defect.
bool HasDefects(const degrade::DegradeOptions& degrade);

// The placeholder names the command templates may use (see above).
const std::vector<std::string>& CommandPlaceholders();

}  // namespace rephoto::eval
