// One interface for every representation rephoto renders itself, and one loop over views.
//
// ViewRepresentation (the paper's Table I, as `--representation` names them):
//   kAuto       the model as what it is: a mesh (vertex colours or textures) or a point cloud
//               (render.h); `auto` also detects a 3D Gaussian splatting file, rendered as
//               kGaussians (representation/make_renderer.h decides, for every caller)
//   kGaussians  3D Gaussians with the CPU rasterizer (splat/rasterize.h)
//   kVdt        view-dependent texturing of training photos on a mesh (ibr/)
//   kIbr        image-based rendering with per-view depth maps (ibr/)
// ViewRenderer renders one camera into a Rephoto (render.h: RGBA with alpha = coverage, and the
// camera-frame depth). ModelViewRenderer and GaussianViewRenderer live here; the image-based
// ones in ibr/image_based_renderer.h.
//
// RenderViews renders `views` of `scene` with one renderer and writes OUT/<stem>.png (RGBA 8-bit,
// the values quantized as written) and, unless `write_depth` is false, OUT/<stem>.depth.exr for
// each (WriteRephoto: without, a stale OUT/<stem>.depth.exr is removed), atomically, reporting
// each view to `progress` (may be null). Stems come from the caller (scene/image_name.h
// OutputStems). Views are rendered in order; each rendering is multi-threaded.
//
// Thread safety: a ViewRenderer reuses internal buffers: one thread per renderer.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/core/progress.h"
#include "rephoto/render/render.h"
#include "rephoto/scene/scene.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/splat/rasterize.h"

namespace rephoto::render {

enum class ViewRepresentation { kAuto, kGaussians, kVdt, kIbr };

// "auto", "gaussians", "vdt", "ibr"; std::nullopt for anything else.
std::optional<ViewRepresentation> ParseRepresentation(std::string_view name);
std::string_view RepresentationName(ViewRepresentation representation);
// True for the representations that render from training photos (vdt, ibr).
inline bool IsImageBased(ViewRepresentation r) {
  return r == ViewRepresentation::kVdt || r == ViewRepresentation::kIbr;
}

class ViewRenderer {
 public:
  virtual ~ViewRenderer() = default;
  virtual void Render(const camera::Camera& camera, const camera::Pose& cam_from_world,
                      Rephoto* out) = 0;
};

// A mesh or point cloud with the Embree renderer (render.h).
class ModelViewRenderer : public ViewRenderer {
 public:
  ModelViewRenderer(std::shared_ptr<const RenderModel> model, RenderOptions options)
      : model_(std::move(model)), options_(options) {}
  void Render(const camera::Camera& camera, const camera::Pose& cam_from_world,
              Rephoto* out) override;

 private:
  std::shared_ptr<const RenderModel> model_;
  RenderOptions options_;
};

// 3D Gaussians: the CPU forward pass of the reference rasterizer.
class GaussianViewRenderer : public ViewRenderer {
 public:
  GaussianViewRenderer(std::shared_ptr<const splat::GaussianModel> model,
                       splat::GaussianRenderOptions options)
      : model_(std::move(model)), options_(options) {}
  void Render(const camera::Camera& camera, const camera::Pose& cam_from_world,
              Rephoto* out) override;

 private:
  std::shared_ptr<const splat::GaussianModel> model_;
  splat::GaussianRenderOptions options_;
  splat::GaussianRendering rendering_;
};

// Writes a rendering as OUT/<stem>.png (quantized in place: `rephoto->color` then holds the
// values the PNG holds) and, with `write_depth`, OUT/<stem>.depth.exr (without, an existing
// OUT/<stem>.depth.exr is removed: it belonged to an earlier rendering).
void WriteRephoto(const std::filesystem::path& out_dir, const std::string& stem, Rephoto* rephoto,
                  bool write_depth = true);
// The same files, with the PNG's 8-bit samples into `color8` (io::WritePngAndQuantize) and
// `rephoto.color` unchanged: for a caller that goes on with the bytes (evaluate's comparison).
void WriteRephoto(const std::filesystem::path& out_dir, const std::string& stem,
                  const Rephoto& rephoto, bool write_depth, Image8* color8);

// See above. `stems[i]` names views[i]'s files.
void RenderViews(ViewRenderer& renderer, const scene::Scene& scene,
                 const std::vector<size_t>& views, const std::vector<std::string>& stems,
                 const std::filesystem::path& out_dir, Progress* progress, bool write_depth = true);

}  // namespace rephoto::render
