// Geometric accuracy and completeness of a reconstruction against a ground-truth surface, in the
// styles of the Middlebury multi-view benchmark (Seitz et al. 2006) and of ETH3D / Tanks and
// Temples (precision, recall, F-score), so that they can be set beside rephoto's image errors
// (paper Fig. 8).
//
// Method. Both surfaces are sampled uniformly by area with a fixed seed (sampling.h; a point
// cloud contributes its points). For each MODEL sample the exact distance to the REFERENCE
// surface is computed, and for each REFERENCE sample the exact distance to the MODEL surface
// (surface_distance.h: closest point on the triangles; nearest point when that side is a point
// cloud). All distances are in the reference's units, after options.model_from_input is applied
// to the model.
// Definitions (d_m: model-sample distances, d_r: reference-sample distances, both restricted to
// samples inside options.crop when it is set):
//   accuracy        the distance within which `accuracy_fraction` of the model's surface lies
//                   from the reference: the quantile accuracy_fraction of d_m (linear
//                   interpolation between order statistics, core/stats.h). Lower is better.
//   completeness(t) the fraction of the reference's surface within t of the model:
//                   #{d_r <= t} / #d_r. Range [0, 1].
//   precision(t)    #{d_m <= t} / #d_m. Range [0, 1].
//   recall(t)       #{d_r <= t} / #d_r: the same number as completeness (both measure the
//                   reference's surface near the model); reported under both names.
//   f_score(t)      2 precision recall / (precision + recall), 0 when both are 0.
// Every fraction is a fraction of surface area (samples are area-uniform), so its sampling error
// is about sqrt(p (1 - p) / samples) or less (stratified samples).
// Thread safety: EvaluateGeometry is reentrant and parallel inside (core/parallel.h); its result
// is bit-for-bit independent of the thread count.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "rephoto/mesh/mesh.h"

namespace rephoto::geometry {

struct GeometryOptions {
  // Distance thresholds t, in reference units, each > 0; the results keep this order.
  std::vector<double> tolerances = {0.001, 0.002, 0.005};
  double accuracy_fraction = 0.9;  // in (0, 1]
  size_t samples = 1'000'000;      // per surface (a point cloud gives at most its points)
  uint64_t seed = 0;
  // Applied to the model's positions (and normals, by the linear part) first; last row 0 0 0 1.
  Eigen::Matrix4d model_from_input = Eigen::Matrix4d::Identity();
  // Axis-aligned box {min, max} in the reference's frame: only samples (of either surface)
  // inside it (bounds included) count. Distances are still to the whole other surface.
  std::optional<std::array<Eigen::Vector3d, 2>> crop;
  // Also compute the distance of every vertex (model vertex to reference, reference vertex to
  // model), for the coloured PLYs.
  bool vertex_distances = false;
  void Check() const;  // throws UsageError naming the setting
};

struct ToleranceResult {
  double tolerance = 0;     // reference units
  double completeness = 0;  // [0, 1], see the file comment
  double precision = 0;     // [0, 1]
  double recall = 0;        // [0, 1], equals completeness
  double f_score = 0;       // [0, 1]
};

struct GeometryResult {
  double accuracy = 0;  // reference units; NaN when no model sample lies in the crop box
  double accuracy_fraction = 0;
  std::vector<ToleranceResult> tolerances;  // indexed as options.tolerances
  // Sample counts after cropping, and the surfaces' total areas (0 for point clouds).
  size_t model_samples = 0;
  size_t reference_samples = 0;
  double model_area = 0;
  double reference_area = 0;
  bool model_is_point_cloud = false;
  bool reference_is_point_cloud = false;
  // Mean and median of d_m and d_r (reference units; NaN without samples).
  double model_mean_distance = 0;
  double model_median_distance = 0;
  double reference_mean_distance = 0;
  double reference_median_distance = 0;
  // With options.vertex_distances: one per vertex of the model (to the reference) and of the
  // reference (to the model), in vertex order; empty otherwise.
  std::vector<float> model_vertex_distances;
  std::vector<float> reference_vertex_distances;
  double seconds = 0;  // wall time of EvaluateGeometry
};

// The transformed model (options.model_from_input applied to positions and normals).
mesh::Mesh TransformMesh(const mesh::Mesh& mesh, const Eigen::Matrix4d& transform);

// See the file comment. `model_name`/`reference_name` prefix error messages (file names).
// Throws Error when a mesh is empty or invalid or a surface has no area, UsageError for bad
// options.
GeometryResult EvaluateGeometry(const mesh::Mesh& model, const mesh::Mesh& reference,
                                const GeometryOptions& options,
                                const std::string& model_name = "model",
                                const std::string& reference_name = "reference");

// geometry.json, written atomically:
//   {"version": 1,
//    "accuracy": number (reference units; null when undefined),
//    "accuracy_fraction": number,
//    "tolerances": [{"tolerance", "completeness", "precision", "recall", "f_score"}, ...],
//    "model": {"path", "samples", "area", "point_cloud", "mean_distance", "median_distance"},
//    "reference": {... the same ...},
//    "samples_requested", "seed", "crop": [minx, miny, minz, maxx, maxy, maxz] or null,
//    "model_from_input": 16 numbers row-major, "seconds"}
// NaN values are written as null. Throws Error naming `path` when it cannot be written.
void WriteGeometryJson(const GeometryResult& result, const GeometryOptions& options,
                       const std::string& model_path, const std::string& reference_path,
                       const std::filesystem::path& path);

// geometry.csv: header "tolerance,completeness,precision,recall,f_score,accuracy,
// accuracy_fraction", one row per tolerance (accuracy repeated), atomically.
void WriteGeometryCsv(const GeometryResult& result, const std::filesystem::path& path);

// `mesh` (positions as evaluated, i.e. the transformed model) as a binary PLY with one
// distance per vertex: jet colours between the 2.5 and 97.5 % percentiles of the finite
// distances (as `rephoto project`, project::ErrorColour), float `distance` and `quality`
// properties. Throws Error naming `path` when sizes differ or it cannot be written.
void WriteDistancePly(const mesh::Mesh& mesh, const std::vector<float>& distances,
                      const std::filesystem::path& path);

}  // namespace rephoto::geometry
