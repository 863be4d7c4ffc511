// Test fixture shared by the ibr tests: the procedural demo scene (synth/demo_scene.h)
// "photographed" under constant lighting with the true procedural albedo at every surface
// point (not the mesh's vertex colours), so photos carry texture detail beyond what the
// vertex-coloured mesh holds.
//
// Photo of a view: the mesh ray-cast at twice the resolution (one ray per sub-pixel centre),
// each hit coloured by DemoAlbedo at the hit point, 2x2 area-averaged, then SimulatePhoto with
// gain 1 and no noise (8-bit quantization only). Pixels that see no surface are black.
//
// Thread safety: the fixture functions are reentrant (test code, used from the test's main thread).
#pragma once

#include <filesystem>
#include <vector>

#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/ibr/image_ops.h"
#include "rephoto/io/image_io.h"
#include "rephoto/render/render.h"
#include "rephoto/synth/demo_scene.h"

namespace rephoto::ibr::testing {

inline Image PhotographAlbedo(const render::RenderModel& geometry, const camera::Camera& camera,
                              const camera::Pose& pose, uint64_t seed) {
  const camera::Camera fine = camera.Scaled(2 * camera.width, 2 * camera.height);
  render::RenderOptions options;
  options.samples_per_pixel = 1;
  options.pattern = render::SamplePattern::kRegular;
  const render::Rephoto r = render::RenderRephoto(geometry, fine, pose, options);
  const render::CameraRays rays(fine);
  const Eigen::Matrix3d world_from_cam = pose.rotation.transpose();
  const Eigen::Vector3d origin = pose.Center();
  Image colour(fine.width, fine.height, 3, 0.f);
  for (int y = 0; y < fine.height; ++y) {
    for (int x = 0; x < fine.width; ++x) {
      const float z = r.depth.at(x, y);
      float xn, yn;
      if (!std::isfinite(z) || !rays.Ray(x + 0.5f, y + 0.5f, &xn, &yn)) continue;
      const Eigen::Vector3d X = origin + world_from_cam * Eigen::Vector3d(xn * z, yn * z, z);
      const Eigen::Vector3f a = synth::DemoAlbedo(X.cast<float>(), seed);
      for (int c = 0; c < 3; ++c) colour.at(x, y, c) = a[c];
    }
  }
  return synth::SimulatePhoto(internal::ShrinkArea(colour, camera.width, camera.height), 1.0, 0.0,
                              1);
}

struct DemoPhotos {
  synth::DemoSceneOptions options;
  mesh::Mesh mesh;  // ground-truth geometry with vertex colours (DemoAlbedo at the vertices)
  scene::Scene scene;
  std::vector<Image> photos;                      // as written to scene.views[i].image_path
  std::unique_ptr<render::RenderModel> geometry;  // the mesh without colours (plain)

  // Ground-truth depth (camera-frame z, NaN = empty) at view i's camera, one ray per pixel.
  Image TrueDepth(size_t i) const {
    render::RenderOptions o;
    o.samples_per_pixel = 1;
    o.pattern = render::SamplePattern::kRegular;
    return render::RenderRephoto(*geometry, scene.CameraOf(scene.views[i]),
                                 scene.views[i].cam_from_world, o)
        .depth;
  }

  TrainingView Training(size_t i) const {
    return {scene.views[i].name,
            scene.CameraOf(scene.views[i]),
            scene.views[i].cam_from_world,
            scene.views[i].image_path,
            {}};
  }
};

inline DemoPhotos MakeDemoPhotos(const synth::DemoSceneOptions& options,
                                 const std::filesystem::path& folder) {
  DemoPhotos d;
  d.options = options;
  d.mesh = synth::MakeDemoMesh(options);
  d.scene = synth::MakeDemoScene(options, folder);
  mesh::Mesh plain;
  plain.positions = d.mesh.positions;
  plain.faces = d.mesh.faces;
  d.geometry = std::make_unique<render::RenderModel>(std::move(plain));
  for (const scene::View& view : d.scene.views) {
    d.photos.push_back(
        PhotographAlbedo(*d.geometry, d.scene.CameraOf(view), view.cam_from_world, options.seed));
    io::WritePng(view.image_path, d.photos.back());
  }
  return d;
}

}  // namespace rephoto::ibr::testing
