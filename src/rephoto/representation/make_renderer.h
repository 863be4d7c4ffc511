// Choosing the renderer: the one place where `rephoto render`, `rephoto evaluate` and the Python
// bindings decide how a representation is rendered (render/view_renderer.h ViewRepresentation).
//
// Resolution (ResolveRepresentation), decided once per model file:
//   auto       a file with Gaussian properties (splat::IsGaussianFile: a ".splat" file, or a PLY
//              whose header declares Gaussians) -> gaussians; any other file stays auto: the
//              mesh / point-cloud renderer (render/render.h: vertex colours, textures or splats,
//              from what the file holds). Only the file's header is read.
//   gaussians, vdt, ibr   as requested (the file is not looked at).
// After resolution, kAuto means "the mesh / point-cloud renderer".
//
// What each resolved representation renders from (Models, MakeRenderer):
//   auto       Models::mesh (a render::RenderModel, BVH built)
//   gaussians  Models::gaussians
//   vdt        Models::proxy, else Models::mesh's mesh() (a triangle mesh, not a point cloud),
//              and the training photos
//   ibr        the training photos and their depth maps (TrainingPhotos::depth_maps; views
//              without one are estimated by plane sweep); no model
// A model the representation needs and that is missing is an Error ("--representation vdt needs
// a model (the geometry proxy)"); models it does not need are ignored.
//
// Enums are parsed once, at the edge (CLI flags, settings files, Python arguments):
// RepresentationFromName and GaussianModeFromName throw UsageError for anything else.
//
// Thread safety: the functions are reentrant. The renderers made follow render::ViewRenderer
// (one thread per renderer); the shared models are read-only and may back several renderers.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/render/render.h"
#include "rephoto/render/render_model.h"
#include "rephoto/render/view_renderer.h"
#include "rephoto/scene/scene.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/splat/rasterize.h"

namespace rephoto::representation {

// Everything a renderer is configured with; each representation reads its own part.
struct RendererSettings {
  render::RenderOptions render;  // auto: samples per pixel, back faces, ...
  render::ModelOptions model;    // auto: how LoadModels prepares a mesh or point cloud
  splat::GaussianRenderOptions gaussians;
  // vdt/ibr. Empty scene_points: MakeRenderer takes the training scene's sparse points
  // (ibr::ScenePoints of TrainingPhotos::scene).
  ibr::ImageBasedOptions image_based;
};

// "auto", "gaussians", "vdt", "ibr" (render::ParseRepresentation). Throws UsageError
// "<source> <name>: expected auto, gaussians, vdt or ibr" otherwise.
render::ViewRepresentation RepresentationFromName(std::string_view name, std::string_view source);
// "classic", "antialiased" (splat::ParseGaussianMode). Throws UsageError
// "<source> <name>: expected classic or antialiased" otherwise.
splat::GaussianMode GaussianModeFromName(std::string_view name, std::string_view source);

// See "Resolution" above. `model_path` may be empty (then auto stays auto).
render::ViewRepresentation ResolveRepresentation(render::ViewRepresentation requested,
                                                 const std::filesystem::path& model_path);

// The models a renderer renders, shared (evaluate keeps them from fold to fold). Only the one the
// representation needs must be set (see above).
struct Models {
  std::shared_ptr<const render::RenderModel> mesh;        // auto; vdt's proxy without `proxy`
  std::shared_ptr<const splat::GaussianModel> gaussians;  // gaussians
  std::shared_ptr<const mesh::Mesh> proxy;                // vdt: the proxy, no BVH needed
};

// Reads what the *resolved* `representation` renders from `path` (auto: the mesh or point cloud
// with settings.model, BVH built; gaussians: the Gaussians; vdt: the proxy mesh; ibr: nothing)
// and logs what was read (counts, seconds). Throws Error when `path` is empty and the
// representation needs a model, and the readers' errors (naming the file).
Models LoadModels(render::ViewRepresentation representation, const std::filesystem::path& path,
                  const RendererSettings& settings);

// vdt/ibr: the photos a renderer renders from (the other representations ignore them).
struct TrainingPhotos {
  const scene::Scene* scene = nullptr;  // must outlive the MakeRenderer call only
  std::vector<size_t> views;            // indices into scene->views
  // ibr: folder of per-view depth maps (ibr/training_views.h names); empty = estimate all.
  std::filesystem::path depth_maps;
};

// The renderer of the *resolved* `representation` (kAuto must already be resolved: a Gaussian
// file passed as kAuto with only Models::gaussians set is an Error). vdt/ibr read the training
// photos (and depth maps) now. Throws Error for a missing model (see above), a point cloud as vdt
// proxy, no training photos for vdt/ibr, and the renderers' own errors.
std::unique_ptr<render::ViewRenderer> MakeRenderer(render::ViewRepresentation representation,
                                                   const Models& models,
                                                   const TrainingPhotos& training,
                                                   const RendererSettings& settings);

// Logs a warning for each of `views` that is also in `training`: an image-based renderer
// reproduces its own photo, so the error measured there is meaningless (paper Section 4.4).
void WarnRenderedTrainingPhotos(const scene::Scene& scene, const std::vector<size_t>& training,
                                const std::vector<size_t>& views);

// vdt/ibr without a training list: renders each of `views` from all other views of `scene`
// (leave-one-out: one renderer per rendered view, built as MakeRenderer builds it) and writes
// OUT/<stems[i]>.png and (with `write_depth`) .depth.exr as render::RenderViews does, logging
// each view. Throws Error as MakeRenderer does, and for `representation` not vdt/ibr or
// stems.size() != views.size().
void RenderLeaveOneOut(render::ViewRepresentation representation, const Models& models,
                       const scene::Scene& scene, const std::vector<size_t>& views,
                       const std::vector<std::string>& stems,
                       const std::filesystem::path& depth_maps, const RendererSettings& settings,
                       const std::filesystem::path& out_dir, bool write_depth = true);

}  // namespace rephoto::representation
