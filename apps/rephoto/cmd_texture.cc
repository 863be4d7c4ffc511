// rephoto texture MESH --scene SCENE [--images LIST] [--format F] [--image-root DIR]
//                 [--texel-scale S] [--smoothness W] [--max-atlas-size N] [--report R.json]
//                 [--ply OUT.ply] --out OUT.obj
// Textures a mesh from calibrated photos (rephoto/texture/texture_mesh.h, after Waechter et al.
// 2014): OUT.obj + OUT.mtl + OUT_atlas_<i>.png, optionally a PLY with per-face texture
// coordinates beside the same atlases, and a JSON report (faces textured / filled / unseen,
// photos used, seconds per stage; default OUT.texture.json). Every file is written atomically.
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <string>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/split/split.h"
#include "rephoto/texture/texture_mesh.h"
#include "scene_args.h"

namespace rephoto::cli {
namespace {

struct TextureArguments {
  std::string mesh;
  std::string scene;
  std::string images;
  SceneArguments scene_args;
  std::string out;
  std::string ply;
  std::string report;
  texture::TextureOptions options;
  bool no_consistency = false;
  bool no_leveling = false;
};

CommandRunner SetupTexture(CLI::App& app) {
  auto args = std::make_shared<TextureArguments>();
  app.add_option("mesh", args->mesh,
                 "Mesh (.ply, .obj); colours and texture coordinates are ignored")
      ->required();
  app.add_option("--scene", args->scene, "Scene file or folder with cameras and photos")
      ->required();
  app.add_option("--images", args->images,
                 "List file of the photos to use, e.g. a fold's training list (default: every "
                 "view whose photo exists)");
  app.add_option("--texel-scale", args->options.texel_scale,
                 "Texels per photo pixel, (0, 1] (smaller atlases for evaluation at reduced size)")
      ->capture_default_str();
  app.add_option("--smoothness", args->options.smoothness,
                 "Potts weight of the view selection (data costs are in [0, 1])")
      ->capture_default_str();
  app.add_option("--min-cosine", args->options.min_facing_cosine,
                 "A photo sees a face only if cos(face normal, direction to camera) exceeds this")
      ->capture_default_str();
  app.add_option("--partial-fraction", args->options.partial_min_fraction,
                 "A face no photo sees whole may take a photo that sees this fraction of it "
                 "(0 = whole faces only)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--max-atlas-size", args->options.max_atlas_size,
                 "Width and greatest height of an atlas image in texels")
      ->capture_default_str();
  app.add_flag("--no-photo-consistency", args->no_consistency,
               "Keep every photo that sees a face whole (no outlier removal)");
  app.add_flag("--no-seam-leveling", args->no_leveling, "Skip the global colour adjustment");
  AddSceneOptions(app, &args->scene_args);
  app.add_option("--ply", args->ply, "Also write a PLY with per-face texture coordinates");
  app.add_option("--report", args->report, "JSON report (default: OUT with .texture.json)");
  app.add_option("--out", args->out, "Output OBJ (MTL and PNG atlases are written beside it)")
      ->required();
  return [args]() {
    REPHOTO_CHECK_USAGE(std::filesystem::path(args->out).extension() == ".obj",
                        "--out {}: must name an .obj file", args->out);
    REPHOTO_CHECK_USAGE(args->ply.empty() || std::filesystem::path(args->ply).extension() == ".ply",
                        "--ply {}: must name a .ply file", args->ply);
    args->options.photo_consistency = !args->no_consistency;
    args->options.seam_leveling = !args->no_leveling;
    args->options.show_progress = true;
    args->options.Check();
    const scene::Scene scene =
        scene::ReadScene(args->scene, MakeReadSceneOptions(args->scene_args));
    const std::vector<size_t> views = PhotoViews(scene, args->images, args->scene);
    const mesh::Mesh mesh = mesh::ReadMesh(args->mesh);
    const texture::TexturedMesh textured = texture::TextureMesh(mesh, scene, views, args->options);
    texture::WriteTexturedObj(args->out, textured);
    if (!args->ply.empty()) texture::WriteTexturedPly(args->ply, textured);
    std::filesystem::path report = args->report;
    if (report.empty())
      report = std::filesystem::path(args->out).replace_extension(".texture.json");
    texture::WriteTextureReport(report, textured.report);
    const texture::TextureReport& r = textured.report;
    LogInfo(fmt::format(
        "{}: {} of {} faces textured from {} of {} photos ({} patches, {} atlases), {} filled "
        "from neighbours, {} grey, in {:.1f} s -> {}",
        args->mesh, r.textured_faces, r.faces, r.views_used, r.views_given, r.patches, r.atlases,
        r.filled_faces, r.default_faces, r.seconds_total, args->out));
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(33, "texture", "Texture a mesh from calibrated photos (OBJ + MTL + PNG atlases)",
                SetupTexture);

}  // namespace rephoto::cli
