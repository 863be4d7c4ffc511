#include "rephoto/render/view_renderer.h"

#include "rephoto/core/error.h"
#include "rephoto/io/image_io.h"

namespace rephoto::render {

std::optional<ViewRepresentation> ParseRepresentation(std::string_view name) {
  if (name == "auto") return ViewRepresentation::kAuto;
  if (name == "gaussians") return ViewRepresentation::kGaussians;
  if (name == "vdt") return ViewRepresentation::kVdt;
  if (name == "ibr") return ViewRepresentation::kIbr;
  return std::nullopt;
}

std::string_view RepresentationName(ViewRepresentation representation) {
  switch (representation) {
    case ViewRepresentation::kAuto:
      return "auto";
    case ViewRepresentation::kGaussians:
      return "gaussians";
    case ViewRepresentation::kVdt:
      return "vdt";
    case ViewRepresentation::kIbr:
      return "ibr";
  }
  return "auto";
}

void ModelViewRenderer::Render(const camera::Camera& camera, const camera::Pose& cam_from_world,
                               Rephoto* out) {
  const auto rays = model_->RaysFor(camera);
  RenderRephoto(*model_, *rays, cam_from_world, options_, out);
}

void GaussianViewRenderer::Render(const camera::Camera& camera, const camera::Pose& cam_from_world,
                                  Rephoto* out) {
  splat::RenderGaussians(*model_, camera, cam_from_world, options_, &rendering_);
  std::swap(out->color, rendering_.color);
  std::swap(out->depth, rendering_.depth);
}

namespace {
void WriteDepth(const std::filesystem::path& out_dir, const std::string& stem,
                const Rephoto& rephoto, bool write_depth) {
  const std::filesystem::path depth = out_dir / (stem + ".depth.exr");
  if (write_depth) {
    io::WriteExr(depth, rephoto.depth);
  } else {
    std::error_code ec;
    std::filesystem::remove(depth, ec);  // an earlier rendering's: it would not match this one
  }
}
}  // namespace

void WriteRephoto(const std::filesystem::path& out_dir, const std::string& stem, Rephoto* rephoto,
                  bool write_depth) {
  io::WritePngAndQuantize(out_dir / (stem + ".png"), &rephoto->color);
  WriteDepth(out_dir, stem, *rephoto, write_depth);
}

void WriteRephoto(const std::filesystem::path& out_dir, const std::string& stem,
                  const Rephoto& rephoto, bool write_depth, Image8* color8) {
  io::WritePngAndQuantize(out_dir / (stem + ".png"), rephoto.color, color8);
  WriteDepth(out_dir, stem, rephoto, write_depth);
}

void RenderViews(ViewRenderer& renderer, const scene::Scene& scene,
                 const std::vector<size_t>& views, const std::vector<std::string>& stems,
                 const std::filesystem::path& out_dir, Progress* progress, bool write_depth) {
  REPHOTO_CHECK(views.size() == stems.size(), "RenderViews: {} views but {} stems", views.size(),
                stems.size());
  Rephoto rephoto;
  for (size_t i = 0; i < views.size(); ++i) {
    const scene::View& view = scene.views.at(views[i]);
    renderer.Render(scene.CameraOf(view), view.cam_from_world, &rephoto);
    WriteRephoto(out_dir, stems[i], &rephoto, write_depth);
    if (progress != nullptr) progress->Advance(stems[i]);
  }
}

}  // namespace rephoto::render
