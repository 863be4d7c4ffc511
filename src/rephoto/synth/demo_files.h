// The demo scene written to disk as a user's scene folder would be, for tests and examples that
// run rephoto's commands on it (the demo itself, `rephoto demo`, adds masks and models).
//
// WriteDemoSceneFiles(options, root, photo) writes
//   root/truth.ply   the ground-truth mesh with vertex colours (MakeDemoMesh)
//   root/plain.ply   the same mesh without colours
//   root/sparse/     the cameras as a COLMAP text model (MakeDemoScene; no points)
//   root/images/     one photo per view: the truth rendered with 9 samples per pixel
//                    (render.h defaults: stratified jitter, seed 0), then SimulatePhoto(gain, noise_sigma, seed) of PhotoSettings(i)
// and returns the paths and the scene. Throws Error when a file cannot be written.
//
// Thread safety: reentrant (renders with the library's thread pool).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>

#include "rephoto/scene/scene.h"
#include "rephoto/synth/demo_scene.h"

namespace rephoto::synth {

struct PhotoSettings {
  double gain = 1;
  double noise_sigma = 0.01;
  uint64_t seed = 0;
};

struct DemoSceneFiles {
  std::filesystem::path root, sparse, images, truth, plain;
  scene::Scene scene;  // image_root = images
};

DemoSceneFiles WriteDemoSceneFiles(const DemoSceneOptions& options,
                                   const std::filesystem::path& root,
                                   const std::function<PhotoSettings(size_t view)>& photo);

}  // namespace rephoto::synth
