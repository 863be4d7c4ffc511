// The fold-model stage of `rephoto evaluate` (eval/state.h): what a fold renders.
//
// ResolveFoldModel  finds the fold's model (--model, or the reconstruction's {out}/<model>),
//                   tells whether it holds 3D Gaussians, and computes its keys: the model key
//                   (file content and textures, keys.h), the derived-model key with --colorize
//                   or defects, and the base key every rendering of the fold depends on (model,
//                   renderer settings; vdt/ibr: the training photos and depth maps).
// LoadFoldModel     the fold's render model: the cached one when the key is the same (one model
//                   for all folds is built once), else model.ply when its key file matches,
//                   else the model read and, with --colorize, coloured from the fold's training
//                   photos only (render/colorize.h), or with --texture textured from them
//                   (texture/texture_mesh.h: textured/model.obj, atlases, texture.json), with
//                   defects degraded (degrade/degrade.h), written to FoldPlan::derived_model
//                   + model.key; then its BVH built. Colours and texels are rendered as the files
//                   store them (8 bits), so a run that reads the files renders the same pixels.
// MakeFoldRenderer  the renderer of the representation for the fold (render::ViewRenderer).
//
// Thread safety: one thread; the ModelCache holds the last models built.
#pragma once

#include <map>
#include <memory>
#include <optional>

#include "rephoto/eval/state.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/render/render_model.h"
#include "rephoto/render/view_renderer.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/splat/rasterize.h"

namespace rephoto::eval {

// Models kept from fold to fold (one model file for every fold is read and built once).
struct ModelCache {
  std::string model_key;  // of `model`
  std::shared_ptr<const render::RenderModel> model;
  std::filesystem::path model_path;  // the file `model` was built from
  // Model file keys by "<path>\n<content hash>", so a shared model is parsed once.
  std::map<std::string, std::string> file_keys;
  std::shared_ptr<const splat::GaussianModel> gaussians;  // the last Gaussian model read
  std::string gaussians_key;
  std::map<std::filesystem::path, bool> is_gaussian_file;  // rendered as Gaussians, decided once per path
};

// The fold's training scene (prepare_fold.h TrainingScene), computed on first use and then kept
// for the fold's colouring, texturing and image-based renderer.
class FoldTrainingScene {
 public:
  FoldTrainingScene(const RunContext& s, const FoldPlan& fold);
  const scene::Scene& Get();

 private:
  const RunContext& s_;
  const FoldPlan& fold_;
  std::optional<scene::Scene> scene_;
};

// Whether `path` is rendered as 3D Gaussians (representation gaussians, or auto and a file with
// Gaussian properties).
bool IsGaussianModel(const RunContext& s, ModelCache& cache, const std::filesystem::path& path);

// The fold's model into *model: its path (--model, or the model `command` wrote), whether it
// holds Gaussians, model_key, colorize_key, base_key and the recorded colouring time. `mesh`
// receives the model when it had to be read for its key. Throws Error for a model that cannot be
// read (*model then holds what was known before, its path first, as fold.json records it); for
// a reconstruction it also marks `command` failed (its status in fold.json), so it runs again.
void ResolveFoldModel(const RunContext& s, const FoldPlan& fold, CommandOutcome& command,
                      ModelCache& cache, std::optional<mesh::Mesh>* mesh, FoldModel* model);

// The fold's render model (see above); null for ibr without a model. Sets
// model.colorize_seconds when it colours or textures the model.
std::shared_ptr<const render::RenderModel> LoadFoldModel(const RunContext& s,
                                                         const FoldPlan& fold, FoldModel& model,
                                                         FoldTrainingScene& training,
                                                         ModelCache& cache,
                                                         std::optional<mesh::Mesh>* mesh,
                                                         Tally& tally);

std::shared_ptr<const splat::GaussianModel> LoadGaussians(ModelCache& cache,
                                                          const std::filesystem::path& path,
                                                          const std::string& key);
splat::GaussianRenderOptions GaussianOptions(const EvaluateOptions& o);

// The renderer of the fold's representation (loads the model as above).
std::unique_ptr<render::ViewRenderer> MakeFoldRenderer(const RunContext& s, const FoldPlan& fold,
                                                       FoldModel& fold_model,
                                                       FoldTrainingScene& training,
                                                       ModelCache& cache,
                                                       std::optional<mesh::Mesh>* mesh,
                                                       Tally& tally);

}  // namespace rephoto::eval
