#include "rephoto/eval/fold_model.h"

#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/degrade/degrade.h"
#include "rephoto/eval/keys.h"
#include "rephoto/eval/prepare_fold.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/render/colorize.h"
#include "rephoto/representation/make_renderer.h"
#include "rephoto/texture/texture_mesh.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

namespace {

// The fold's model key from the file (read once per file content), and the derived model's key
// with --colorize or defects.
void ComputeModelKey(const RunContext& s, ModelCache& cache, const FoldPlan& fold,
                     CommandOutcome& command, FoldModel& model, std::optional<mesh::Mesh>* mesh) {
  const std::string file_hash = s.hashes->Hash(model.path);
  const std::string cache_key = model.path.string() + "\n" + file_hash;
  const auto cached = cache.file_keys.find(cache_key);
  if (cached != cache.file_keys.end()) {
    model.model_key = cached->second;
  } else {
    try {
      mesh->emplace(mesh::ReadMesh(model.path));
    } catch (const Error& e) {
      if (s.source == ModelSource::kReconstruct) {
        command.status = "failed";  // rerun the command next time
        ThrowError("{}: reconstruct command '{}' wrote a model that cannot be read: {}; see {}",
                   fold.name, Shorten(s.CommandTemplate()), e.what(), s.Relative(fold.log_file));
      }
      throw;
    }
    model.model_key = ModelFileKey(*s.hashes, model.path, **mesh);
    cache.file_keys[cache_key] = model.model_key;
  }
  if (s.DerivesModel()) {
    // The coloured and/or degraded model: its key covers what it was made from.
    model.colorize_key = DerivedModelKey(s.options, model.model_key, fold.train_key);
    model.model_key = model.colorize_key;
  }
}

std::string BaseKey(const RunContext& s, const FoldPlan& fold, const FoldModel& model) {
  const render::ViewRepresentation representation = s.options.representation;
  Hasher base;
  base.Add(model.model_key).Add(RenderSettingsKey(s.options));
  // Image-based representations render from the fold's training photos (and depth maps).
  if (render::IsImageBased(representation)) {
    base.Add(fold.train_key);
    if (representation == render::ViewRepresentation::kIbr && !s.options.depth_maps.empty()) {
      base.Add(s.options.depth_maps.string());
      std::error_code ec;
      for (const auto& entry : fs::directory_iterator(s.options.depth_maps, ec)) {
        if (entry.is_regular_file(ec)) base.Add(s.hashes->Hash(entry.path()));
      }
    }
  }
  return base.Hex();
}

render::ModelOptions ModelOptions(const EvaluateOptions& o) {
  render::ModelOptions model_options;
  model_options.point_radius = o.point_radius;
  model_options.point_radius_neighbors = o.point_neighbors;
  return model_options;
}

// Textures `mesh` from the fold's training photos (textured/model.obj, its atlases and
// texture.json) and replaces it by the textured mesh as read back from the OBJ.
void TextureFoldModel(const RunContext& s, const FoldPlan& fold, FoldModel& model,
                      const scene::Scene& train, Tally& tally, mesh::Mesh& mesh) {
  REPHOTO_CHECK(!mesh.is_point_cloud(), "{}: --texture needs a mesh with faces",
                model.path.string());
  const auto start = Clock::now();
  const fs::path out = fold.dir / "textured" / "model.obj";
  std::error_code ec;
  fs::remove(fold.dir / "model.key", ec);
  std::vector<size_t> views(train.views.size());
  for (size_t v = 0; v < views.size(); ++v) views[v] = v;
  const texture::TexturedMesh textured = texture::TextureMesh(mesh, train, views);
  texture::WriteTexturedObj(out, textured);
  texture::WriteTextureReport(fold.dir / "textured" / "texture.json", textured.report);
  mesh = mesh::ReadMesh(out);
  if (!HasDefects(s.options.degrade)) {
    WriteTextFileAtomically(fold.dir / "model.key", model.colorize_key);
  }
  model.colorize_seconds = Seconds(start);
  tally.AddSeconds(&EvaluateTimings::colorize, model.colorize_seconds);
  tally.Count(&EvaluateCounters::models_colorized);
  const texture::TextureReport& r = textured.report;
  LogInfo(fmt::format(
      "{}: textured {} of {} faces from {} of {} training photos ({} filled) in {:.1f} s",
      fold.name, r.textured_faces, r.faces, r.views_used, r.views_given,
      r.filled_faces + r.default_faces, model.colorize_seconds));
}

// Colours (from the fold's training photos) and/or degrades `mesh`, writes model.ply and its
// key. Returns the render model when colouring already built it (colours leave the BVH as it is).
std::unique_ptr<render::RenderModel> DeriveModel(const RunContext& s, const FoldPlan& fold,
                                                 FoldModel& model, FoldTrainingScene& training,
                                                 Tally& tally, mesh::Mesh& mesh) {
  const fs::path coloured = fold.dir / "model.ply";
  const fs::path coloured_key = fold.dir / "model.key";
  std::error_code ec;
  std::unique_ptr<render::RenderModel> built;
  if (s.options.colorize) {
    REPHOTO_CHECK(!mesh.is_point_cloud(), "{}: --colorize needs a mesh with faces",
                  model.path.string());
    const auto colorize_start = Clock::now();
    const scene::Scene& train = training.Get();
    std::vector<size_t> views(train.views.size());
    for (size_t v = 0; v < views.size(); ++v) views[v] = v;
    render::ColorizeReport report;
    fs::remove(coloured_key, ec);
    if (HasDefects(s.options.degrade)) {
      // The defects change the geometry after colouring: two BVHs.
      mesh = render::ColorizeMesh(mesh, train, views, {}, &report);
    } else {
      // One BVH for colouring, rendering and projecting.
      built = std::make_unique<render::RenderModel>(std::move(mesh), ModelOptions(s.options),
                                                    model.path.string());
      render::VertexColors colors = render::ColorizeVertices(*built, train, views, {}, &report);
      built->SetVertexColors(std::move(colors.colors));
      built->SetVertexScalar(std::move(colors.view_count));
    }
    mesh::WritePly(coloured, built ? built->mesh() : mesh);
    WriteTextFileAtomically(coloured_key, model.colorize_key);
    model.colorize_seconds = Seconds(colorize_start);
    tally.AddSeconds(&EvaluateTimings::colorize, model.colorize_seconds);
    tally.Count(&EvaluateCounters::models_colorized);
    LogInfo(fmt::format("{}: coloured {} of {} vertices from {} training photos in {:.1f} s",
                        fold.name, report.colored_vertices, report.vertices, train.views.size(),
                        model.colorize_seconds));
  }
  if (s.options.texture) TextureFoldModel(s, fold, model, training.Get(), tally, mesh);
  if (HasDefects(s.options.degrade)) {
    const auto degrade_start = Clock::now();
    fs::remove(coloured_key, ec);
    degrade::DegradeOptions d = s.options.degrade;
    d.texture_dir = fold.dir / "textures";
    d.texture_prefix = "model";
    degrade::DegradeReport report;
    mesh = degrade::Degrade(mesh, d, &report);
    tally.AddSeconds(&EvaluateTimings::prepare, Seconds(degrade_start));
    LogInfo(fmt::format("{}: degraded the model ({} -> {} vertices)", fold.name,
                        report.vertices_before, report.vertices_after));
    mesh::WritePly(coloured, mesh);
    WriteTextFileAtomically(coloured_key, model.colorize_key);
  }
  return built;
}

}  // namespace

FoldTrainingScene::FoldTrainingScene(const RunContext& s, const FoldPlan& fold)
    : s_(s), fold_(fold) {}

const scene::Scene& FoldTrainingScene::Get() {
  if (!scene_) scene_ = TrainingScene(s_, fold_);
  return *scene_;
}

bool IsGaussianModel(const RunContext& s, ModelCache& cache, const fs::path& path) {
  if (path.empty()) return false;
  // The run's representation is fixed: the file's header is read once per path.
  const auto [it, inserted] = cache.is_gaussian_file.emplace(path, false);
  if (inserted) {
    it->second = representation::ResolveRepresentation(s.options.representation, path) ==
                 render::ViewRepresentation::kGaussians;
  }
  return it->second;
}

void ResolveFoldModel(const RunContext& s, const FoldPlan& fold, CommandOutcome& command,
                      ModelCache& cache, std::optional<mesh::Mesh>* mesh, FoldModel* resolved) {
  FoldModel& model = *resolved;
  model = FoldModel();
  if (s.source == ModelSource::kModel && !s.options.model.empty()) {
    model.path = fs::absolute(s.options.model).lexically_normal();
  } else if (s.source == ModelSource::kReconstruct) {
    model.path = command.model_path;
  }
  if (s.source == ModelSource::kRender) {
    model.base_key = command.key;
    return;
  }
  model.gaussians = IsGaussianModel(s, cache, model.path);
  if (model.path.empty()) {
    model.model_key = Hasher().Add(kKeyVersion).Add("no model").Hex();  // ibr from depth
  } else if (model.gaussians) {
    REPHOTO_CHECK(!s.DerivesModel(),
                  "{}: holds 3D Gaussians; --colorize and model defects need a mesh",
                  model.path.string());
    // Rendering and completeness settings of Gaussians are part of the model's key.
    model.model_key = GaussianModelKey(s.options, s.hashes->Hash(model.path));
  } else {
    // model_key = the colorize key when colouring
    ComputeModelKey(s, cache, fold, command, model, mesh);
  }
  // The recorded colouring time stays the fold's cost while its coloured model is reused.
  if (s.DerivesModel() && fold.previous &&
      fold.previous->value("colorize_key", "") == model.colorize_key) {
    model.colorize_seconds = fold.previous->value("/seconds/colorize"_json_pointer, 0.0);
  }
  model.base_key = BaseKey(s, fold, model);
}

namespace {

// A fold whose degraded model is the one in memory (the same fixed model and defects as an
// earlier fold) gets that fold's files as its own, hard-linked (or copied), so that its
// model.ply (and the textures it names) exist as its fold.json says.
void ShareDegradedModel(const RunContext& s, const ModelCache& cache, const FoldPlan& fold,
                        const FoldModel& model) {
  if (!HasDefects(s.options.degrade)) return;
  const fs::path& mine = fold.derived_model;
  const fs::path key_file = fold.dir / "model.key";
  std::error_code ec;
  if (cache.model_path.empty() || cache.model_path == mine) return;
  if (fs::is_regular_file(mine, ec) && fs::is_regular_file(key_file, ec) &&
      ReadFileToString(key_file) == model.colorize_key) {
    return;
  }
  fs::remove(key_file, ec);
  const fs::path textures = cache.model_path.parent_path() / "textures";
  for (fs::directory_iterator it(textures, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->is_regular_file(ec)) {
      LinkOrCopyFileAtomically(it->path(), fold.dir / "textures" / it->path().filename());
    }
  }
  LinkOrCopyFileAtomically(cache.model_path, mine);
  WriteTextFileAtomically(key_file, model.colorize_key);
}

}  // namespace

std::shared_ptr<const render::RenderModel> LoadFoldModel(const RunContext& s,
                                                         const FoldPlan& fold, FoldModel& model,
                                                         FoldTrainingScene& training,
                                                         ModelCache& cache,
                                                         std::optional<mesh::Mesh>* mesh,
                                                         Tally& tally) {
  if (model.path.empty()) return nullptr;  // image-based rendering from depth maps alone
  if (cache.model && cache.model_key == model.model_key) {
    ShareDegradedModel(s, cache, fold, model);
    return cache.model;
  }
  cache.model.reset();
  const fs::path coloured = fold.derived_model;
  const fs::path coloured_key = fold.dir / "model.key";
  std::error_code ec;
  std::string previous_colorize;
  if (s.DerivesModel() && fs::is_regular_file(coloured, ec) &&
      fs::is_regular_file(coloured_key, ec)) {
    previous_colorize = ReadFileToString(coloured_key);
  }
  std::unique_ptr<render::RenderModel> built;  // set when colouring built it already
  if (s.DerivesModel() && previous_colorize == model.colorize_key) {
    mesh->emplace(mesh::ReadMesh(coloured));
  } else {
    if (!*mesh) mesh->emplace(mesh::ReadMesh(model.path));
    if (s.DerivesModel()) {
      built = DeriveModel(s, fold, model, training, tally, **mesh);
      // Rendered with the colours model.ply holds, so that a later run (or another process)
      // that reads model.ply renders the same pixels.
      if (built) {
        std::vector<Eigen::Vector3f> colors = built->mesh().colors;
        mesh::QuantizeColorsAsPly(&colors);
        built->SetVertexColors(std::move(colors));
      } else {
        mesh::QuantizeColorsAsPly(&(*mesh)->colors);
      }
    }
  }
  std::shared_ptr<const render::RenderModel> render_model;
  if (built) {
    render_model = std::move(built);
  } else {
    const auto build_start = Clock::now();
    render_model = std::make_shared<const render::RenderModel>(
        std::move(**mesh), ModelOptions(s.options), model.path.string());
    tally.AddSeconds(&EvaluateTimings::render, Seconds(build_start));
  }
  cache.model = render_model;
  cache.model_key = model.model_key;
  cache.model_path = HasDefects(s.options.degrade) ? coloured : model.path;
  return render_model;
}

std::shared_ptr<const splat::GaussianModel> LoadGaussians(ModelCache& cache, const fs::path& path,
                                                          const std::string& key) {
  if (!cache.gaussians || cache.gaussians_key != key) {
    cache.gaussians.reset();
    const auto start = Clock::now();
    splat::GaussianFormat format;
    auto model = std::make_shared<splat::GaussianModel>(splat::ReadGaussians(path, &format));
    LogInfo(fmt::format("{}: {} Gaussians ({}, SH degree {}) read in {:.1f} s", path.string(),
                        model->size(), splat::GaussianFormatName(format), model->sh_degree,
                        Seconds(start)));
    cache.gaussians = std::move(model);
    cache.gaussians_key = key;
  }
  return cache.gaussians;
}

splat::GaussianRenderOptions GaussianOptions(const EvaluateOptions& o) {
  splat::GaussianRenderOptions options;
  options.mode = o.gaussian_mode;
  options.background = Eigen::Vector3f(o.background[0], o.background[1], o.background[2]);
  return options;
}

std::unique_ptr<render::ViewRenderer> MakeFoldRenderer(const RunContext& s, const FoldPlan& fold,
                                                       FoldModel& fold_model,
                                                       FoldTrainingScene& training_scene,
                                                       ModelCache& cache,
                                                       std::optional<mesh::Mesh>* mesh,
                                                       Tally& tally) {
  representation::RendererSettings settings;
  representation::Models models;
  if (fold_model.gaussians) {
    settings.gaussians = GaussianOptions(s.options);
    models.gaussians = LoadGaussians(cache, fold_model.path, fold_model.model_key);
    return representation::MakeRenderer(render::ViewRepresentation::kGaussians, models, {},
                                        settings);
  }
  models.mesh = LoadFoldModel(s, fold, fold_model, training_scene, cache, mesh, tally);
  settings.render.samples_per_pixel = s.options.samples_per_pixel;
  settings.render.backfaces = s.options.backfaces;
  const auto build_start = Clock::now();
  // vdt/ibr: the fold's training photos reprojected through the model (vdt) or through per-view
  // depth maps (ibr: --depth-maps, else plane-sweep stereo): never the test photo.
  representation::TrainingPhotos training;
  if (render::IsImageBased(s.options.representation)) {
    const scene::Scene& train = training_scene.Get();
    training.scene = &train;
    for (size_t i = 0; i < train.views.size(); ++i) training.views.push_back(i);
    training.depth_maps = s.options.depth_maps;
  }
  std::unique_ptr<render::ViewRenderer> renderer =
      representation::MakeRenderer(s.options.representation, models, training, settings);
  tally.AddSeconds(&EvaluateTimings::render, Seconds(build_start));
  return renderer;
}

}  // namespace rephoto::eval
