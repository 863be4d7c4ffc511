// The built-in demo scene: a procedurally textured, non-trivial object on a textured ground,
// photographed by a ring of cameras. Everything is generated from a seed (no data files), so
// `rephoto demo` and the tests that need a ground truth work anywhere.
//
// World frame: metres, z up, ground plane z = 0 spanning [-2, 2] x [-2, 2]; the object (a
// sphere of radius 0.5 with low-frequency bumps, centred at (0, 0, 0.5)) stands on it.
// Colours are vertex colours sampled from DemoAlbedo, dense enough (about one vertex per
// photo pixel on the object) that the mesh acts as the scene's ground-truth texture.
//
// Thread safety: reentrant (the noise is cached per thread; no shared mutable state).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>

#include "rephoto/core/image.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/scene/scene.h"

namespace rephoto::synth {

struct DemoSceneOptions {
  int image_width = 1280;  // photo size in pixels
  int image_height = 960;
  int camera_count = 16;   // on a ring around the object
  int ground_cells = 500;  // ground grid cells per side (2 triangles each)
  int object_bands = 300;  // object latitude bands (twice as many longitude segments)
  uint64_t seed = 2017;
};

// Albedo (RGB in [0,1]) at a world position: tiles, stripes and multi-scale simplex noise, so
// every 9x9 patch of a photo has structure for the patch metrics.
Eigen::Vector3f DemoAlbedo(const Eigen::Vector3f& position, uint64_t seed);

// The ground-truth mesh (ground + object, vertex colours and normals).
mesh::Mesh MakeDemoMesh(const DemoSceneOptions& options);

// The cameras: one OPENCV camera (focal length = image width, mild barrel distortion k1 =
// -0.05, k2 = 0.01, principal point slightly off-centre, like a real lens) shared by all views;
// views named "view_000.png", ... on a ring of radius 3.2 m at height 1.5 m, looking at
// (0, 0, 0.45) with small per-view jitter of the height and target. image_root is stored as the
// views' folder.
scene::Scene MakeDemoScene(const DemoSceneOptions& options,
                           const std::filesystem::path& image_root);

// Turns a clean rendering into a "photo": multiplies by `gain` (exposure difference), adds
// Gaussian sensor noise of standard deviation `noise_sigma` (colour units) per channel,
// quantizes to 8 bits and clips to [0,1]. Drops an alpha channel (returns RGB). Deterministic
// for the seed.
Image SimulatePhoto(const Image& rendering, double gain, double noise_sigma, uint64_t seed);

}  // namespace rephoto::synth
