// Exact distances from points to a surface: the closest point on a triangle mesh, or the nearest
// point of a point cloud.
//
// Meshes: an Embree BVH over the triangles, queried with rtcPointQuery; every triangle whose
// bounding box meets the current search sphere is tested with the exact closed-form closest point
// on a triangle (Ericson, Real-Time Collision Detection, 5.1.5, in double precision), and the
// sphere shrinks to the best distance found. The result is the exact Euclidean distance to the
// union of the triangles (two-sided, boundaries included), up to float rounding of the stored
// positions. Degenerate triangles count as their segment or point.
// Point clouds (no faces): the distance to the nearest point (the same BVH query over the points
// as zero-size boxes); this is a nearest-sample distance, not a distance to an underlying surface.
// Units are the model's; positions are used as stored (apply transforms before).
// Thread safety: construction is not; Distance/Distances are const and may run concurrently.
#pragma once

#include <embree3/rtcore.h>

#include <Eigen/Core>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/mesh/mesh.h"

namespace rephoto::geometry {

// Squared distance from `point` to the triangle (a, b, c) and the closest point on it.
double PointTriangleDistanceSquared(const Eigen::Vector3d& point, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                    Eigen::Vector3d* closest = nullptr);

class SurfaceDistance {
 public:
  // Keeps a copy of the positions and faces. Throws Error "<name>: ..." when the mesh has no
  // vertices or is invalid (Mesh::Validate).
  explicit SurfaceDistance(const mesh::Mesh& mesh, std::string_view name = "mesh");
  ~SurfaceDistance();
  SurfaceDistance(const SurfaceDistance&) = delete;
  SurfaceDistance& operator=(const SurfaceDistance&) = delete;

  struct Closest {
    float distance = 0;      // Euclidean, model units
    Eigen::Vector3f point;   // the closest point on the surface (or the nearest point)
    uint32_t primitive = 0;  // its face (mesh) or point (point cloud) index
  };

  // The closest point to `query`. `upper_bound` (> 0, may be infinity) is a distance known to be
  // at least the answer (e.g. the distance to a surface point found before); it only speeds up
  // the search. Never fails (the surface is non-empty).
  Closest Find(const Eigen::Vector3f& query,
               float upper_bound = std::numeric_limits<float>::infinity()) const;

  // Distances of many points, in parallel; out[i] for points[i]. Consecutive points are
  // assumed close to each other (surface samples in face order): each query starts with the
  // bound |p_i - closest_{i-1}|. Bit-for-bit independent of the thread count (the bound only
  // prunes the search, the exact minimum does not depend on it).
  std::vector<float> Distances(std::span<const Eigen::Vector3f> points) const;

  bool is_point_cloud() const { return faces_.empty(); }

 private:
  std::vector<Eigen::Vector3f> positions_;
  std::vector<mesh::Triangle> faces_;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

}  // namespace rephoto::geometry
