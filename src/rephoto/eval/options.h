// The settings and results of `rephoto evaluate` (eval/evaluate.h documents what they mean
// for a run): the bottom of eval/, included by every stage; nothing here runs a stage.
//
// Enumerated settings (executor, representation, Gaussian mode) are parsed once where they
// enter (eval/settings.h: flags, config files), so the stages compare enums, not strings.
//
// Thread safety: plain values; the functions are pure.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/cluster/slurm.h"
#include "rephoto/core/error.h"
#include "rephoto/core/stats.h"
#include "rephoto/degrade/degrade.h"
#include "rephoto/lpips/lpips.h"
#include "rephoto/metrics/compat.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/metrics/validity.h"
#include "rephoto/render/view_renderer.h"
#include "rephoto/splat/rasterize.h"

namespace rephoto::eval {

enum class ModelSource { kModel, kReconstruct, kRender };

// Where the work of a run runs (EvaluateOptions::executor).
enum class Executor { kLocal, kSlurm };

// "local", "slurm"; std::nullopt for anything else.
std::optional<Executor> ParseExecutor(std::string_view name);
std::string_view ExecutorName(Executor executor);

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
  // Settings parse the names (render::ParseRepresentation); run.json writes them back.
  render::ViewRepresentation representation = render::ViewRepresentation::kAuto;
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
  // lpips (compare::CompareOptions::lpips_weights / lpips_net): the weights folder (empty =
  // $REPHOTO_LPIPS_WEIGHTS) and the network.
  std::filesystem::path lpips_weights;
  lpips::LpipsNet lpips_net = lpips::LpipsNet::kAlex;
  std::filesystem::path photo_masks;  // folder of masks by photo stem ("" = the scene's masks)
  bool resize = false;                // rescale external renders of another size
  bool error_images = true;
  // Of `metrics`, those whose error images are written: by default (nullopt) the headline
  // metric's (metrics::HeadlineMetric: 1-NCC) only, `--error-image-metrics all` (AllMetrics())
  // every metric's; the projection metric's are always written, since the projection reads
  // them (ErrorImageMetrics). Each metric's images of a 1280x960 view take 5.7 MB (a float EXR
  // and a colour-mapped PNG).
  std::optional<std::vector<metrics::Metric>> error_image_metrics;
  // Write renders/<stem>.depth.exr beside each built-in rendering (camera-frame z, 4 bytes per
  // pixel). Nothing in the run reads them: the projection renders the model's depth again with
  // the same samples, which gives the same values. Off by default.
  bool depth_images = false;

  // ---- the numbers papers publish (`--compat`, eval/compat_numbers.h)
  // With a preset, every evaluated view is also compared as the field's evaluation script does
  // (compare::CompareOptions::compat: whole image, no masks; photos with alpha composited over
  // `background`, the training background), beside rephoto's own masked `metrics`: the
  // per_image.csv columns <preset>_<metric>, summary.json "compat" and the reference's own
  // files (3dgs: results.json, per_view.json and metrics.txt as graphdeco's metrics.py writes
  // and prints them; nerfstudio: output.json as ns-eval writes it). The default split becomes
  // every:8 (llffhold 8, ResolvedScheme).
  std::optional<metrics::CompatPreset> compat;
  // The preset's metrics to compute (CompatMetrics: empty = the preset's default).
  std::vector<metrics::Metric> compat_metrics;

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
  // Not with --colorize or defects (they change meshes). `background` is also what --compat
  // composites photos with alpha over (the reference scripts composite over the training
  // background), for any model source.
  splat::GaussianMode gaussian_mode = splat::GaussianMode::kClassic;  // "classic", "antialiased"
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
  Executor executor = Executor::kLocal;
  cluster::SlurmOptions slurm;
  int views_per_task = 16;  // held-out views per Slurm task (a task of minutes, not seconds)
  std::filesystem::path program;
  // Recorded in run.json only.
  std::vector<std::string> command_line;
  std::filesystem::path config_file;

  ModelSource source() const;
  // Throws UsageError (core/error.h) for inconsistent settings: not exactly one model source,
  // unknown placeholders, bad numbers, a malformed --only task, no scene or output folder.
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

// One metric of the --compat preset over the evaluated views, as the reference reports it: the
// mean of the per-image values (PSNR: of the images' PSNRs, not of a pooled MSE) and their
// sample standard deviation (n - 1, torch.std_mean's default; NaN with fewer than 2 images).
struct CompatAggregate {
  metrics::Metric metric = metrics::Metric::kPsnr;
  Summary over_images;
  double std = 0;
};

struct EvaluateResult {
  std::vector<FoldResult> folds;
  std::vector<std::string> missing_photos;  // view names whose photo does not exist
  Summary completeness_across_folds;
  Summary completeness_over_images;
  std::vector<MetricAggregate> metrics;  // in EvaluateOptions::metrics order
  // With EvaluateOptions::compat: its metrics (CompatMetrics order) and the lines the
  // reference prints (3dgs: metrics.py's "  SSIM : ..." block; nerfstudio: the results).
  std::vector<CompatAggregate> compat;
  std::string compat_text;
  EvaluateCounters counters;
  EvaluateTimings timings;
  size_t images = 0;                   // test images over all folds
  size_t evaluated_images = 0;         // with a result
  ExitCode exit_code = ExitCode::kOk;  // kIncomplete: failed folds/views or missing photos
};

// The metrics whose error images an evaluation writes, in options.metrics order: empty = all of
// options.metrics (`--error-image-metrics all`, as compare::CompareOptions reads it), else
// options.error_image_metrics (default: the headline metric) and the projection metric when
// it is one of options.metrics.
std::vector<metrics::Metric> ErrorImageMetrics(const EvaluateOptions& options);
// The same as the list of metrics whose images are on disk: ErrorImageMetrics, with "all"
// spelled out as options.metrics (empty when options.error_images is off).
std::vector<metrics::Metric> WrittenErrorImageMetrics(const EvaluateOptions& options);

// Whether a fold's built-in renderings are written with their depth maps
// (renders/<stem>.depth.exr): with options.depth_images, and where the projection reads them
// (the model itself rendered, representation auto, a mesh or point cloud: not `gaussians`, and
// a projection metric), which spares it rendering the model again.
bool WritesDepthImages(const EvaluateOptions& options, bool gaussians);

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

// The split scheme a run uses: options.scheme, or the default described above for
// `photo_count` photos on disk ("every:8" with a --compat preset: 3DGS's llffhold and
// nerfstudio's eval_interval).
std::string ResolvedScheme(const EvaluateOptions& options, size_t photo_count);

// The --only task `text` ("fold:F", "views:F:FIRST:COUNT", "aggregate") parsed; throws
// UsageError naming the expected forms when it is malformed.
struct TaskSpec {
  EvaluateTask::Kind kind = EvaluateTask::Kind::kAggregate;
  size_t fold = 0, first = 0, count = 0;  // count > 0 for kViews
};
TaskSpec ParseTaskSpec(std::string_view text);

// The Gaussian rendering mode's name ("classic", "antialiased"), as splat::ParseGaussianMode
// reads it.
std::string_view GaussianModeName(splat::GaussianMode mode);

// True when options.degrade asks for any defect.
bool HasDefects(const degrade::DegradeOptions& degrade);

// The metrics of the --compat preset a run computes: options.compat_metrics, else the
// preset's default (psnr, ssim); empty without a preset.
std::vector<metrics::Metric> CompatMetrics(const EvaluateOptions& options);

// The placeholder names the command templates may use (see above).
const std::vector<std::string>& CommandPlaceholders();

}  // namespace rephoto::eval
