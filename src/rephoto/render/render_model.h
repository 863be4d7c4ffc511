// A model prepared for rendering: the Embree scene (BVH built once), colours, textures and
// splat radii. Build it once per model and render any number of views from it, concurrently.
//
// Representations (chosen from what the mesh holds):
// - kVertexColoredMesh: triangles with per-vertex colours, interpolated barycentrically (as
//   OpenGL's Gouraud interpolation of stored colours).
// - kTexturedMesh: triangles with texture coordinates and materials with diffuse textures;
//   faces without a texture use their material's diffuse colour (or vertex colours when present).
// - kPlainMesh: triangles without colour: every face has ModelOptions::default_color.
// - kPointCloud: no faces. Each point is an opaque disc (Embree user geometry, exact ray-disc
//   test) of the point's colour (default_color without colours): oriented by the point's normal
//   when the mesh has normals (a zero normal gives a view-facing disc), otherwise facing the
//   ray (a view-facing disc, i.e. the disc through the centre perpendicular to the ray).
//   Radius: ModelOptions::point_radius if > 0, else the file's per-point radius, else the
//   distance to the k-th nearest neighbour (k = point_radius_neighbors) times
//   point_radius_scale, capped at point_radius_max_factor times the median of these radii (an
//   isolated outlier, e.g. a stray point near a camera, would otherwise become a disc that
//   covers the whole view).
// Triangles are two-sided in the BVH; RenderOptions::backfaces decides at render time.
#pragma once

#include <embree3/rtcore.h>

#include <Eigen/Core>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/render/camera_rays.h"
#include "rephoto/render/nearest_hit.h"
#include "rephoto/render/texture.h"

namespace rephoto::render {

enum class Representation { kVertexColoredMesh, kTexturedMesh, kPlainMesh, kPointCloud };

struct ModelOptions {
  // World-unit splat radius for every point (> 0 overrides the file's radii and the density).
  float point_radius = 0;
  int point_radius_neighbors = 6;
  float point_radius_scale = 1.0f;
  float point_radius_max_factor = 3.0f;  // cap of density radii, times their median (0 = none)
  // Colour of surfaces without colour information, RGB in [0,1].
  Eigen::Vector3f default_color = Eigen::Vector3f::Constant(0.5f);
  // Read the materials' texture images (else textured meshes render as kPlainMesh/vertex colours).
  bool load_textures = true;
};

class RenderModel {
 public:
  // Validates the mesh (Mesh::Validate, errors prefixed with `name`), reads textures (errors
  // name the texture file), computes splat radii and builds the BVH.
  explicit RenderModel(mesh::Mesh mesh, const ModelOptions& options = {},
                       std::string_view name = "model");
  ~RenderModel();
  RenderModel(const RenderModel&) = delete;
  RenderModel& operator=(const RenderModel&) = delete;

  Representation representation() const { return representation_; }
  const mesh::Mesh& mesh() const { return mesh_; }
  const ModelOptions& options() const { return options_; }
  RTCScene scene() const { return scene_; }
  // Per-point splat radii (point clouds only; empty for meshes).
  const std::vector<float>& point_radii() const { return point_radii_; }
  // Texture of a material (nullptr when it has none or textures were not loaded).
  const Texture* texture(int material) const {
    return material >= 0 && material < static_cast<int>(textures_.size()) &&
                   textures_[material].width() > 0
               ? &textures_[material]
               : nullptr;
  }
  // The border strips of a triangle mesh (render/nearest_hit.h; empty for point clouds), the
  // scene's geometry kSkirtGeometry.
  const BorderSkirts& border_skirts() const { return skirts_; }
  // Seconds spent building the BVH (rtcCommitScene).
  double build_seconds() const { return build_seconds_; }

  // Attributes that leave the geometry, and so the BVH, as it is: one BVH serves colouring a
  // mesh (ColorizeVertices), rendering it and projecting errors onto it. Not thread-safe: call
  // before the model is shared. SetVertexColors needs one colour per vertex of a mesh with faces;
  // an untextured mesh then renders as kVertexColoredMesh. SetVertexScalar is Mesh::SetScalar
  // (one value per vertex).
  void SetVertexColors(std::vector<Eigen::Vector3f> colors);
  void SetVertexScalar(mesh::VertexScalar scalar);

  // The ray table for these intrinsics (SharedCameraRays: the process-wide cache of the last few
  // intrinsics used, so views and models sharing a camera reuse it). Thread-safe.
  std::shared_ptr<const CameraRays> RaysFor(const camera::Camera& camera) const;

  struct PointGeometry;  // data of the disc user geometry's callbacks (render_model.cc)

 private:
  mesh::Mesh mesh_;
  ModelOptions options_;
  std::unique_ptr<PointGeometry> point_geometry_;
  Representation representation_ = Representation::kPlainMesh;
  std::vector<Texture> textures_;
  std::vector<float> point_radii_;
  BorderSkirts skirts_;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  double build_seconds_ = 0;
};

}  // namespace rephoto::render
