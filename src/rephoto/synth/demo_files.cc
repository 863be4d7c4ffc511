#include "rephoto/synth/demo_files.h"

#include "rephoto/io/image_io.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/render/render.h"
#include "rephoto/scene/colmap.h"

namespace rephoto::synth {

DemoSceneFiles WriteDemoSceneFiles(const DemoSceneOptions& options,
                                   const std::filesystem::path& root,
                                   const std::function<PhotoSettings(size_t view)>& photo) {
  DemoSceneFiles f;
  f.root = root;
  f.sparse = root / "sparse";
  f.images = root / "images";
  f.truth = root / "truth.ply";
  f.plain = root / "plain.ply";
  const mesh::Mesh truth = MakeDemoMesh(options);
  f.scene = MakeDemoScene(options, f.images);
  mesh::WritePly(f.truth, truth);
  mesh::Mesh plain = truth;
  plain.colors.clear();
  mesh::WritePly(f.plain, plain);
  scene::WriteColmap(f.scene, f.sparse, scene::ColmapFormat::kText);
  const render::RenderModel model(truth);
  render::RenderOptions fine;
  fine.samples_per_pixel = 9;
  for (size_t i = 0; i < f.scene.views.size(); ++i) {
    const scene::View& view = f.scene.views[i];
    const render::Rephoto clean =
        render::RenderRephoto(model, f.scene.CameraOf(view), view.cam_from_world, fine);
    const PhotoSettings settings = photo(i);
    io::WritePng(view.image_path,
                 SimulatePhoto(clean.color, settings.gain, settings.noise_sigma, settings.seed));
  }
  return f;
}

}  // namespace rephoto::synth
