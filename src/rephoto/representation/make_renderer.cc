#include "rephoto/representation/make_renderer.h"

#include <fmt/format.h>

#include <chrono>
#include <set>

#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/ibr/training_views.h"
#include "rephoto/mesh/read_mesh.h"

namespace rephoto::representation {
namespace {

using render::ViewRepresentation;

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The message for a representation whose model is missing.
[[noreturn]] void ThrowMissingModel(ViewRepresentation representation) {
  switch (representation) {
    case ViewRepresentation::kGaussians:
      ThrowError("--representation gaussians needs a model (3D Gaussians)");
    case ViewRepresentation::kVdt:
      ThrowError("--representation vdt needs a model (the geometry proxy)");
    default:
      ThrowError("--representation {} needs a model (a mesh or point cloud)",
                 render::RepresentationName(representation));
  }
}

// vdt/ibr: the training views of `training`, with ibr's depth maps.
std::unique_ptr<render::ViewRenderer> MakeImageBasedRenderer(ViewRepresentation representation,
                                                             const Models& models,
                                                             const TrainingPhotos& training,
                                                             const RendererSettings& settings) {
  const bool vdt = representation == ViewRepresentation::kVdt;
  const mesh::Mesh* proxy = nullptr;
  if (vdt) {
    proxy = models.proxy ? models.proxy.get() : models.mesh ? &models.mesh->mesh() : nullptr;
    if (proxy == nullptr) ThrowMissingModel(representation);
    REPHOTO_CHECK(!proxy->is_point_cloud(),
                  "--representation vdt needs a mesh as geometry proxy (got a point cloud)");
  }
  REPHOTO_CHECK(training.scene != nullptr, "--representation {} needs training photos",
                render::RepresentationName(representation));
  ibr::ImageBasedOptions options = settings.image_based;
  if (options.scene_points.empty()) options.scene_points = ibr::ScenePoints(*training.scene);
  // Depth-map files are ibr's proxies; vdt renders its proxy at every training view instead.
  std::vector<ibr::TrainingView> views = ibr::TrainingViewsFromScene(
      *training.scene, training.views, vdt ? std::filesystem::path() : training.depth_maps);
  return std::make_unique<ibr::ImageBasedViewRenderer>(
      vdt ? ibr::ImageBasedRenderer::Vdt(*proxy, std::move(views), options)
          : ibr::ImageBasedRenderer::Ibr(std::move(views), options));
}

}  // namespace

render::ViewRepresentation RepresentationFromName(std::string_view name, std::string_view source) {
  const std::optional<ViewRepresentation> representation = render::ParseRepresentation(name);
  REPHOTO_CHECK_USAGE(representation.has_value(), "{} {}: expected auto, gaussians, vdt or ibr",
                      source, name);
  return *representation;
}

splat::GaussianMode GaussianModeFromName(std::string_view name, std::string_view source) {
  const std::optional<splat::GaussianMode> mode = splat::ParseGaussianMode(name);
  REPHOTO_CHECK_USAGE(mode.has_value(), "{} {}: expected classic or antialiased", source, name);
  return *mode;
}

render::ViewRepresentation ResolveRepresentation(render::ViewRepresentation requested,
                                                 const std::filesystem::path& model_path) {
  if (requested == ViewRepresentation::kAuto && !model_path.empty() &&
      splat::IsGaussianFile(model_path)) {
    return ViewRepresentation::kGaussians;
  }
  return requested;
}

Models LoadModels(render::ViewRepresentation representation, const std::filesystem::path& path,
                  const RendererSettings& settings) {
  Models models;
  if (representation == ViewRepresentation::kIbr) return models;
  if (path.empty()) ThrowMissingModel(representation);
  const auto start = std::chrono::steady_clock::now();
  switch (representation) {
    case ViewRepresentation::kGaussians: {
      splat::GaussianFormat format;
      auto gaussians =
          std::make_shared<const splat::GaussianModel>(splat::ReadGaussians(path, &format));
      LogInfo(fmt::format("{}: {} Gaussians ({}, SH degree {}), read in {:.2f} s", path.string(),
                          gaussians->size(), splat::GaussianFormatName(format),
                          gaussians->sh_degree, SecondsSince(start)));
      models.gaussians = std::move(gaussians);
      break;
    }
    case ViewRepresentation::kVdt:
      models.proxy = std::make_shared<const mesh::Mesh>(mesh::ReadMesh(path));
      break;
    default: {
      auto model = std::make_shared<const render::RenderModel>(mesh::ReadMesh(path), settings.model,
                                                               path.string());
      LogInfo(fmt::format("{}: {} vertices, {} triangles, prepared in {:.2f} s (BVH {:.2f} s)",
                          path.string(), model->mesh().vertex_count(), model->mesh().face_count(),
                          SecondsSince(start), model->build_seconds()));
      models.mesh = std::move(model);
      break;
    }
  }
  return models;
}

std::unique_ptr<render::ViewRenderer> MakeRenderer(render::ViewRepresentation representation,
                                                   const Models& models,
                                                   const TrainingPhotos& training,
                                                   const RendererSettings& settings) {
  switch (representation) {
    case ViewRepresentation::kGaussians:
      if (!models.gaussians) ThrowMissingModel(representation);
      return std::make_unique<render::GaussianViewRenderer>(models.gaussians, settings.gaussians);
    case ViewRepresentation::kVdt:
    case ViewRepresentation::kIbr:
      return MakeImageBasedRenderer(representation, models, training, settings);
    case ViewRepresentation::kAuto:
      break;
  }
  if (!models.mesh) ThrowMissingModel(representation);
  return std::make_unique<render::ModelViewRenderer>(models.mesh, settings.render);
}

void WarnRenderedTrainingPhotos(const scene::Scene& scene, const std::vector<size_t>& training,
                                const std::vector<size_t>& views) {
  const std::set<size_t> training_set(training.begin(), training.end());
  for (size_t v : views) {
    if (training_set.count(v)) {
      LogWarning(
          fmt::format("{} is also a training photo: its rephoto reproduces the photo "
                      "(hold it out to measure anything)",
                      scene.views.at(v).name));
    }
  }
}

void RenderLeaveOneOut(render::ViewRepresentation representation, const Models& models,
                       const scene::Scene& scene, const std::vector<size_t>& views,
                       const std::vector<std::string>& stems,
                       const std::filesystem::path& depth_maps, const RendererSettings& settings,
                       const std::filesystem::path& out_dir, bool write_depth) {
  REPHOTO_CHECK(render::IsImageBased(representation),
                "leave-one-out rendering is for vdt and ibr, not {}",
                render::RepresentationName(representation));
  REPHOTO_CHECK(views.size() == stems.size(), "RenderLeaveOneOut: {} views but {} stems",
                views.size(), stems.size());
  LogInfo("no --training: leave-one-out (each view rendered from all other views)");
  // The scene's points once, not once per rendered view.
  RendererSettings view_settings = settings;
  if (view_settings.image_based.scene_points.empty()) {
    view_settings.image_based.scene_points = ibr::ScenePoints(scene);
  }
  render::Rephoto rephoto;
  for (size_t i = 0; i < views.size(); ++i) {
    TrainingPhotos training{&scene, {}, depth_maps};
    for (size_t v = 0; v < scene.views.size(); ++v) {
      if (v != views[i]) training.views.push_back(v);
    }
    const std::unique_ptr<render::ViewRenderer> renderer =
        MakeRenderer(representation, models, training, view_settings);
    const scene::View& view = scene.views.at(views[i]);
    renderer->Render(scene.CameraOf(view), view.cam_from_world, &rephoto);
    render::WriteRephoto(out_dir, stems[i], &rephoto, write_depth);
    LogInfo(fmt::format("rendered {} ({}/{})", view.name, i + 1, views.size()));
  }
}

}  // namespace rephoto::representation
