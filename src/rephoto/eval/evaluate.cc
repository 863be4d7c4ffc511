#include "rephoto/eval/evaluate.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <thread>

#include "rephoto/compare/compare.h"
#include "rephoto/compare/resample.h"
#include "rephoto/core/file.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/process.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/command.h"
#include "rephoto/eval/hash.h"
#include "rephoto/eval/settings.h"
#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/ibr/training_views.h"
#include "rephoto/io/csv.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/project/project.h"
#include "rephoto/render/colorize.h"
#include "rephoto/render/render.h"
#include "rephoto/report/report.h"
#include "rephoto/run/run_folder.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/scene/transforms_json.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/splat/rasterize.h"
#include "rephoto/splat/scalar_ply.h"
#include "rephoto/split/random.h"
#include "rephoto/split/split.h"
#include "rephoto/split/split_writer.h"

namespace rephoto::eval {
namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

namespace {

constexpr const char* kSchema = "rephoto.evaluate/1";
// Bumped when the meaning of a stored result changes, so old records are recomputed.
constexpr const char* kKeyVersion = "rephoto.evaluate.key/1";
constexpr const char* kImageExtensions[] = {".png", ".jpg", ".jpeg", ".exr", ".pfm",
                                            ".PNG", ".JPG", ".JPEG", ".EXR", ".PFM"};

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// JSON has no NaN: null.
Json Number(double value) {
  if (std::isnan(value)) return nullptr;
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  return value;
}

double JsonDouble(const Json& value) {
  if (value.is_number()) return value.get<double>();
  if (value.is_string()) {
    const std::string s = value.get<std::string>();
    if (s == "inf") return std::numeric_limits<double>::infinity();
    if (s == "-inf") return -std::numeric_limits<double>::infinity();
  }
  return std::numeric_limits<double>::quiet_NaN();
}

Json SummaryJson(const Summary& s) {
  return {{"mean", Number(s.mean)}, {"min", Number(s.min)},
          {"q1", Number(s.q1)},     {"median", Number(s.median)},
          {"q3", Number(s.q3)},     {"max", Number(s.max)},
          {"count", s.count}};
}

std::optional<Json> ReadJsonFile(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return std::nullopt;
  try {
    return Json::parse(ReadFileToString(path));
  } catch (const std::exception&) {
    return std::nullopt;  // a damaged record is recomputed
  }
}

void AddCamera(Hasher& h, const camera::Camera& camera) {
  h.AddInt(static_cast<int64_t>(camera.model)).AddInt(camera.width).AddInt(camera.height);
  h.AddInt(static_cast<int64_t>(camera.params.size()));
  for (double p : camera.params) h.AddDouble(p);
}

void AddPose(Hasher& h, const camera::Pose& pose) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) h.AddDouble(pose.rotation(r, c));
    h.AddDouble(pose.translation[r]);
  }
}

// Size whose shorter side is `short_side` (never larger than the original; 0 = original).
std::pair<int, int> ScaledSize(int width, int height, int short_side) {
  const int shorter = std::min(width, height);
  if (short_side <= 0 || shorter <= short_side) return {width, height};
  const double scale = static_cast<double>(short_side) / shorter;
  int w = std::max(1, static_cast<int>(std::lround(width * scale)));
  int h = std::max(1, static_cast<int>(std::lround(height * scale)));
  (width <= height ? w : h) = short_side;
  return {w, h};
}

// The name of each view's downscaled training photo: "dir/a.jpg" -> "dir/a.png", or, when two
// views of the scene would share one ("a.jpg" and "a.png"), "a.jpg.png" for every view.
std::map<std::string, std::string> PngNames(const scene::Scene& scene) {
  std::map<std::string, std::string> png_names;
  std::set<std::string> seen;
  bool distinct = true;
  for (const scene::View& view : scene.views) {
    const std::string png = fs::path(view.name).replace_extension(".png").generic_string();
    distinct &= seen.insert(png).second;
    png_names[view.name] = png;
  }
  if (!distinct) {
    for (const scene::View& view : scene.views) png_names[view.name] = view.name + ".png";
  }
  return png_names;
}

std::string JoinLines(const std::vector<std::string>& names) {
  std::string text;
  for (const std::string& name : names) text += name + "\n";
  return text;
}

std::string Shorten(const std::string& text, size_t max_chars = 160) {
  std::string one_line = text;
  std::replace(one_line.begin(), one_line.end(), '\n', ' ');
  if (one_line.size() <= max_chars) return one_line;
  return one_line.substr(0, max_chars) + "...";
}

// Relative path of `path` inside `root` ("folds/fold_00/renders/a.png").
std::string RelativeTo(const fs::path& path, const fs::path& root) {
  return path.lexically_relative(root).generic_string();
}

// An image <folder>/<stem>.<ext> for any extension ReadImage handles; empty if none.
fs::path FindImageByStem(const fs::path& folder, const std::string& stem) {
  std::error_code ec;
  for (const char* ext : kImageExtensions) {
    const fs::path candidate = folder / (stem + ext);
    if (fs::is_regular_file(candidate, ec)) return candidate;
  }
  return {};
}

void RemoveStaleErrorImages(const fs::path& errors_dir, const std::string& stem) {
  std::error_code ec;
  for (metrics::Metric metric : metrics::AllMetrics()) {
    const std::string base = stem + "." + std::string(metrics::MetricName(metric));
    fs::remove(errors_dir / (base + ".exr"), ec);
    fs::remove(errors_dir / (base + ".png"), ec);
  }
}

// Makes `dir` hold exactly `files` (relative name -> source file), each a hard link to its
// source (a symbolic link when hard links are impossible, e.g. across file systems); other
// files in `dir` are removed. Existing links to the right file are kept.
void SyncLinkedFolder(const fs::path& dir, const std::map<std::string, fs::path>& files) {
  std::set<fs::path> expected;
  std::error_code ec;
  for (const auto& [name, source] : files) {
    // Names passed the scene boundary's rule; checked again because this removes files.
    REPHOTO_CHECK(scene::CheckedImageName(name, dir.string()) == name,
                  "{}: image name '{}' is not in normal form", dir.string(), name);
    const fs::path target = (dir / name).lexically_normal();
    expected.insert(target);
    if (fs::exists(target, ec) && fs::equivalent(target, source, ec)) continue;
    fs::create_directories(target.parent_path(), ec);
    fs::remove(target, ec);
    ec.clear();
    fs::create_hard_link(source, target, ec);
    if (ec) {
      ec.clear();
      fs::create_symlink(fs::absolute(source).lexically_normal(), target, ec);
    }
    if (ec) {
      ec.clear();
      fs::copy_file(source, target, fs::copy_options::overwrite_existing, ec);
    }
    REPHOTO_CHECK(!ec, "{}: cannot link or copy {} there: {}", dir.string(), source.string(),
                  ec.message());
  }
  std::vector<fs::path> stale;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_directory() && !expected.count(it->path().lexically_normal())) {
      stale.push_back(it->path());
    }
  }
  for (const fs::path& path : stale) fs::remove(path, ec);
}

// ------------------------------------------------------------------------------ the plan

struct TestView {
  std::string name;  // scene name
  std::string stem;
  size_t view_index = 0;  // into the full scene
  camera::Camera camera;  // at the evaluation resolution
  camera::Pose pose;
  fs::path photo;  // original photo
  std::string photo_hash;
  fs::path mask;  // photo mask (original resolution), empty = none
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
  fs::path record;
  bool reused = false;
};

struct FoldState {
  size_t index = 0;
  std::string name;                      // fold_00
  fs::path dir;                          // RUN/folds/fold_00
  std::vector<std::string> train_names;  // the views the fold trains on
  std::vector<TestView> tests;
  // Folders and files the commands see.
  fs::path train_dir, images_dir, train_list;
  fs::path test_dir, test_list;
  fs::path out_dir;  // RUN/folds/fold_00/reconstruction
  fs::path log_file;
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

  // Rephoto stage.
  bool ok = true;
  std::string message;
  fs::path model_path;     // the model file rendered
  bool gaussians = false;  // model_path holds 3D Gaussians (splat/gaussians.h)
  std::string model_key;
  std::string colorize_key;
  double colorize_seconds = 0;
  std::vector<ViewOutcome> views;
  double seconds = 0;  // this run's wall time of the rephoto stage
};

// -------------------------------------------------------------------- built-in renderers

// Renders a fold's model at its test cameras. The built-in representations live here:
// "auto" renders the model as what it is (mesh or point cloud, render/render_model.h).
// View-dependent texturing ("vdt") and image-based rendering ("ibr") need the fold's training
// photos and cameras too: they get the FoldState (train_names, train scene) when added.
class FoldRenderer {
 public:
  virtual ~FoldRenderer() = default;
  virtual void Render(const TestView& view, render::Rephoto* out) = 0;
};

class ModelRenderer : public FoldRenderer {
 public:
  ModelRenderer(std::shared_ptr<const render::RenderModel> model, render::RenderOptions options)
      : model_(std::move(model)), options_(options) {}
  void Render(const TestView& view, render::Rephoto* out) override {
    const auto rays = model_->RaysFor(view.camera);
    render::RenderRephoto(*model_, *rays, view.pose, options_, out);
  }

 private:
  std::shared_ptr<const render::RenderModel> model_;
  render::RenderOptions options_;
};

// 3D Gaussian splatting models: the CPU forward pass of the reference rasterizer.
class GaussianFoldRenderer : public FoldRenderer {
 public:
  GaussianFoldRenderer(std::shared_ptr<const splat::GaussianModel> model,
                       splat::GaussianRenderOptions options)
      : model_(std::move(model)), options_(options) {}
  void Render(const TestView& view, render::Rephoto* out) override {
    splat::RenderGaussians(*model_, view.camera, view.pose, options_, &rendering_);
    std::swap(out->color, rendering_.color);
    std::swap(out->depth, rendering_.depth);
  }

 private:
  std::shared_ptr<const splat::GaussianModel> model_;
  splat::GaussianRenderOptions options_;
  splat::GaussianRendering rendering_;
};

// The built-in renderer of `representation` for one fold: `model` is the fold's prepared
// model; `training_scene` loads the fold's training scene exactly as the reconstruct command
// and --colorize see it (photos possibly downscaled, cameras scaled with them), which the
// image-based representations ("vdt": training photos reprojected through the model; "ibr":
// per-view depth maps as proxies, ibr/image_based_renderer.h) need besides the model. They are
// added here; EvaluateOptions::Check accepts only "auto" until then.
// Image-based representations (ibr/image_based_renderer.h): the fold's training photos
// reprojected into the novel view through the model ("vdt") or through per-view depth maps
// ("ibr": files from --depth-maps, else plane-sweep stereo over the training photos). Only the
// fold's training photos are used, never the test photo (evaluate's folds guarantee it).
class ImageBasedFoldRenderer : public FoldRenderer {
 public:
  explicit ImageBasedFoldRenderer(ibr::ImageBasedRenderer renderer)
      : renderer_(std::move(renderer)) {}
  void Render(const TestView& view, render::Rephoto* out) override {
    renderer_.Render(view.camera, view.pose, out);
  }

 private:
  ibr::ImageBasedRenderer renderer_;
};

std::unique_ptr<FoldRenderer> MakeFoldRenderer(const std::string& representation,
                                               std::shared_ptr<const render::RenderModel> model,
                                               const render::RenderOptions& options,
                                               const std::function<scene::Scene()>& training_scene,
                                               const fs::path& depth_maps) {
  if (representation == "auto") return std::make_unique<ModelRenderer>(std::move(model), options);
  const scene::Scene train = training_scene();
  std::vector<size_t> indices(train.views.size());
  for (size_t i = 0; i < indices.size(); ++i) indices[i] = i;
  ibr::ImageBasedOptions ibr_options;
  ibr_options.scene_points = ibr::ScenePoints(train);
  auto views = ibr::TrainingViewsFromScene(train, indices,
                                           representation == "ibr" ? depth_maps : fs::path());
  if (representation == "vdt") {
    REPHOTO_CHECK(model && !model->mesh().is_point_cloud(),
                  "--representation vdt needs a mesh as geometry proxy (got a point cloud)");
    return std::make_unique<ImageBasedFoldRenderer>(
        ibr::ImageBasedRenderer::Vdt(model->mesh(), std::move(views), ibr_options));
  }
  if (representation == "ibr") {
    return std::make_unique<ImageBasedFoldRenderer>(
        ibr::ImageBasedRenderer::Ibr(std::move(views), ibr_options));
  }
  throw UsageError(fmt::format("--representation {}: not available", representation));
}

// ------------------------------------------------------------------------------ the run

class Evaluation {
 public:
  explicit Evaluation(const EvaluateOptions& options) : o_(options) {}
  EvaluateResult Run();

 private:
  void ReadInputs();
  void PrepareRunDirectory();
  void MakeSplit();
  void PrepareFold(FoldState& fold);
  void WriteFoldScene(const scene::Scene& part, const fs::path& dir, const std::string& list_name,
                      const std::vector<std::string>& names);
  std::string TrainKey(const scene::Scene& train, int short_side) const;
  void CommandStage(FoldState& fold);
  bool ValidateCommandOutput(FoldState& fold);
  void RephotoStage(FoldState& fold, Progress& progress);
  void ComputeModelKey(FoldState& fold, std::optional<mesh::Mesh>* mesh);
  scene::Scene TrainingScene(const FoldState& fold) const;
  void RemoveStaleOutputs() const;
  std::string ModelFileKey(const fs::path& path, const mesh::Mesh& mesh);
  void EvaluateView(FoldState& fold, const TestView& test, FoldRenderer* renderer,
                    const std::string& base_key, ViewOutcome* outcome);
  const Image& EvalPhoto(const TestView& test, Image* scratch, fs::path* used_path);
  // EvaluateOptions::cache_dir, else RUN/cache.
  fs::path CacheDir() const {
    return o_.cache_dir.empty() ? run_ / "cache" : fs::absolute(o_.cache_dir).lexically_normal();
  }
  std::optional<Mask> EvalMask(const TestView& test);
  std::string ViewKey(const FoldState& fold, const TestView& test, const std::string& base,
                      const std::string& render_hash) const;
  bool ReuseView(const fs::path& record, const std::string& key, ViewOutcome* outcome) const;
  void WriteViewRecord(const FoldState& fold, const ViewOutcome& outcome) const;
  void WriteFoldJson(const FoldState& fold, const std::string& status) const;
  void FailFold(FoldState& fold, const std::string& message);
  void Aggregate(EvaluateResult* result);
  void ProjectAndReport(EvaluateResult* result);
  // The metric projected onto the model, or none (no projection, or it cannot be made: the
  // reason is logged once).
  std::optional<metrics::Metric> ProjectionMetric();
  void ProjectFold(const FoldState& fold);
  // Runs `project`; a failure is a warning and run.json's projection_error, not the run's.
  void GuardProjection(const std::function<void()>& project);
  // The rendered model is made from the fold's model: coloured and/or degraded (model.ply).
  bool DerivesModel() const { return o_.colorize || HasDefects(o_.degrade); }
  // Whether `path` is rendered as 3D Gaussians (representation gaussians, or auto and a file
  // with Gaussian properties).
  bool IsGaussianModel(const fs::path& path);
  std::shared_ptr<const splat::GaussianModel> LoadGaussians(const fs::path& path,
                                                            const std::string& key);
  splat::GaussianRenderOptions GaussianOptions() const;
  void ProjectOntoGaussians(const fs::path& model_path, const std::string& model_key,
                            const std::vector<project::ProjectView>& views,
                            const std::string& metric_name, const fs::path& out);
  void ProjectOnto(const fs::path& model_path, const std::string& model_key,
                   const std::vector<const FoldState*>& folds, metrics::Metric metric,
                   const fs::path& out);
  void WriteRunJson(const EvaluateResult* result, const std::string& status);

 public:
  // After a failure that ends the run: run.json's status becomes "failed" with the message
  // (an interrupted run keeps "interrupted"). Does nothing before the run folder is ours.
  void RecordFailure(const std::string& message) {
    if (!run_json_ours_ || InterruptRequested()) return;
    failure_ = message;
    try {
      WriteRunJson(nullptr, "failed");
    } catch (const std::exception&) {
      // The original error is the one to report.
    }
  }

 private:
  void WriteManifest();
  compare::CompareOptions CompareSettings() const;
  std::string CompareSettingsKey() const;
  std::string RenderSettingsKey() const;
  std::string CommandTemplate() const { return o_.render.empty() ? o_.reconstruct : o_.render; }
  const char* CommandKind() const { return o_.render.empty() ? "reconstruct" : "render"; }
  int CommandThreads() const;

  EvaluateOptions o_;
  ModelSource source_ = ModelSource::kModel;
  fs::path run_;
  Clock::time_point start_;
  double start_cpu_ = 0;  // ProcessCpuSeconds() at start_
  scene::Scene scene_;
  scene::SceneSource scene_source_;
  std::vector<std::string> missing_photos_;
  std::map<std::string, std::string> stems_;
  run::RunFolder run_folder_;   // locked from PrepareRunDirectory on
  std::string failure_;         // run.json's "error" of a failed run
  bool run_json_ours_ = false;  // run.json is this scene's run (set once the identity matched)
  std::map<std::string, size_t> view_index_;
  std::vector<std::string> photo_names_;  // views with a photo, scene order
  split::Split split_;
  std::string scheme_text_;
  std::unique_ptr<FileHashCache> hashes_;
  std::vector<FoldState> folds_;
  EvaluateCounters counters_;
  EvaluateTimings timings_;
  std::mutex timings_mutex_;
  compare::CompareWorkspace compare_workspace_;
  // Full-size photos decoded before downscaling: one buffer reused for all of them (a fresh
  // 6-24 MP float image costs more in zeroing and page faults than in decoding).
  Image full_photo_scratch_;
  // Buffers of EvaluateView, reused from view to view (same sizes: no allocation, no page
  // faults): the rendering, its depth, the rendering compared and the evaluation photo.
  render::Rephoto rephoto_scratch_;
  Image render_scratch_, eval_photo_scratch_;
  // The last built render model, reused by the next fold when its key is the same (one model
  // for all folds).
  std::string cached_model_key_;
  std::shared_ptr<const render::RenderModel> cached_model_;
  // Model file keys by "<path>\n<content hash>", so a shared model is parsed once.
  std::map<std::string, std::string> model_file_keys_;
  Json scene_identity_;
  std::shared_ptr<const splat::GaussianModel> cached_gaussians_;  // the last Gaussian model read
  std::string cached_gaussians_key_;
  std::map<fs::path, bool> is_gaussian_file_;        // splat::IsGaussianFile, asked once per file
  fs::path cached_model_path_;                       // the file cached_model_ was built from
  std::string projection_message_, report_message_;  // why they were not written
  bool projection_checked_ = false;
  std::optional<metrics::Metric> projection_metric_;
};

// ------------------------------------------------------------------------------ settings

compare::CompareOptions Evaluation::CompareSettings() const {
  compare::CompareOptions c;
  c.metrics = o_.metrics;
  c.metric_options = o_.metric_options;
  c.exposure = o_.exposure;
  c.resize = o_.resize;
  c.write_error_images = o_.error_images;
  return c;
}

std::string Evaluation::CompareSettingsKey() const {
  Hasher h;
  h.Add("compare");
  for (metrics::Metric m : o_.metrics) h.Add(metrics::MetricName(m));
  const metrics::MetricOptions& mo = o_.metric_options;
  h.AddInt(mo.window).AddInt(mo.ssim_gaussian).AddInt(mo.ssim_window).AddDouble(mo.ssim_sigma);
  h.AddDouble(mo.ncc_flat_threshold).AddInt(mo.icid_window).AddDouble(mo.icid_sigma);
  h.AddDouble(o_.exposure.dark_threshold).AddDouble(o_.exposure.saturated_threshold);
  h.AddInt(o_.resize).AddInt(o_.error_images).AddInt(o_.eval_short_side);
  h.Add(compare::ToolVersion());
  return h.Hex();
}

bool Evaluation::IsGaussianModel(const fs::path& path) {
  if (path.empty() || (o_.representation != "auto" && o_.representation != "gaussians")) {
    return false;
  }
  if (o_.representation == "gaussians") return true;
  const auto [it, inserted] = is_gaussian_file_.emplace(path, false);
  if (inserted) it->second = splat::IsGaussianFile(path);
  return it->second;
}

std::shared_ptr<const splat::GaussianModel> Evaluation::LoadGaussians(const fs::path& path,
                                                                      const std::string& key) {
  if (!cached_gaussians_ || cached_gaussians_key_ != key) {
    cached_gaussians_.reset();
    const auto start = Clock::now();
    splat::GaussianFormat format;
    auto model = std::make_shared<splat::GaussianModel>(splat::ReadGaussians(path, &format));
    LogInfo(fmt::format("{}: {} Gaussians ({}, SH degree {}) read in {:.1f} s", path.string(),
                        model->size(), splat::GaussianFormatName(format), model->sh_degree,
                        Seconds(start)));
    cached_gaussians_ = std::move(model);
    cached_gaussians_key_ = key;
  }
  return cached_gaussians_;
}

splat::GaussianRenderOptions Evaluation::GaussianOptions() const {
  splat::GaussianRenderOptions options;
  options.mode = o_.gaussian_mode == "antialiased" ? splat::GaussianMode::kAntialiased
                                                   : splat::GaussianMode::kClassic;
  options.background = Eigen::Vector3f(o_.background[0], o_.background[1], o_.background[2]);
  return options;
}

std::string Evaluation::RenderSettingsKey() const {
  Hasher h;
  h.Add("render").Add(o_.representation).AddInt(o_.samples_per_pixel).AddInt(o_.backfaces);
  h.AddDouble(o_.point_radius).AddInt(o_.point_neighbors);
  return h.Hex();
}

int Evaluation::CommandThreads() const {
  const int all = static_cast<int>(
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  return std::max(1, all / std::max(1, o_.jobs));
}

// ------------------------------------------------------------------------------ inputs

void Evaluation::ReadInputs() {
  scene::ReadSceneOptions read_options;
  if (!o_.format.empty()) {
    read_options.format = scene::ParseSceneFormat(o_.format);
    if (!read_options.format) {
      throw UsageError(fmt::format("--format '{}': unknown format (supported: {})", o_.format,
                                   scene::SceneFormatList()));
    }
  }
  if (!o_.image_root.empty()) read_options.image_root = o_.image_root;
  scene_ = scene::ReadScene(o_.scene, read_options, &scene_source_);
  missing_photos_ = scene::MissingImages(scene_);
  const std::set<std::string> missing(missing_photos_.begin(), missing_photos_.end());
  for (size_t v = 0; v < scene_.views.size(); ++v) {
    view_index_[scene_.views[v].name] = v;
    if (missing.count(scene_.views[v].name)) {
      LogWarning(fmt::format("{}: photo {} not found: view '{}' left out of the evaluation",
                             o_.scene.string(), scene_.views[v].image_path.string(),
                             scene_.views[v].name));
    }
    if (!missing.count(scene_.views[v].name)) photo_names_.push_back(scene_.views[v].name);
  }
  REPHOTO_CHECK(!photo_names_.empty(), "{}: none of the {} photos exists (image root {})",
                o_.scene.string(), scene_.views.size(), scene_.image_root.string());
  const std::vector<std::string> stems = scene::OutputStems(scene_);
  for (size_t v = 0; v < scene_.views.size(); ++v) stems_[scene_.views[v].name] = stems[v];
}

void Evaluation::PrepareRunDirectory() {
  std::error_code ec;
  // One writer, and only a folder that holds an evaluate run or nothing (run/run_folder.h);
  // folders from before the mark are recognised by their run.json.
  run_folder_ = run::OpenRunFolder(run_, "evaluate", [](const fs::path& dir) {
    std::error_code exists_ec;
    return fs::exists(dir / "run.json", exists_ec);
  });
  // Identity of the scene: the set of its image names.
  std::vector<std::string> names;
  for (const scene::View& view : scene_.views) names.push_back(view.name);
  std::sort(names.begin(), names.end());
  Hasher h;
  for (const std::string& name : names) h.Add(name);
  const std::string identity = h.Hex();
  const fs::path run_json = run_ / "run.json";
  if (fs::exists(run_json, ec)) {
    const std::optional<Json> previous = ReadJsonFile(run_json);
    REPHOTO_CHECK(previous && previous->contains("scene_identity"),
                  "{}: not a rephoto evaluate run (unreadable run.json); use another --out",
                  run_json.string());
    const Json& old = (*previous)["scene_identity"];
    REPHOTO_CHECK(old.value("names_hash", "") == identity,
                  "{}: holds a run of another scene ({}, {} images; this scene {} has {} "
                  "images with other names); use another --out or delete it",
                  run_.string(), old.value("scene", "?"), old.value("images", 0), o_.scene.string(),
                  names.size());
  }
  scene_identity_ = {{"scene", fs::absolute(o_.scene).lexically_normal().string()},
                     {"format", std::string(scene::SceneFormatName(scene_source_.format))},
                     {"images", names.size()},
                     {"names_hash", identity}};
  hashes_ = std::make_unique<FileHashCache>(CacheDir() / "file_hashes.json");
  WriteRunJson(nullptr, "running");  // marks the folder as this scene's run from now on
  run_json_ours_ = true;
}

void Evaluation::MakeSplit() {
  scheme_text_ = ResolvedScheme(o_, photo_names_.size());
  const split::Scheme scheme = split::ParseScheme(scheme_text_);  // UsageError when bad
  if (scheme.kind == split::SchemeKind::kLeaveOneOut || scheme.kind == split::SchemeKind::kKFold ||
      scheme.kind == split::SchemeKind::kInterleaved) {
    REPHOTO_CHECK(photo_names_.size() >= 2, "{}: {} needs at least 2 photos, found {}",
                  o_.scene.string(), scheme_text_, photo_names_.size());
  }
  split_ = split::MakeSplit(photo_names_, scheme);
  const scene::Scene with_photos = split::SubsetScene(scene_, photo_names_, /*keep_points=*/true);
  split::WriteSplit(with_photos, split_,
                    {o_.scene.string(), std::string(scene::SceneFormatName(scene_source_.format))},
                    run_ / "split");
}

std::string Evaluation::TrainKey(const scene::Scene& train, int short_side) const {
  Hasher h;
  h.Add(kKeyVersion).Add("train").AddInt(short_side);
  for (const scene::View& view : train.views) {
    h.Add(view.name);
    AddCamera(h, train.CameraOf(view));
    AddPose(h, view.cam_from_world);
  }
  h.AddInt(static_cast<int64_t>(train.points.size()));
  for (const scene::Point3D& point : train.points) {
    for (int i = 0; i < 3; ++i) h.AddDouble(point.position[i]).AddInt(point.color[i]);
    h.AddInt(static_cast<int64_t>(point.track.size()));
    for (const scene::Observation& obs : point.track) {
      h.AddInt(obs.view_index).AddDouble(obs.pixel.x()).AddDouble(obs.pixel.y());
    }
  }
  return h.Hex();
}

void Evaluation::WriteFoldScene(const scene::Scene& part, const fs::path& dir,
                                const std::string& list_name,
                                const std::vector<std::string>& names) {
  scene::WriteColmap(part, dir / "sparse", scene::ColmapFormat::kText);
  try {
    scene::WriteTransformsJson(part, dir / "transforms.json");
  } catch (const Error& e) {
    LogWarning(fmt::format("{}: not written: {}", (dir / "transforms.json").string(), e.what()));
  }
  WriteTextFileAtomically(dir / list_name, JoinLines(names));
}

void Evaluation::PrepareFold(FoldState& fold) {
  const split::Fold& sf = split_.folds[fold.index];
  const fs::path split_dir = run_ / "split" / fold.name;
  fold.dir = run_ / "folds" / fold.name;
  fold.out_dir = fold.dir / "reconstruction";
  fold.log_file = run_ / "logs" / fmt::format("{}.{}.log", fold.name, CommandKind());
  fold.previous = ReadJsonFile(fold.dir / "fold.json");

  // Training views: all, or a seeded subset.
  fold.train_names = sf.train;
  if (o_.train_count > 0 && static_cast<size_t>(o_.train_count) < fold.train_names.size()) {
    split::SeededShuffle(fold.train_names, o_.train_seed + fold.index);
    fold.train_names.resize(static_cast<size_t>(o_.train_count));
    std::sort(fold.train_names.begin(), fold.train_names.end());
  } else if (o_.train_count > 0) {
    LogWarning(fmt::format("{}: --train-count {} >= the fold's {} training views: using all",
                           fold.name, o_.train_count, fold.train_names.size()));
  }
  scene::Scene train = split::SubsetScene(scene_, fold.train_names, /*keep_points=*/true);
  Hasher photos;
  for (const std::string& name : fold.train_names) {
    photos.Add(name).Add(hashes_->Hash(scene_.views[view_index_.at(name)].image_path));
  }
  // Commands see a folder with only the fold's training photos (links), so that a pipeline
  // that takes every image of {images} cannot see a test photo.
  const bool commands = source_ != ModelSource::kModel;
  const bool own_train =
      o_.train_count > 0 || o_.train_short_side > 0;  // else the split's scene is used
  fold.images_dir = scene_.image_root;
  if (commands && o_.train_short_side == 0) {
    fold.images_dir = fold.dir / "train" / "images";
    std::map<std::string, fs::path> links;
    for (scene::View& view : train.views) {
      links[view.name] = view.image_path;
      view.image_path = fold.images_dir / view.name;
    }
    SyncLinkedFolder(fold.images_dir, links);
    train.image_root = fold.images_dir;
  }
  if (!own_train) {
    fold.train_dir = split_dir / "train";
    fold.train_list = split_dir / "train.txt";
  } else {
    fold.train_dir = fold.dir / "train";
    fold.train_list = fold.train_dir / "train.txt";
    if (o_.train_short_side > 0) {
      // Downscaled photos as PNG in the fold's images/ folder (hard links to one shared cache,
      // so a photo is decoded and filtered once for all folds); cameras scaled with them.
      fold.images_dir = fold.train_dir / "images";
      const fs::path cache_dir = CacheDir() / fmt::format("train_photos_s{}", o_.train_short_side);
      std::map<int, std::pair<int, int>> new_sizes;
      for (const auto& [id, camera] : train.cameras) {
        new_sizes[id] = ScaledSize(camera.width, camera.height, o_.train_short_side);
      }
      std::map<std::string, fs::path> links;
      const std::map<std::string, std::string> png_names = PngNames(scene_);
      for (size_t v = 0; v < train.views.size(); ++v) {
        scene::View& view = train.views[v];
        const camera::Camera& camera = train.CameraOf(view);
        const auto [w, h] = new_sizes.at(view.camera_id);
        if (w == camera.width && h == camera.height) {
          // Already at most that size: the pipeline gets the original file, not a re-encoding.
          links[view.name] = view.image_path;
          view.image_path = fold.images_dir / view.name;
          continue;
        }
        const std::string png_name = png_names.at(view.name);
        const fs::path cached = cache_dir / png_name;
        const fs::path cached_key = cache_dir / (png_name + ".key");
        const fs::path target = fold.images_dir / png_name;
        const std::string key =
            Hasher().Add(hashes_->Hash(view.image_path)).AddInt(w).AddInt(h).Hex();
        std::error_code ec;
        if (!(fs::is_regular_file(cached, ec) && fs::is_regular_file(cached_key, ec) &&
              ReadFileToString(cached_key) == key)) {
          fs::remove(cached_key, ec);
          Image& photo = full_photo_scratch_;
          io::ReadImage(view.image_path, &photo);
          REPHOTO_CHECK(photo.width() == camera.width && photo.height() == camera.height,
                        "{}: photo is {}x{} but its camera is {}x{}", view.image_path.string(),
                        photo.width(), photo.height(), camera.width, camera.height);
          Image scaled;
          compare::ResizeImage(photo, w, h, &scaled);
          io::WritePng(cached, scaled, io::PngDepth::k8, io::PngCompression::kNone);
          WriteTextFileAtomically(cached_key, key);
          ++counters_.photos_downscaled;
        }
        links[png_name] = cached;
        view.name = png_name;
        view.image_path = target;
      }
      SyncLinkedFolder(fold.images_dir, links);
      // Observations move with the pixels.
      for (auto& [id, camera] : train.cameras) {
        const auto [w, h] = new_sizes.at(id);
        const double sx = static_cast<double>(w) / camera.width;
        const double sy = static_cast<double>(h) / camera.height;
        for (scene::Point3D& point : train.points) {
          for (scene::Observation& obs : point.track) {
            if (train.views[obs.view_index].camera_id == id) {
              obs.pixel = Eigen::Vector2d(obs.pixel.x() * sx, obs.pixel.y() * sy);
            }
          }
        }
        camera = camera.Scaled(w, h);
      }
      train.image_root = fold.images_dir;
    }
    std::vector<std::string> listed;
    for (const scene::View& view : train.views) listed.push_back(view.name);
    WriteFoldScene(train, fold.train_dir, "train.txt", listed);
  }
  fold.train_key = Hasher().Add(TrainKey(train, o_.train_short_side)).Add(photos.Hex()).Hex();

  // Test views at the evaluation resolution.
  scene::Scene test = split::SubsetScene(scene_, sf.test, /*keep_points=*/false);
  bool scaled_test = false;
  for (auto& [id, camera] : test.cameras) {
    const auto [w, h] = ScaledSize(camera.width, camera.height, o_.eval_short_side);
    if (w != camera.width || h != camera.height) {
      camera = camera.Scaled(w, h);
      scaled_test = true;
    }
  }
  if (scaled_test) {
    fold.test_dir = fold.dir / "test";
    fold.test_list = fold.test_dir / "test.txt";
    WriteFoldScene(test, fold.test_dir, "test.txt", sf.test);
  } else {
    fold.test_dir = split_dir / "test";
    fold.test_list = split_dir / "test.txt";
  }
  Hasher test_key;
  test_key.Add(kKeyVersion).Add("test");
  for (const scene::View& view : test.views) {
    TestView t;
    t.name = view.name;
    t.stem = stems_.at(view.name);
    t.view_index = view_index_.at(view.name);
    t.camera = test.CameraOf(view);
    t.pose = view.cam_from_world;
    t.photo = fs::absolute(view.image_path).lexically_normal();
    t.photo_hash = hashes_->Hash(t.photo);
    if (!o_.photo_masks.empty()) {
      t.mask = FindImageByStem(o_.photo_masks, t.stem);
      REPHOTO_CHECK(!t.mask.empty(), "{}: no mask named '{}' for photo {}", o_.photo_masks.string(),
                    t.stem, t.photo.string());
    } else if (view.mask_path) {
      t.mask = *view.mask_path;
    }
    if (!t.mask.empty()) t.mask_hash = hashes_->Hash(t.mask);
    test_key.Add(t.name).Add(t.stem);
    AddCamera(test_key, t.camera);
    AddPose(test_key, t.pose);
    fold.tests.push_back(std::move(t));
  }
  fold.test_key = test_key.Hex();
}

// The fold's training views as the reconstruct command sees them: the downscaled photos and
// scaled cameras of RUN/folds/fold_XX/train when --train-short-side is set, else the scene's.
scene::Scene Evaluation::TrainingScene(const FoldState& fold) const {
  if (o_.train_short_side > 0) {
    scene::ReadSceneOptions read;
    read.format = scene::SceneFormat::kColmap;
    read.image_root = fold.images_dir;
    return scene::ReadScene(fold.train_dir / "sparse", read);
  }
  return split::SubsetScene(scene_, fold.train_names, /*keep_points=*/true);
}

// Results of an earlier run with another split (other folds, other test views per fold) are
// removed, so that every file in RUN belongs to this run's settings (project and report scan
// the folders).
void Evaluation::RemoveStaleOutputs() const {
  std::set<std::string> fold_names;
  for (const FoldState& fold : folds_) fold_names.insert(fold.name);
  std::error_code ec;
  for (const fs::path& parent : {run_ / "folds", run_ / "split"}) {
    std::vector<fs::path> stale;
    for (fs::directory_iterator it(parent, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (it->is_directory() && name.rfind("fold_", 0) == 0 && !fold_names.count(name)) {
        stale.push_back(it->path());
      }
    }
    for (const fs::path& path : stale) fs::remove_all(path, ec);
  }
  std::vector<fs::path> stale_logs;
  for (fs::directory_iterator it(run_ / "logs", ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!fold_names.count(name.substr(0, name.find('.')))) stale_logs.push_back(it->path());
  }
  for (const fs::path& path : stale_logs) fs::remove(path, ec);
  for (const FoldState& fold : folds_) {
    std::set<fs::path> allowed;
    for (const TestView& test : fold.tests) {
      allowed.insert(fold.dir / "views" / (test.stem + ".json"));
      allowed.insert(fold.dir / "renders" / (test.stem + ".png"));
      allowed.insert(fold.dir / "renders" / (test.stem + ".depth.exr"));
      for (metrics::Metric metric : metrics::AllMetrics()) {
        const std::string base = test.stem + "." + std::string(metrics::MetricName(metric));
        allowed.insert(fold.dir / "errors" / (base + ".exr"));
        allowed.insert(fold.dir / "errors" / (base + ".png"));
      }
    }
    for (const char* folder : {"views", "renders", "errors"}) {
      std::vector<fs::path> stale;
      for (fs::recursive_directory_iterator it(fold.dir / folder, ec), end; !ec && it != end;
           it.increment(ec)) {
        if (it->is_regular_file() && !allowed.count(it->path().lexically_normal())) {
          stale.push_back(it->path());
        }
      }
      for (const fs::path& path : stale) fs::remove(path, ec);
    }
  }
}

// ------------------------------------------------------------------------- command stage

bool Evaluation::ValidateCommandOutput(FoldState& fold) {
  const std::string log = RelativeTo(fold.log_file, run_);
  const std::string head =
      fmt::format("{}: {} command '{}'", fold.name, CommandKind(), Shorten(CommandTemplate()));
  std::error_code ec;
  bool empty = true;
  for (fs::directory_iterator it(fold.out_dir, ec), end; !ec && it != end; it.increment(ec)) {
    empty = false;
    break;
  }
  if (empty) {
    FailFold(fold, fmt::format("{} wrote nothing into {}; see {}", head,
                               RelativeTo(fold.out_dir, run_), log));
    return false;
  }
  if (source_ == ModelSource::kReconstruct) {
    const fs::path model = fold.out_dir / o_.model;
    if (!fs::is_regular_file(model, ec)) {
      FailFold(fold,
               fmt::format("{} wrote no model {}; see {}", head, RelativeTo(model, run_), log));
      return false;
    }
    fold.model_path = model;
    return true;
  }
  // External renderer: one image per test view at the evaluation size.
  std::vector<std::string> missing, wrong, unreadable;
  for (const TestView& test : fold.tests) {
    const fs::path image = FindImageByStem(fold.out_dir, test.stem);
    if (image.empty()) {
      missing.push_back(test.stem);
      continue;
    }
    try {
      const io::ImageHeader header = io::ReadImageHeader(image);
      if (!o_.resize &&
          (header.width != test.camera.width || header.height != test.camera.height)) {
        wrong.push_back(fmt::format("{} is {}x{}, expected {}x{}", image.filename().string(),
                                    header.width, header.height, test.camera.width,
                                    test.camera.height));
      }
    } catch (const Error& e) {
      unreadable.push_back(e.what());
    }
  }
  if (!missing.empty()) {
    std::string list;
    for (size_t i = 0; i < missing.size() && i < 5; ++i) list += (i ? ", " : "") + missing[i];
    if (missing.size() > 5) list += ", ...";
    FailFold(fold, fmt::format("{} wrote {} of {} images (missing: {}); see {}", head,
                               fold.tests.size() - missing.size(), fold.tests.size(), list, log));
    return false;
  }
  if (!unreadable.empty()) {
    FailFold(fold,
             fmt::format("{} wrote {} unreadable image(s) ({}{}); see {}", head, unreadable.size(),
                         unreadable[0], unreadable.size() > 1 ? ", ..." : "", log));
    return false;
  }
  if (!wrong.empty()) {
    FailFold(fold, fmt::format("{} wrote {} image(s) of the wrong size ({}{}); see {}", head,
                               wrong.size(), wrong[0], wrong.size() > 1 ? ", ..." : "", log));
    return false;
  }
  return true;
}

void Evaluation::CommandStage(FoldState& fold) {
  Hasher key;
  key.Add(kKeyVersion)
      .Add(CommandKind())
      .Add(CommandTemplate())
      .AddInt(static_cast<int64_t>(fold.index));
  key.Add(fold.train_key).Add(fold.test_key);
  if (source_ == ModelSource::kReconstruct) key.Add(o_.model.generic_string());
  if (source_ == ModelSource::kRender) key.AddInt(o_.eval_short_side);
  fold.command_key = key.Hex();
  const std::map<std::string, std::string> values = {
      {"train", fold.train_dir.string()},
      {"sparse", (fold.train_dir / "sparse").string()},
      {"transforms", (fold.train_dir / "transforms.json").string()},
      {"images", fs::absolute(fold.images_dir).lexically_normal().string()},
      {"train_list", fold.train_list.string()},
      {"test", fold.test_dir.string()},
      {"test_sparse", (fold.test_dir / "sparse").string()},
      {"test_transforms", (fold.test_dir / "transforms.json").string()},
      {"test_list", fold.test_list.string()},
      {"out", fold.out_dir.string()},
      {"fold", std::to_string(fold.index)},
      {"threads", std::to_string(CommandThreads())}};
  fold.command =
      SubstitutePlaceholders(CommandTemplate(), values, std::string("--") + CommandKind());

  if (fold.previous && fold.previous->contains("command")) {
    const Json& previous = (*fold.previous)["command"];
    if (previous.value("key", "") == fold.command_key && previous.value("status", "") == "ok") {
      fold.command_reused = true;
      fold.command_seconds = previous.value("seconds", 0.0);
      fold.command_cpu_seconds = previous.value("cpu_seconds", 0.0);
      fold.command_status = "ok";
      if (ValidateCommandOutput(fold)) return;
      // The outputs changed since: run the command again.
      fold.command_reused = false;
      fold.ok = true;
      fold.message.clear();
    }
  }
  std::error_code ec;
  fs::remove_all(fold.out_dir, ec);
  fs::create_directories(fold.out_dir, ec);
  REPHOTO_CHECK(!ec, "{}: cannot create: {}", fold.out_dir.string(), ec.message());
  // Forget the previous command result before starting a new one.
  fold.command_status = "running";
  WriteFoldJson(fold, "running");
  LogInfo(fmt::format("{}: running the {} command (log: {})", fold.name, CommandKind(),
                      fold.log_file.string()));
  const CommandOutcome outcome = RunShellCommand(
      fold.command, fold.log_file, fmt::format("rephoto evaluate {} {}", fold.name, CommandKind()),
      o_.command_timeout);
  {
    std::lock_guard<std::mutex> lock(timings_mutex_);
    ++counters_.commands_run;
    timings_.external += outcome.seconds;
    timings_.external_cpu += outcome.cpu_seconds;
  }
  fold.external_seconds = outcome.seconds;
  fold.command_seconds = outcome.seconds;
  fold.command_cpu_seconds = outcome.cpu_seconds;
  fold.exit_status = outcome.exit_status;
  fold.command_status = "failed";
  if (outcome.interrupted) {
    fold.interrupted = true;
    fold.command_ok = false;
    return;
  }
  const std::string log = RelativeTo(fold.log_file, run_);
  if (!outcome.ok()) {
    const std::string last = LastLogLine(fold.log_file);
    const std::string why =
        outcome.timed_out
            ? fmt::format("timed out after {:g} s, --command-timeout", o_.command_timeout)
        : outcome.signal != 0
            ? fmt::format("killed by signal {}", outcome.signal)
            : fmt::format("exit status {}{}", outcome.exit_status,
                          outcome.exit_status == 127 ? ", command not found" : "");
    FailFold(fold, fmt::format("{}: {} command '{}' failed ({}); see {}{}", fold.name,
                               CommandKind(), Shorten(CommandTemplate()), why, log,
                               last.empty() ? "" : " (last line: " + last + ")"));
    fold.command_ok = false;
    return;
  }
  fold.command_ok = ValidateCommandOutput(fold);
  if (fold.command_ok) fold.command_status = "ok";
  LogInfo(fmt::format("{}: {} command finished in {:.1f} s{}", fold.name, CommandKind(),
                      outcome.seconds, fold.command_ok ? "" : " (failed)"));
}

void Evaluation::FailFold(FoldState& fold, const std::string& message) {
  fold.ok = false;
  fold.command_ok = false;
  if (fold.message.empty()) fold.message = message;
}

// ------------------------------------------------------------------------- rephoto stage

std::string Evaluation::ModelFileKey(const fs::path& path, const mesh::Mesh& mesh) {
  Hasher h;
  h.Add("model").Add(hashes_->Hash(path));
  for (const mesh::Material& material : mesh.materials) {
    h.Add(material.name);
    for (int c = 0; c < 3; ++c) h.AddDouble(material.diffuse[c]);
    h.Add(material.diffuse_texture.empty() ? std::string()
                                           : hashes_->Hash(material.diffuse_texture));
  }
  return h.Hex();
}

void Evaluation::ComputeModelKey(FoldState& fold, std::optional<mesh::Mesh>* mesh) {
  const std::string file_hash = hashes_->Hash(fold.model_path);
  const std::string cache_key = fold.model_path.string() + "\n" + file_hash;
  const auto cached = model_file_keys_.find(cache_key);
  if (cached != model_file_keys_.end()) {
    fold.model_key = cached->second;
  } else {
    try {
      mesh->emplace(mesh::ReadMesh(fold.model_path));
    } catch (const Error& e) {
      if (source_ == ModelSource::kReconstruct) {
        fold.command_status = "failed";  // rerun the command next time
        ThrowError("{}: reconstruct command '{}' wrote a model that cannot be read: {}; see {}",
                   fold.name, Shorten(CommandTemplate()), e.what(),
                   RelativeTo(fold.log_file, run_));
      }
      throw;
    }
    fold.model_key = ModelFileKey(fold.model_path, **mesh);
    model_file_keys_[cache_key] = fold.model_key;
  }
  if (DerivesModel()) {
    // The coloured and/or degraded model: its key covers what it was made from.
    Hasher h;
    h.Add(kKeyVersion).Add("colorize").Add(fold.model_key);
    if (o_.colorize) h.Add(fold.train_key);
    if (HasDefects(o_.degrade)) {
      h.Add("degrade")
          .AddDouble(o_.degrade.texture_noise)
          .AddDouble(o_.degrade.geometry_noise)
          .AddDouble(o_.degrade.simplify)
          .AddDouble(o_.degrade.noise_frequency)
          .AddInt(static_cast<int64_t>(o_.degrade.seed));
    }
    fold.colorize_key = h.Hex();
    fold.model_key = fold.colorize_key;
  }
}

std::string Evaluation::ViewKey(const FoldState& fold, const TestView& test,
                                const std::string& base, const std::string& render_hash) const {
  Hasher h;
  h.Add(kKeyVersion).Add("view").Add(base).Add(render_hash).Add(test.stem).Add(test.name);
  AddCamera(h, test.camera);
  AddPose(h, test.pose);
  h.Add(test.photo_hash).Add(test.mask_hash).Add(CompareSettingsKey());
  (void)fold;
  return h.Hex();
}

bool Evaluation::ReuseView(const fs::path& record, const std::string& key,
                           ViewOutcome* outcome) const {
  const std::optional<Json> json = ReadJsonFile(record);
  if (!json || json->value("key", "") != key || json->value("status", "") != "ok") return false;
  try {
    compare::ImageResult& image = outcome->image;
    image.name = json->at("name_stem").get<std::string>();
    image.photo = json->at("photo").get<std::string>();
    image.render = json->at("render").get<std::string>();
    image.width = json->at("width").get<int>();
    image.height = json->at("height").get<int>();
    image.resized = json->at("resized").get<bool>();
    const Json& c = json->at("completeness");
    image.completeness.value = JsonDouble(c.at("value"));
    image.completeness.valid_photo = c.at("valid_photo_windows").get<size_t>();
    image.completeness.valid_both = c.at("valid_both_windows").get<size_t>();
    const Json& m = json->at("metrics");
    image.metrics.clear();
    for (metrics::Metric metric : o_.metrics) {
      const Json& entry = m.at(std::string(metrics::MetricName(metric)));
      image.metrics.push_back({JsonDouble(entry.at("mean")), entry.at("evaluated").get<size_t>()});
    }
    outcome->render_seconds = json->value("render_seconds", 0.0);
    outcome->compare_seconds = json->value("compare_seconds", 0.0);
  } catch (const std::exception&) {
    return false;
  }
  // The files the record points to must still be there.
  std::error_code ec;
  if (!fs::exists(run_ / outcome->image.render, ec)) return false;
  if (o_.error_images) {
    for (metrics::Metric metric : o_.metrics) {
      const std::string base = outcome->stem + "." + std::string(metrics::MetricName(metric));
      if (!fs::exists(record.parent_path().parent_path() / "errors" / (base + ".exr"), ec)) {
        return false;
      }
    }
  }
  return true;
}

void Evaluation::WriteViewRecord(const FoldState& fold, const ViewOutcome& outcome) const {
  const compare::ImageResult& image = outcome.image;
  Json j;
  j["schema"] = "rephoto.evaluate.view/1";
  j["key"] = outcome.key;
  j["render_key"] = outcome.render_key.empty() ? Json() : Json(outcome.render_key);
  j["status"] = "ok";
  j["fold"] = fold.name;
  j["name"] = outcome.name;
  j["name_stem"] = image.name;
  j["photo"] = image.photo.string();
  j["render"] = image.render.generic_string();
  j["width"] = image.width;
  j["height"] = image.height;
  j["resized"] = image.resized;
  j["completeness"] = {{"value", Number(image.completeness.value)},
                       {"valid_photo_windows", image.completeness.valid_photo},
                       {"valid_both_windows", image.completeness.valid_both}};
  Json metrics_json = Json::object();
  for (size_t k = 0; k < o_.metrics.size(); ++k) {
    metrics_json[std::string(metrics::MetricName(o_.metrics[k]))] = {
        {"mean", Number(image.metrics[k].mean)}, {"evaluated", image.metrics[k].evaluated}};
  }
  j["metrics"] = metrics_json;
  j["render_seconds"] = outcome.render_seconds;
  j["compare_seconds"] = outcome.compare_seconds;
  WriteTextFileAtomically(outcome.record, j.dump(2) + "\n");
}

const Image& Evaluation::EvalPhoto(const TestView& test, Image* scratch, fs::path* used_path) {
  const camera::Camera& full = scene_.CameraOf(scene_.views[test.view_index]);
  if (full.width == test.camera.width && full.height == test.camera.height) {
    io::ReadImage(test.photo, scratch);
    *used_path = test.photo;
    return *scratch;
  }
  // Downscaled once into the cache, as 16-bit PNG (keeps the filtered values to 1/65535).
  const fs::path cache_dir = CacheDir() / "eval_photos";
  const fs::path cached = fs::absolute(cache_dir / (test.stem + ".png")).lexically_normal();
  const fs::path key_file = cache_dir / (test.stem + ".key");
  const std::string key =
      Hasher().Add(test.photo_hash).AddInt(test.camera.width).AddInt(test.camera.height).Hex();
  std::error_code ec;
  if (fs::is_regular_file(cached, ec) && fs::is_regular_file(key_file, ec)) {
    try {
      if (ReadFileToString(key_file) == key) {
        io::ReadImage(cached, scratch);
        if (scratch->width() == test.camera.width && scratch->height() == test.camera.height) {
          *used_path = cached;
          return *scratch;
        }
      }
    } catch (const Error&) {
      // recompute below
    }
  }
  Image& photo = full_photo_scratch_;
  io::ReadImage(test.photo, &photo);
  REPHOTO_CHECK(photo.width() == full.width && photo.height() == full.height,
                "{}: photo is {}x{} but its camera is {}x{}", test.photo.string(), photo.width(),
                photo.height(), full.width, full.height);
  compare::ResizeImage(photo, test.camera.width, test.camera.height, scratch);
  // The values compared are the cached file's (as if read back).
  io::WritePngAndQuantize(cached, scratch, io::PngDepth::k16, io::PngCompression::kNone);
  WriteTextFileAtomically(key_file, key);
  ++counters_.photos_downscaled;
  *used_path = cached;
  return *scratch;
}

std::optional<Mask> Evaluation::EvalMask(const TestView& test) {
  if (test.mask.empty()) return std::nullopt;
  Mask mask = io::ReadMask(test.mask);
  if (mask.width() != test.camera.width || mask.height() != test.camera.height) {
    Mask scaled;
    compare::ResizeMask(mask, test.camera.width, test.camera.height, &scaled);
    return scaled;
  }
  return mask;
}

void Evaluation::EvaluateView(FoldState& fold, const TestView& test, FoldRenderer* renderer,
                              const std::string& base_key, ViewOutcome* outcome) {
  const fs::path renders_dir = fold.dir / "renders";
  const fs::path errors_dir = fold.dir / "errors";
  fs::path render_path;
  Image& render = render_scratch_;
  auto start = Clock::now();
  if (outcome->reuse_render) {
    // Only compare settings changed: the rendering on disk is the one this view needs.
    render_path = renders_dir / (test.stem + ".png");
    io::ReadImage(render_path, &render);
  } else if (renderer != nullptr) {
    render::Rephoto& rephoto = rephoto_scratch_;
    renderer->Render(test, &rephoto);
    render_path = renders_dir / (test.stem + ".png");
    io::WritePngAndQuantize(render_path, &rephoto.color);  // compared as the PNG written
    io::WriteExr(renders_dir / (test.stem + ".depth.exr"), rephoto.depth);
    std::swap(render, rephoto.color);  // the next view renders into the previous buffer
    ++counters_.views_rendered;
  } else {
    render_path = FindImageByStem(fold.out_dir, test.stem);
    REPHOTO_CHECK(!render_path.empty(), "{}: no rendering named '{}'", fold.out_dir.string(),
                  test.stem);
    io::ReadImage(render_path, &render);
  }
  outcome->render_seconds = Seconds(start);
  timings_.render += outcome->render_seconds;

  start = Clock::now();
  fs::path photo_path;
  const Image& photo = EvalPhoto(test, &eval_photo_scratch_, &photo_path);
  const std::optional<Mask> mask = EvalMask(test);
  std::error_code ec;
  if (o_.error_images) {
    RemoveStaleErrorImages(errors_dir, test.stem);
    fs::create_directories((errors_dir / test.stem).parent_path(), ec);
  }
  // Gaussians: a pixel is the model's where its alpha reaches --min-alpha (the PNG's alpha, so
  // a reused rendering gives the same mask).
  std::optional<Mask> render_mask;
  if (fold.gaussians && (renderer != nullptr || outcome->reuse_render)) {
    render_mask.emplace(render.width(), render.height(), 1);
    const float* px = render.data();
    const int channels = render.channels();
    uint8_t* m = render_mask->data();
    for (size_t i = 0, n = static_cast<size_t>(render.width()) * render.height(); i < n; ++i) {
      m[i] = channels == 4 && px[i * 4 + 3] >= static_cast<float>(o_.min_alpha) ? 255 : 0;
    }
  }
  outcome->image = compare::ComparePhotoAndRender(
      CompareSettings(), test.stem, photo_path, fs::path(RelativeTo(render_path, run_)), photo,
      render, mask ? &*mask : nullptr, render_mask ? &*render_mask : nullptr, errors_dir,
      &compare_workspace_);
  outcome->compare_seconds = Seconds(start);
  timings_.compare += outcome->compare_seconds;
  ++counters_.views_compared;
  outcome->ok = true;
  (void)base_key;
  WriteViewRecord(fold, *outcome);
}

void Evaluation::RephotoStage(FoldState& fold, Progress& progress) {
  const auto start = Clock::now();
  const bool external = source_ == ModelSource::kRender;
  if (source_ == ModelSource::kModel && !o_.model.empty()) {
    fold.model_path = fs::absolute(o_.model).lexically_normal();
  }
  std::string base_key;
  std::optional<mesh::Mesh> mesh;  // read by ComputeModelKey unless its key was known
  if (!external) {
    fold.gaussians = IsGaussianModel(fold.model_path);
    if (fold.model_path.empty()) {
      fold.model_key = Hasher().Add(kKeyVersion).Add("no model").Hex();  // ibr from depth
    } else if (fold.gaussians) {
      REPHOTO_CHECK(!DerivesModel(),
                    "{}: holds 3D Gaussians; --colorize and model defects need a mesh",
                    fold.model_path.string());
      // Rendering and completeness settings of Gaussians are part of the model's key.
      fold.model_key = Hasher()
                           .Add(kKeyVersion)
                           .Add("gaussians")
                           .Add(hashes_->Hash(fold.model_path))
                           .Add(o_.gaussian_mode)
                           .AddDouble(o_.background[0])
                           .AddDouble(o_.background[1])
                           .AddDouble(o_.background[2])
                           .AddDouble(o_.min_alpha)
                           .Hex();
    } else {
      ComputeModelKey(fold, &mesh);  // model_key = the colorize key when colouring
    }
    // The recorded colouring time stays the fold's cost while its coloured model is reused.
    if (DerivesModel() && fold.previous &&
        fold.previous->value("colorize_key", "") == fold.colorize_key) {
      fold.colorize_seconds = fold.previous->value("/seconds/colorize"_json_pointer, 0.0);
    }
    Hasher base;
    base.Add(fold.model_key).Add(RenderSettingsKey());
    // Image-based representations render from the fold's training photos (and depth maps).
    if (o_.representation == "vdt" || o_.representation == "ibr") {
      base.Add(fold.train_key);
      if (o_.representation == "ibr" && !o_.depth_maps.empty()) {
        base.Add(o_.depth_maps.string());
        std::error_code ec;
        for (const auto& entry : fs::directory_iterator(o_.depth_maps, ec)) {
          if (entry.is_regular_file(ec)) base.Add(hashes_->Hash(entry.path()));
        }
      }
    }
    base_key = base.Hex();
  } else {
    base_key = fold.command_key;
  }

  // Which views need work.
  fold.views.resize(fold.tests.size());
  std::vector<size_t> todo;
  for (size_t i = 0; i < fold.tests.size(); ++i) {
    const TestView& test = fold.tests[i];
    ViewOutcome& outcome = fold.views[i];
    outcome.stem = test.stem;
    outcome.name = test.name;
    outcome.record = fold.dir / "views" / (test.stem + ".json");
    std::string render_hash;
    if (external) {
      const fs::path image = FindImageByStem(fold.out_dir, test.stem);
      render_hash = image.empty() ? std::string() : hashes_->Hash(image);
    }
    outcome.key = ViewKey(fold, test, base_key, render_hash);
    if (!external) {
      Hasher render_key;
      render_key.Add(kKeyVersion).Add("render").Add(base_key).Add(test.stem);
      AddCamera(render_key, test.camera);
      AddPose(render_key, test.pose);
      outcome.render_key = render_key.Hex();
      const std::optional<Json> previous = ReadJsonFile(outcome.record);
      std::error_code ec;
      outcome.reuse_render =
          previous && previous->value("render_key", "") == outcome.render_key &&
          fs::is_regular_file(fold.dir / "renders" / (test.stem + ".png"), ec) &&
          fs::is_regular_file(fold.dir / "renders" / (test.stem + ".depth.exr"), ec);
    }
    if (ReuseView(outcome.record, outcome.key, &outcome)) {
      outcome.ok = true;
      outcome.reused = true;
      outcome.image.name = test.stem;
      ++counters_.views_reused;
      progress.Advance(fmt::format("{} {} (done before)", fold.name, test.stem));
    } else {
      todo.push_back(i);
    }
  }

  bool need_renderer = false;
  for (size_t i : todo) need_renderer |= !external && !fold.views[i].reuse_render;
  std::unique_ptr<FoldRenderer> renderer;
  if (need_renderer && fold.gaussians) {
    renderer = std::make_unique<GaussianFoldRenderer>(
        LoadGaussians(fold.model_path, fold.model_key), GaussianOptions());
  } else if (need_renderer) {
    std::shared_ptr<const render::RenderModel> model;
    if (fold.model_path.empty()) {
      // No model (image-based rendering from depth maps alone).
    } else if (cached_model_ && cached_model_key_ == fold.model_key) {
      model = cached_model_;
    } else {
      cached_model_.reset();
      const fs::path coloured = fold.dir / "model.ply";
      const fs::path coloured_key = fold.dir / "model.key";
      std::error_code ec;
      std::string previous_colorize;
      if (DerivesModel() && fs::is_regular_file(coloured, ec) &&
          fs::is_regular_file(coloured_key, ec)) {
        previous_colorize = ReadFileToString(coloured_key);
      }
      render::ModelOptions model_options;
      model_options.point_radius = o_.point_radius;
      model_options.point_radius_neighbors = o_.point_neighbors;
      std::unique_ptr<render::RenderModel> built;  // set when colouring built it already
      if (DerivesModel() && previous_colorize == fold.colorize_key) {
        mesh.emplace(mesh::ReadPly(coloured));
      } else {
        if (!mesh) mesh.emplace(mesh::ReadMesh(fold.model_path));
        if (o_.colorize) {
          REPHOTO_CHECK(!mesh->is_point_cloud(), "{}: --colorize needs a mesh with faces",
                        fold.model_path.string());
          const auto colorize_start = Clock::now();
          const scene::Scene train = TrainingScene(fold);
          std::vector<size_t> views(train.views.size());
          for (size_t v = 0; v < views.size(); ++v) views[v] = v;
          render::ColorizeReport report;
          fs::remove(coloured_key, ec);
          if (HasDefects(o_.degrade)) {
            // The defects change the geometry after colouring: two BVHs.
            *mesh = render::ColorizeMesh(*mesh, train, views, {}, &report);
          } else {
            // One BVH for colouring, rendering and projecting (colours leave it as it is).
            built = std::make_unique<render::RenderModel>(std::move(*mesh), model_options,
                                                          fold.model_path.string());
            render::VertexColors colors =
                render::ColorizeVertices(*built, train, views, {}, &report);
            built->SetVertexColors(std::move(colors.colors));
            built->SetVertexScalar(std::move(colors.view_count));
          }
          mesh::WritePly(coloured, built ? built->mesh() : *mesh);
          WriteTextFileAtomically(coloured_key, fold.colorize_key);
          fold.colorize_seconds = Seconds(colorize_start);
          timings_.colorize += fold.colorize_seconds;
          ++counters_.models_colorized;
          LogInfo(fmt::format("{}: coloured {} of {} vertices from {} training photos in {:.1f} s",
                              fold.name, report.colored_vertices, report.vertices,
                              train.views.size(), fold.colorize_seconds));
        }
        if (HasDefects(o_.degrade)) {
          const auto degrade_start = Clock::now();
          fs::remove(coloured_key, ec);
          degrade::DegradeOptions d = o_.degrade;
          d.texture_dir = fold.dir / "textures";
          d.texture_prefix = "model";
          degrade::DegradeReport report;
          *mesh = degrade::Degrade(*mesh, d, &report);
          timings_.prepare += Seconds(degrade_start);
          LogInfo(fmt::format("{}: degraded the model ({} -> {} vertices)", fold.name,
                              report.vertices_before, report.vertices_after));
        }
        if (HasDefects(o_.degrade)) {
          // With colouring alone this was written above.
          mesh::WritePly(coloured, *mesh);
          WriteTextFileAtomically(coloured_key, fold.colorize_key);
        }
      }
      if (built) {
        model = std::move(built);
      } else {
        const auto build_start = Clock::now();
        model = std::make_shared<const render::RenderModel>(std::move(*mesh), model_options,
                                                            fold.model_path.string());
        timings_.render += Seconds(build_start);
      }
      cached_model_ = model;
      cached_model_key_ = fold.model_key;
      cached_model_path_ = HasDefects(o_.degrade) ? coloured : fold.model_path;
    }
    render::RenderOptions render_options;
    render_options.samples_per_pixel = o_.samples_per_pixel;
    render_options.backfaces = o_.backfaces;
    const auto build_start = Clock::now();
    renderer = MakeFoldRenderer(
        o_.representation, model, render_options, [&] { return TrainingScene(fold); },
        o_.depth_maps);
    timings_.render += Seconds(build_start);
  }
  WriteFoldJson(fold, "running");

  for (size_t i : todo) {
    if (InterruptRequested()) break;
    const TestView& test = fold.tests[i];
    ViewOutcome& outcome = fold.views[i];
    try {
      EvaluateView(fold, test, renderer.get(), base_key, &outcome);
      progress.Advance(fmt::format("{} {}", fold.name, test.stem));
    } catch (const UsageError&) {
      throw;
    } catch (const Error& e) {
      outcome.ok = false;
      outcome.message = fmt::format("{} {}: {}", fold.name, test.stem, e.what());
      LogWarning(outcome.message);
      progress.Advance(fmt::format("{} {} (failed)", fold.name, test.stem));
    }
  }
  fold.seconds = Seconds(start);
}

// --------------------------------------------------------------------------- outputs

void Evaluation::WriteFoldJson(const FoldState& fold, const std::string& status) const {
  Json j;
  j["schema"] = "rephoto.evaluate.fold/1";
  j["fold"] = fold.name;
  j["index"] = fold.index;
  j["status"] = status;
  j["message"] = fold.message;
  if (source_ != ModelSource::kModel) {
    j["command"] = {{"kind", CommandKind()},
                    {"key", fold.command_key},
                    {"status", fold.command_status},
                    {"seconds", fold.command_seconds},
                    {"cpu_seconds", fold.command_cpu_seconds},
                    {"reused", fold.command_reused},
                    {"command", fold.command},
                    {"log", RelativeTo(fold.log_file, run_)}};
  }
  j["model"] = fold.model_path.empty() ? Json() : Json(fold.model_path.string());
  j["model_key"] = fold.model_key;
  j["colorize_key"] = fold.colorize_key;
  if (DerivesModel()) j["colorized_model"] = "model.ply";
  j["train"] = {{"folder", fold.train_dir.string()},
                {"images", fold.images_dir.string()},
                {"count", fold.train_names.size()},
                {"key", fold.train_key}};
  j["test"] = {{"folder", fold.test_dir.string()}, {"count", fold.tests.size()}};
  size_t evaluated = 0;
  double view_seconds = 0;
  for (const ViewOutcome& v : fold.views) {
    evaluated += v.ok ? 1 : 0;
    view_seconds += v.render_seconds + v.compare_seconds;
  }
  j["test_images"] = fold.tests.size();
  j["evaluated_images"] = evaluated;
  j["seconds"] = {{"command", fold.command_seconds},
                  {"colorize", fold.colorize_seconds},
                  {"views", view_seconds},
                  {"this_run", fold.seconds}};
  WriteTextFileAtomically(fold.dir / "fold.json", j.dump(2) + "\n");
}

void Evaluation::Aggregate(EvaluateResult* result) {
  const auto start = Clock::now();
  const size_t metric_count = o_.metrics.size();
  io::CsvWriter per_image;
  std::vector<std::string> header = {"fold"};
  for (std::string& column : compare::PerImageCsvHeader(o_.metrics)) header.push_back(column);
  per_image.AddRow(header);
  const size_t columns = header.size();

  std::vector<compare::ImageResult> all_images;
  std::vector<double> fold_completeness;
  std::vector<std::vector<double>> fold_metric(metric_count);
  io::CsvWriter per_fold;
  {
    std::vector<std::string> fold_header = {"fold", "status", "test_images", "evaluated_images",
                                            "completeness"};
    for (metrics::Metric m : o_.metrics) fold_header.emplace_back(metrics::MetricName(m));
    fold_header.push_back("message");
    per_fold.AddRow(fold_header);
  }
  Json failed = Json::array();
  for (FoldState& fold : folds_) {
    FoldResult fr;
    fr.index = fold.index;
    fr.name = fold.name;
    fr.test_images = fold.tests.size();
    fr.external_seconds = fold.external_seconds;
    std::vector<std::pair<std::string, std::vector<std::string>>> rows;
    std::vector<double> completeness;
    std::vector<std::vector<double>> means(metric_count);
    size_t failed_views = 0;
    double seconds = fold.command_seconds + fold.colorize_seconds;
    for (size_t i = 0; i < fold.tests.size(); ++i) {
      const TestView& test = fold.tests[i];
      const ViewOutcome* outcome = i < fold.views.size() ? &fold.views[i] : nullptr;
      std::vector<std::string> row = {fold.name};
      if (fold.ok && outcome && outcome->ok) {
        for (std::string& field : compare::PerImageCsvRow(outcome->image)) row.push_back(field);
        // The photo by its scene name (relative to the scene's image root), not by a path into
        // this run's cache: two runs of the same inputs give byte-identical tables.
        row[3] = test.name;
        completeness.push_back(outcome->image.completeness.value);
        for (size_t k = 0; k < metric_count; ++k) {
          means[k].push_back(outcome->image.metrics[k].mean);
        }
        all_images.push_back(outcome->image);
        seconds += outcome->render_seconds + outcome->compare_seconds;
        ++fr.evaluated_images;
      } else {
        row.push_back(test.stem);
        row.push_back("failed");
        row.push_back(test.name);
        row.push_back("");
        ++failed_views;
      }
      row.resize(columns);
      rows.emplace_back(test.stem, std::move(row));
    }
    std::sort(rows.begin(), rows.end());
    for (const auto& row : rows) per_image.AddRow(row.second);

    fr.ok = fold.ok && failed_views == 0;
    fr.message = fold.message;
    if (fold.ok && failed_views > 0) {
      for (const ViewOutcome& v : fold.views) {
        if (!v.ok && !v.message.empty()) {
          fr.message = fmt::format("{} of {} views failed, first: {}", failed_views,
                                   fold.tests.size(), v.message);
          break;
        }
      }
      if (fr.message.empty()) fr.message = fmt::format("{} views not evaluated", failed_views);
    }
    fr.seconds = seconds;
    fr.completeness = Summarize(completeness).mean;
    if (completeness.empty()) fr.completeness = std::numeric_limits<double>::quiet_NaN();
    for (size_t k = 0; k < metric_count; ++k) {
      const Summary s = Summarize(means[k]);
      fr.metric_means.push_back(s.count ? s.mean : std::numeric_limits<double>::quiet_NaN());
      fold_metric[k].push_back(fr.metric_means.back());
    }
    fold_completeness.push_back(fr.completeness);
    std::vector<std::string> fold_row = {
        fold.name, fr.ok ? "ok" : "failed", std::to_string(fr.test_images),
        std::to_string(fr.evaluated_images), io::CsvNumber(fr.completeness)};
    for (double v : fr.metric_means) fold_row.push_back(io::CsvNumber(v));
    fold_row.push_back(fr.message);
    per_fold.AddRow(fold_row);
    if (!fr.ok) failed.push_back({{"fold", fold.name}, {"message", fr.message}});
    result->images += fr.test_images;
    result->evaluated_images += fr.evaluated_images;
    WriteFoldJson(fold, fold.ok ? (failed_views ? "incomplete" : "ok") : "failed");
    result->folds.push_back(std::move(fr));
  }

  std::vector<double> image_completeness;
  for (const compare::ImageResult& image : all_images) {
    image_completeness.push_back(image.completeness.value);
  }
  result->completeness_across_folds = Summarize(fold_completeness);
  result->completeness_over_images = Summarize(image_completeness);
  const std::vector<compare::MetricSummary> pooled =
      compare::SummarizeMetrics(o_.metrics, all_images);
  for (size_t k = 0; k < metric_count; ++k) {
    MetricAggregate a;
    a.metric = o_.metrics[k];
    a.across_folds = Summarize(fold_metric[k]);
    a.over_images = pooled[k].over_images;
    a.pooled = pooled[k].pooled;
    result->metrics.push_back(a);
  }

  // Pooled completeness: all valid windows together.
  size_t valid_photo = 0, valid_both = 0;
  for (const compare::ImageResult& image : all_images) {
    valid_photo += image.completeness.valid_photo;
    valid_both += image.completeness.valid_both;
  }
  Json summary;
  summary["schema"] = kSchema;
  summary["tool_version"] = compare::ToolVersion();
  summary["scene"] = fs::absolute(o_.scene).lexically_normal().string();
  summary["scheme"] = split_.scheme.ToString();
  // A fixed --model saw every photo, the test photos among them, whatever the split.
  summary["cross_validated"] = split_.cross_validated && source_ != ModelSource::kModel;
  summary["source"] = source_ == ModelSource::kModel         ? "model"
                      : source_ == ModelSource::kReconstruct ? "reconstruct"
                                                             : "render";
  summary["folds"] = folds_.size();
  summary["images"] = result->images;
  summary["evaluated_images"] = result->evaluated_images;
  summary["failed_folds"] = failed;
  Json missing = Json::array();
  for (const std::string& name : missing_photos_) {
    missing.push_back({{"name", name},
                       {"missing", "photo"},
                       {"path", scene_.views[view_index_.at(name)].image_path.string()}});
  }
  summary["missing"] = missing;
  summary["completeness"] = {
      {"across_folds", SummaryJson(result->completeness_across_folds)},
      {"over_images", SummaryJson(result->completeness_over_images)},
      {"pooled", valid_photo ? Json(static_cast<double>(valid_both) / valid_photo) : Json()}};
  Json metrics_json = Json::object();
  for (const MetricAggregate& a : result->metrics) {
    const auto [low, high] = compare::ErrorColourRange(a.metric);
    metrics_json[std::string(metrics::MetricName(a.metric))] = {
        {"across_folds", SummaryJson(a.across_folds)},
        {"over_images", SummaryJson(a.over_images)},
        {"pooled", Number(a.pooled)},
        {"higher_is_better", metrics::HigherIsBetter(a.metric)},
        {"error_png_range", {low, high}}};
  }
  summary["metrics"] = metrics_json;
  summary["files"] = {{"per_image", "per_image.csv"},
                      {"per_fold", "per_fold.csv"},
                      {"run", "run.json"},
                      {"manifest", "manifest.json"}};

  WriteTextFileAtomically(run_ / "per_image.csv", per_image.text());
  WriteTextFileAtomically(run_ / "per_fold.csv", per_fold.text());
  WriteTextFileAtomically(run_ / "summary.json", summary.dump(2) + "\n");
  timings_.aggregate += Seconds(start);
}

// Projects one metric's error images of `folds` onto `model_path` (or the cached render model
// when it is that model) into `out`, unless `out` was written with the same key.
void Evaluation::ProjectOnto(const fs::path& model_path, const std::string& model_key,
                             const std::vector<const FoldState*>& folds, metrics::Metric metric,
                             const fs::path& out) {
  const std::string metric_name(metrics::MetricName(metric));
  std::vector<project::ProjectView> views;
  Hasher key;
  key.Add(kKeyVersion)
      .Add("project/rendering-depth")
      .Add(model_key)
      .Add(metric_name)
      .Add(RenderSettingsKey());
  for (const FoldState* fold : folds) {
    for (size_t i = 0; i < fold->tests.size() && i < fold->views.size(); ++i) {
      if (!fold->views[i].ok) continue;
      const TestView& test = fold->tests[i];
      project::ProjectView view;
      view.camera = test.camera;
      view.cam_from_world = test.pose;
      view.error_image = fold->dir / "errors" / (test.stem + "." + metric_name + ".exr");
      const fs::path depth = fold->dir / "renders" / (test.stem + ".depth.exr");
      std::error_code exists_ec;
      if (o_.representation == "auto" && fs::is_regular_file(depth, exists_ec)) {
        // The model's own rendering made these errors: its depth map needs no second render.
        view.depth_image = depth;
      }
      view.name = fold->name + "/" + test.stem;
      key.Add(view.name).Add(fold->views[i].key).Add(view.depth_image.empty() ? "render" : "file");
      views.push_back(std::move(view));
    }
  }
  if (views.empty()) return;
  const fs::path key_file = fs::path(out).replace_extension(".key");
  std::error_code ec;
  if (fs::is_regular_file(out, ec) && fs::is_regular_file(key_file, ec) &&
      ReadFileToString(key_file) == key.Hex()) {
    return;
  }
  if (IsGaussianModel(model_path)) {
    fs::remove(key_file, ec);
    ProjectOntoGaussians(model_path, model_key, views, metric_name, out);
    WriteTextFileAtomically(key_file, key.Hex());
    ++counters_.projections;
    return;
  }
  project::ProjectOptions options;
  options.backfaces = o_.backfaces;
  options.higher_is_better = metrics::ErrorImageHigherIsBetter(metric);
  options.model_options.point_radius = o_.point_radius;
  options.model_options.point_radius_neighbors = o_.point_neighbors;
  options.model_options.load_textures = false;
  fs::remove(key_file, ec);
  project::ProjectResult projected;
  if (cached_model_ && cached_model_->mesh().vertex_count() > 0 &&
      cached_model_path_ == model_path) {
    projected = project::ProjectErrors(*cached_model_, views, options);
    project::WriteProjectedPly(cached_model_->mesh(), projected, out);
  } else {
    const mesh::Mesh mesh = mesh::ReadMesh(model_path);
    projected = project::ProjectErrors(mesh, views, options);
    project::WriteProjectedPly(mesh, projected, out);
  }
  WriteTextFileAtomically(key_file, key.Hex());
  ++counters_.projections;
  LogInfo(fmt::format("projected {} of {} views onto {} vertices ({} seen) -> {}", metric_name,
                      views.size(), projected.vertex_error.size(), projected.seen_vertices,
                      out.string()));
}

void Evaluation::ProjectOntoGaussians(const fs::path& model_path, const std::string& model_key,
                                      const std::vector<project::ProjectView>& views,
                                      const std::string& metric_name, const fs::path& out) {
  const std::shared_ptr<const splat::GaussianModel> model = LoadGaussians(model_path, model_key);
  size_t seen = 0;
  const std::vector<float> mean =
      project::ProjectErrorsOntoGaussians(*model, views, GaussianOptions(), {}, &seen);
  splat::WriteGaussiansWithScalar(model_path, *model, "error", mean, out);
  LogInfo(fmt::format("projected {} of {} views onto {} Gaussians ({} seen) -> {}", metric_name,
                      views.size(), model->size(), seen, out.string()));
}

std::optional<metrics::Metric> Evaluation::ProjectionMetric() {
  if (projection_checked_) return projection_metric_;
  projection_checked_ = true;
  if (o_.projection_metric == "none" || source_ == ModelSource::kRender ||
      (source_ == ModelSource::kModel && o_.model.empty())) {
    return std::nullopt;
  }
  const std::optional<metrics::Metric> metric = metrics::ParseMetric(o_.projection_metric);
  const bool have_metric =
      metric && std::find(o_.metrics.begin(), o_.metrics.end(), *metric) != o_.metrics.end();
  if (!o_.error_images) {
    LogWarning("no error projection: error images are off (--no-error-images)");
  } else if (!have_metric) {
    LogWarning(fmt::format("no error projection: '{}' is not among the metrics evaluated",
                           o_.projection_metric));
  } else {
    projection_metric_ = metric;
  }
  return projection_metric_;
}

void Evaluation::ProjectFold(const FoldState& fold) {
  if (source_ == ModelSource::kModel || !fold.ok || fold.model_path.empty()) return;
  const std::optional<metrics::Metric> metric = ProjectionMetric();
  if (!metric) return;
  const auto start = Clock::now();
  const std::string name(metrics::MetricName(*metric));
  const fs::path out =
      run_ / "projected" / (folds_.size() == 1 ? name + ".ply" : fold.name + "." + name + ".ply");
  GuardProjection([&] {
    ProjectOnto(HasDefects(o_.degrade) ? fold.dir / "model.ply" : fold.model_path, fold.model_key,
                {&fold}, *metric, out);
  });
  timings_.project += Seconds(start);
}

void Evaluation::GuardProjection(const std::function<void()>& project) {
  try {
    project();
  } catch (const Error& e) {
    LogWarning(fmt::format("error projection failed: {}", e.what()));
    projection_message_ = e.what();
  }
}

void Evaluation::ProjectAndReport(EvaluateResult* result) {
  (void)result;
  auto start = Clock::now();
  // Per-fold models were projected fold by fold (ProjectFold), while each fold's model was in
  // memory; one model for all folds is projected here, with the views of every fold.
  const std::optional<metrics::Metric> metric =
      source_ == ModelSource::kModel ? ProjectionMetric() : std::nullopt;
  if (metric) {
    const std::string name(metrics::MetricName(*metric));
    GuardProjection([&] {
      std::vector<const FoldState*> folds;
      for (const FoldState& fold : folds_) {
        if (fold.ok) folds.push_back(&fold);
      }
      fs::path model = fs::absolute(o_.model).lexically_normal();
      std::string model_key = hashes_->Hash(model);
      if (HasDefects(o_.degrade) && !folds.empty()) {
        // Geometry noise and simplification change the geometry the errors belong to; it is
        // the same in every fold (the defects are deterministic).
        model = folds.front()->dir / "model.ply";
        model_key = folds.front()->model_key;
      }
      ProjectOnto(model, model_key, folds, *metric, run_ / "projected" / (name + ".ply"));
    });
  }
  timings_.project += Seconds(start);
  start = Clock::now();
  if (o_.report) {
    try {
      report::WriteRunReport(run_, run_ / "report.html");
    } catch (const Error& e) {
      LogWarning(fmt::format("report not written: {}", e.what()));
      report_message_ = e.what();
    }
  }
  timings_.report += Seconds(start);
}

void Evaluation::WriteManifest() {
  Json tasks = Json::array();
  for (const FoldState& fold : folds_) {
    std::string command_id;
    if (source_ != ModelSource::kModel) {
      command_id = fold.name + "/" + CommandKind();
      tasks.push_back({{"id", command_id},
                       {"kind", CommandKind()},
                       {"fold", fold.name},
                       {"key", fold.command_key},
                       {"command", fold.command},
                       {"inputs",
                        {{"train", fold.train_dir.string()},
                         {"images", fold.images_dir.string()},
                         {"test", fold.test_dir.string()}}},
                       {"outputs", {{"folder", RelativeTo(fold.out_dir, run_)}}},
                       {"log", RelativeTo(fold.log_file, run_)},
                       {"depends_on", Json::array()}});
    }
    for (size_t i = 0; i < fold.tests.size(); ++i) {
      const TestView& test = fold.tests[i];
      const ViewOutcome* outcome = i < fold.views.size() ? &fold.views[i] : nullptr;
      Json outputs = {{"record", RelativeTo(fold.dir / "views" / (test.stem + ".json"), run_)}};
      if (source_ != ModelSource::kRender) {
        outputs["render"] = RelativeTo(fold.dir / "renders" / (test.stem + ".png"), run_);
        outputs["depth"] = RelativeTo(fold.dir / "renders" / (test.stem + ".depth.exr"), run_);
      }
      if (o_.error_images) {
        Json errors = Json::array();
        for (metrics::Metric m : o_.metrics) {
          errors.push_back(
              RelativeTo(fold.dir / "errors" /
                             (test.stem + "." + std::string(metrics::MetricName(m)) + ".exr"),
                         run_));
        }
        outputs["errors"] = errors;
      }
      Json camera_params = Json::array();
      for (double p : test.camera.params) camera_params.push_back(p);
      tasks.push_back(
          {{"id", fold.name + "/" + test.stem},
           {"kind", "view"},
           {"fold", fold.name},
           {"view", test.name},
           {"key", outcome && !outcome->key.empty() ? Json(outcome->key) : Json()},
           {"inputs",
            {{"photo", test.photo.string()},
             {"photo_hash", test.photo_hash},
             {"mask", test.mask.empty() ? Json() : Json(test.mask.string())},
             {"model", fold.model_path.empty() ? Json() : Json(fold.model_path.string())},
             {"camera",
              {{"model", std::string(camera::CameraModelName(test.camera.model))},
               {"width", test.camera.width},
               {"height", test.camera.height},
               {"params", camera_params}}}}},
           {"outputs", outputs},
           {"depends_on", command_id.empty() ? Json::array() : Json::array({command_id})},
           {"status", outcome && outcome->ok ? "done" : "pending"}});
    }
  }
  Json manifest;
  manifest["schema"] = "rephoto.evaluate.manifest/1";
  manifest["run"] = fs::absolute(run_).lexically_normal().string();
  manifest["note"] =
      "Independent tasks: a view task needs only its fold's command task. Running a task "
      "elsewhere and copying its outputs (record last) into RUN lets `rephoto evaluate` with "
      "the same settings reuse it.";
  manifest["tasks"] = tasks;
  WriteTextFileAtomically(run_ / "manifest.json", manifest.dump(2) + "\n");
}

void Evaluation::WriteRunJson(const EvaluateResult* result, const std::string& status) {
  Json j;
  j["schema"] = kSchema;
  j["tool"] = {{"name", "rephoto"}, {"version", compare::ToolVersion()}};
  j["status"] = status;
  if (!failure_.empty()) j["error"] = failure_;
  Json command_line = Json::array();
  for (const std::string& arg : o_.command_line) command_line.push_back(arg);
  j["command_line"] = command_line;
  j["config_file"] = o_.config_file.empty() ? Json() : Json(o_.config_file.string());
  j["settings"] = SettingsJson(o_);
  j["scene_identity"] = scene_identity_;
  Json inputs;
  inputs["scene"] = {{"path", fs::absolute(o_.scene).lexically_normal().string()},
                     {"format", std::string(scene::SceneFormatName(scene_source_.format))},
                     {"source", fs::absolute(scene_source_.path).lexically_normal().string()},
                     {"image_root", fs::absolute(scene_.image_root).lexically_normal().string()},
                     {"views", scene_.views.size()}};
  if (source_ == ModelSource::kModel && !o_.model.empty()) {
    std::string model_hash;
    try {
      model_hash = hashes_->Hash(o_.model);
    } catch (const Error&) {
    }
    inputs["model"] = {{"path", fs::absolute(o_.model).lexically_normal().string()},
                       {"hash", model_hash}};
  }
  Json photos = Json::array();
  for (const FoldState& fold : folds_) {
    for (const TestView& test : fold.tests) {
      photos.push_back(
          {{"name", test.name}, {"path", test.photo.string()}, {"hash", test.photo_hash}});
    }
  }
  std::sort(photos.begin(), photos.end(),
            [](const Json& a, const Json& b) { return a["name"] < b["name"]; });
  photos.erase(std::unique(photos.begin(), photos.end()), photos.end());
  inputs["photos"] = photos;
  inputs["hash"] = "xxh3-64 of the file content";
  Json missing = Json::array();
  for (const std::string& name : missing_photos_) missing.push_back(name);
  inputs["missing_photos"] = missing;
  j["inputs"] = inputs;
  Json split_json;
  split_json["scheme"] = split_.scheme.ToString();
  split_json["cross_validated"] = split_.cross_validated;
  split_json["folder"] = "split";
  Json folds = Json::array();
  for (size_t f = 0; f < split_.folds.size() && f < folds_.size(); ++f) {
    folds.push_back({{"fold", folds_[f].name},
                     {"train", folds_[f].train_names},
                     {"test", split_.folds[f].test}});
  }
  split_json["folds"] = folds;
  j["split"] = split_json;
  const double total = Seconds(start_);
  const double rephoto_cpu = ProcessCpuSeconds() - start_cpu_;
  j["timings"] = {{"total", total},
                  {"external", timings_.external},
                  {"cpu",
                   {{"external", timings_.external_cpu},
                    {"rephoto", rephoto_cpu},
                    {"rephoto_share", RephotoShare(rephoto_cpu, timings_.external_cpu)}}},
                  {"rephoto",
                   {{"total", timings_.rephoto()},
                    {"split", timings_.split},
                    {"prepare", timings_.prepare},
                    {"colorize", timings_.colorize},
                    {"render", timings_.render},
                    {"compare", timings_.compare},
                    {"aggregate", timings_.aggregate},
                    {"project", timings_.project},
                    {"report", timings_.report}}},
                  {"note",
                   "seconds of this invocation; external = sum over commands, which run in "
                   "background threads and may overlap rephoto's own work (wall-clock sums "
                   "then count the overlap twice); cpu = user + system CPU seconds of the "
                   "commands' process trees and of rephoto's own process"}};
  j["counters"] = {{"commands_run", counters_.commands_run},
                   {"folds_reused", counters_.folds_reused},
                   {"models_colorized", counters_.models_colorized},
                   {"views_rendered", counters_.views_rendered},
                   {"views_compared", counters_.views_compared},
                   {"views_reused", counters_.views_reused},
                   {"photos_downscaled", counters_.photos_downscaled},
                   {"projections", counters_.projections}};
  Json fold_status = Json::array();
  if (result != nullptr) {
    for (const FoldResult& fr : result->folds) {
      fold_status.push_back({{"fold", fr.name},
                             {"status", fr.ok ? "ok" : "failed"},
                             {"message", fr.message},
                             {"test_images", fr.test_images},
                             {"evaluated_images", fr.evaluated_images},
                             {"seconds", fr.seconds}});
    }
  }
  j["folds"] = fold_status;
  Json projected = Json::array();
  std::error_code ec;
  for (fs::directory_iterator it(run_ / "projected", ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().extension() == ".ply") {
      projected.push_back(RelativeTo(it->path(), run_));
    }
  }
  std::sort(projected.begin(), projected.end());
  j["outputs"] = {
      {"projected", projected},
      {"projection_error", projection_message_.empty() ? Json() : Json(projection_message_)},
      {"report", fs::exists(run_ / "report.html", ec) ? Json("report.html") : Json()},
      {"report_error", report_message_.empty() ? Json() : Json(report_message_)}};
  WriteTextFileAtomically(run_ / "run.json", j.dump(2) + "\n");
}

EvaluateResult Evaluation::Run() {
  start_ = Clock::now();
  start_cpu_ = ProcessCpuSeconds();
  o_.Check();
  source_ = o_.source();
  run_ = fs::absolute(o_.out).lexically_normal();
  if (source_ == ModelSource::kModel && !o_.model.empty()) {
    std::error_code ec;
    REPHOTO_CHECK(fs::is_regular_file(o_.model, ec), "{}: no such model file (--model)",
                  o_.model.string());
  }
  std::optional<InterruptGuard> guard;
  if (o_.handle_interrupts) guard.emplace();
  RequestInterrupt(false);

  auto phase = Clock::now();
  ReadInputs();
  PrepareRunDirectory();
  MakeSplit();
  WriteRunJson(nullptr, "running");
  timings_.split += Seconds(phase);

  phase = Clock::now();
  folds_.resize(split_.folds.size());
  for (size_t f = 0; f < folds_.size(); ++f) {
    folds_[f].index = f;
    folds_[f].name = split::FoldFolderName(f, folds_.size());
    PrepareFold(folds_[f]);
  }
  RemoveStaleOutputs();
  timings_.prepare += Seconds(phase);
  size_t total_views = 0;
  for (const FoldState& fold : folds_) total_views += fold.tests.size();
  LogInfo(fmt::format("evaluate: {} photos ({} missing), {} folds ({}), {} test views -> {}",
                      photo_names_.size(), missing_photos_.size(), folds_.size(),
                      split_.scheme.ToString(), total_views, run_.string()));

  // External commands in background threads, `jobs` at a time, in fold order.
  std::mutex mutex;
  std::condition_variable done_cv;
  std::vector<char> done(folds_.size(), source_ == ModelSource::kModel ? 1 : 0);
  std::vector<std::thread> workers;
  std::atomic<size_t> next{0};
  std::atomic<bool> stop{false};
  if (source_ != ModelSource::kModel) {
    const int count = std::min<int>(o_.jobs, static_cast<int>(folds_.size()));
    for (int w = 0; w < count; ++w) {
      workers.emplace_back([&] {
        for (;;) {
          const size_t f = next.fetch_add(1);
          if (f >= folds_.size()) return;
          FoldState& fold = folds_[f];
          if (InterruptRequested() || stop) {
            fold.interrupted = true;
          } else {
            try {
              CommandStage(fold);
            } catch (const Error& e) {
              FailFold(fold, fmt::format("{}: {}", fold.name, e.what()));
            }
          }
          {
            std::lock_guard<std::mutex> lock(mutex);
            done[f] = 1;
          }
          done_cv.notify_all();
        }
      });
    }
  }
  // On an exception: no new commands; wait for the running ones.
  struct Joiner {
    std::vector<std::thread>& threads;
    std::atomic<bool>& stop;
    ~Joiner() {
      stop = true;
      for (std::thread& t : threads) {
        if (t.joinable()) t.join();
      }
    }
  } joiner{workers, stop};

  {
    Progress progress("evaluate", total_views);
    for (FoldState& fold : folds_) {
      {
        std::unique_lock<std::mutex> lock(mutex);
        done_cv.wait(lock, [&] { return done[fold.index] != 0; });
      }
      if (InterruptRequested() || fold.interrupted) break;
      if (fold.command_reused) ++counters_.folds_reused;
      if (fold.ok) {
        try {
          RephotoStage(fold, progress);
        } catch (const UsageError&) {
          throw;
        } catch (const Error& e) {
          const std::string what = e.what();
          FailFold(fold, what.rfind(fold.name + ":", 0) == 0 ? what : fold.name + ": " + what);
        }
      }
      if (!fold.ok) {
        LogWarning(fold.message);
        for (size_t i = 0; i < fold.tests.size(); ++i) {
          progress.Advance(fmt::format("{} {} (fold failed)", fold.name, fold.tests[i].stem));
        }
      }
      WriteFoldJson(fold, fold.ok ? "ok" : "failed");
      if (!InterruptRequested()) ProjectFold(fold);  // while its model is in memory
    }
  }
  for (std::thread& t : workers) t.join();
  workers.clear();
  hashes_->Save();
  if (InterruptRequested()) {
    WriteRunJson(nullptr, "interrupted");
    throw Interrupted(fmt::format(
        "{}: interrupted; finished folds and views are kept: rerun the same command to resume",
        run_.string()));
  }

  EvaluateResult result;
  result.missing_photos = missing_photos_;
  Aggregate(&result);
  WriteManifest();
  bool incomplete = !missing_photos_.empty();
  for (const FoldResult& fr : result.folds) incomplete |= !fr.ok;
  result.exit_code = incomplete ? ExitCode::kIncomplete : ExitCode::kOk;
  const std::string status = incomplete ? "incomplete" : "ok";
  WriteRunJson(&result, status);  // the report reads it
  ProjectAndReport(&result);
  timings_.total = Seconds(start_);
  timings_.rephoto_cpu = ProcessCpuSeconds() - start_cpu_;
  result.counters = counters_;
  result.timings = timings_;
  WriteRunJson(&result, status);
  result.timings.total = Seconds(start_);
  return result;
}

}  // namespace

// ------------------------------------------------------------------------------ public API

const std::vector<std::string>& CommandPlaceholders() {
  static const std::vector<std::string> names = {
      "train",       "sparse",          "transforms", "images", "train_list", "test",
      "test_sparse", "test_transforms", "test_list",  "out",    "fold",       "threads"};
  return names;
}

std::string ResolvedScheme(const EvaluateOptions& options, size_t photo_count) {
  if (!options.scheme.empty()) return options.scheme;
  if (options.source() == ModelSource::kModel && !options.colorize) return "none";
  return photo_count >= 5 ? "kfold:5" : "loo";
}

bool HasDefects(const degrade::DegradeOptions& d) {
  return d.texture_noise > 0 || d.geometry_noise > 0 || d.simplify > 0;
}

ModelSource EvaluateOptions::source() const {
  if (!render.empty()) return ModelSource::kRender;
  if (!reconstruct.empty()) return ModelSource::kReconstruct;
  return ModelSource::kModel;
}

void EvaluateOptions::Check() const {
  if (scene.empty()) throw UsageError("evaluate: no scene given (--scene)");
  if (out.empty()) throw UsageError("evaluate: no run directory given (--out)");
  if (!scheme.empty()) split::ParseScheme(scheme);  // syntax now, before anything is written
  const int sources = (!render.empty()) + (!reconstruct.empty());
  if (sources > 1) throw UsageError("evaluate: give either --reconstruct or --render, not both");
  if (!reconstruct.empty() && model.empty()) {
    throw UsageError("evaluate: --reconstruct needs --model, the model's path inside {out}");
  }
  if (!reconstruct.empty() && model.is_absolute()) {
    throw UsageError(fmt::format(
        "evaluate: with --reconstruct, --model is the model's path inside {{out}} (got the "
        "absolute path {})",
        model.string()));
  }
  if (render.empty() && reconstruct.empty() && model.empty() && representation != "ibr") {
    throw UsageError(
        "evaluate: give a model source: --model FILE, --reconstruct CMD --model "
        "PATH, or --render CMD");
  }
  if (!render.empty() && !model.empty()) {
    throw UsageError("evaluate: --render renders by itself; --model is not used with it");
  }
  if (!render.empty() && colorize) {
    throw UsageError("evaluate: --colorize needs a model (not --render)");
  }
  if (!render.empty() && HasDefects(degrade)) {
    throw UsageError(
        "evaluate: model defects (--texture-noise, --geometry-noise, --simplify) need a model "
        "rendered by rephoto (not --render)");
  }
  if (!(degrade.texture_noise >= 0) || !(degrade.geometry_noise >= 0) ||
      !(degrade.simplify >= 0 && degrade.simplify < 1)) {
    throw UsageError(fmt::format(
        "evaluate: defects out of range (texture noise {} >= 0, geometry noise {} >= 0, "
        "simplify {} in [0, 1))",
        degrade.texture_noise, degrade.geometry_noise, degrade.simplify));
  }
  if (!reconstruct.empty())
    TemplatePlaceholders(reconstruct, CommandPlaceholders(), "--reconstruct");
  if (!render.empty()) TemplatePlaceholders(render, CommandPlaceholders(), "--render");
  if (representation != "auto" && representation != "vdt" && representation != "ibr" &&
      representation != "gaussians") {
    throw UsageError(fmt::format(
        "evaluate: --representation '{}' is not one of auto (the model as it is), vdt "
        "(view-dependent texturing on the model), ibr (image-based rendering with depth maps), "
        "gaussians (the model as 3D Gaussian splats)",
        representation));
  }
  if (representation != "auto" && !render.empty()) {
    throw UsageError("evaluate: --representation is for rephoto's renderers, not --render");
  }
  if (!depth_maps.empty() && representation != "ibr") {
    throw UsageError("evaluate: --depth-maps is for --representation ibr");
  }
  if (jobs < 1) throw UsageError("evaluate: --jobs must be at least 1");
  if (samples_per_pixel < 1) throw UsageError("evaluate: --spp must be at least 1");
  if (train_count < 0 || train_short_side < 0 || eval_short_side < 0) {
    throw UsageError("evaluate: counts and sizes must not be negative");
  }
  if (metrics.empty()) throw UsageError("evaluate: no metric selected");
  if (projection_metric != "none" && !metrics::ParseMetric(projection_metric)) {
    throw UsageError(fmt::format("evaluate: unknown projection metric '{}'", projection_metric));
  }
  compare::CompareOptions c;
  c.photos = c.renders = c.out = "-";
  c.metrics = metrics;
  c.metric_options = metric_options;
  c.exposure = exposure;
  try {
    c.Check();
  } catch (const Error& e) {
    throw UsageError(e.what());
  }
}

EvaluateResult RunEvaluate(const EvaluateOptions& options) {
  Evaluation evaluation(options);
  try {
    return evaluation.Run();
  } catch (const Error& e) {
    evaluation.RecordFailure(e.what());
    throw;
  }
}

}  // namespace rephoto::eval
