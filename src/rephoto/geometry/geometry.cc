#include "rephoto/geometry/geometry.h"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/stats.h"
#include "rephoto/geometry/sampling.h"
#include "rephoto/geometry/surface_distance.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/project/project.h"

namespace rephoto::geometry {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

bool InBox(const Eigen::Vector3f& p, const std::array<Eigen::Vector3d, 2>& box) {
  const Eigen::Vector3d q = p.cast<double>();
  return (q.array() >= box[0].array()).all() && (q.array() <= box[1].array()).all();
}

// Distances of the samples that count (inside the crop box), as doubles.
std::vector<double> Counted(const SurfaceSamples& samples, const std::vector<float>& distances,
                            const GeometryOptions& options) {
  std::vector<double> counted;
  counted.reserve(distances.size());
  for (size_t i = 0; i < distances.size(); ++i) {
    if (options.crop && !InBox(samples.positions[i], *options.crop)) continue;
    counted.push_back(distances[i]);
  }
  return counted;
}

double FractionWithin(const std::vector<double>& distances, double tolerance) {
  if (distances.empty()) return kNan;
  size_t within = 0;
  for (double d : distances) within += d <= tolerance ? 1 : 0;
  return static_cast<double>(within) / static_cast<double>(distances.size());
}

double Mean(const std::vector<double>& values) {
  if (values.empty()) return kNan;
  double sum = 0;
  for (double v : values) sum += v;
  return sum / static_cast<double>(values.size());
}

nlohmann::ordered_json Number(double value) {
  return std::isfinite(value) ? nlohmann::ordered_json(value) : nlohmann::ordered_json(nullptr);
}

}  // namespace

void GeometryOptions::Check() const {
  REPHOTO_CHECK_USAGE(!tolerances.empty(), "--tolerances: at least one tolerance is needed");
  for (double t : tolerances) {
    REPHOTO_CHECK_USAGE(std::isfinite(t) && t > 0, "--tolerances: {} is not a positive distance",
                        t);
  }
  REPHOTO_CHECK_USAGE(accuracy_fraction > 0 && accuracy_fraction <= 1,
                      "--accuracy-fraction {} is not in (0, 1]", accuracy_fraction);
  REPHOTO_CHECK_USAGE(samples > 0, "--samples must be positive");
  REPHOTO_CHECK_USAGE(model_from_input.allFinite() &&
                          model_from_input.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)),
                      "--transform: the last row must be 0 0 0 1 (an affine transform)");
  if (crop) {
    REPHOTO_CHECK_USAGE(((*crop)[0].array() <= (*crop)[1].array()).all() &&
                            (*crop)[0].allFinite() && (*crop)[1].allFinite(),
                        "--crop: min must not exceed max");
  }
}

mesh::Mesh TransformMesh(const mesh::Mesh& mesh, const Eigen::Matrix4d& transform) {
  mesh::Mesh out = mesh;
  if (transform.isIdentity()) return out;
  const Eigen::Matrix3d linear = transform.topLeftCorner<3, 3>();
  const Eigen::Vector3d translation = transform.topRightCorner<3, 1>();
  for (Eigen::Vector3f& p : out.positions) {
    p = (linear * p.cast<double>() + translation).cast<float>();
  }
  const Eigen::Matrix3d normal_matrix = linear.inverse().transpose();
  for (Eigen::Vector3f& n : out.normals) {
    const Eigen::Vector3d m = normal_matrix * n.cast<double>();
    n = (m.norm() > 0 ? m.normalized() : m).cast<float>();
  }
  return out;
}

GeometryResult EvaluateGeometry(const mesh::Mesh& input_model, const mesh::Mesh& reference,
                                const GeometryOptions& options, const std::string& model_name,
                                const std::string& reference_name) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  REPHOTO_CHECK(input_model.vertex_count() > 0, "{}: the model has no vertices", model_name);
  REPHOTO_CHECK(reference.vertex_count() > 0, "{}: the model has no vertices", reference_name);
  const mesh::Mesh model = TransformMesh(input_model, options.model_from_input);

  GeometryResult result;
  result.accuracy_fraction = options.accuracy_fraction;
  result.model_is_point_cloud = model.is_point_cloud();
  result.reference_is_point_cloud = reference.is_point_cloud();
  result.model_area = SurfaceArea(model);
  result.reference_area = SurfaceArea(reference);

  const SurfaceDistance to_reference(reference, reference_name);
  const SurfaceDistance to_model(model, model_name);
  // Different streams for the two surfaces, so equal meshes do not get equal samples.
  const SurfaceSamples model_samples =
      SampleSurface(model, options.samples, options.seed, model_name);
  const SurfaceSamples reference_samples =
      SampleSurface(reference, options.samples, options.seed ^ 0x5DEECE66DULL, reference_name);
  const std::vector<double> model_distances =
      Counted(model_samples, to_reference.Distances(model_samples.positions), options);
  const std::vector<double> reference_distances =
      Counted(reference_samples, to_model.Distances(reference_samples.positions), options);
  result.model_samples = model_distances.size();
  result.reference_samples = reference_distances.size();

  result.accuracy = Quantile(model_distances, options.accuracy_fraction);
  result.model_mean_distance = Mean(model_distances);
  result.model_median_distance = Quantile(model_distances, 0.5);
  result.reference_mean_distance = Mean(reference_distances);
  result.reference_median_distance = Quantile(reference_distances, 0.5);
  for (double t : options.tolerances) {
    ToleranceResult r;
    r.tolerance = t;
    r.precision = FractionWithin(model_distances, t);
    r.recall = FractionWithin(reference_distances, t);
    r.completeness = r.recall;
    const double sum = r.precision + r.recall;
    r.f_score = sum > 0 ? 2 * r.precision * r.recall / sum : (std::isnan(sum) ? kNan : 0.0);
    result.tolerances.push_back(r);
  }
  if (options.vertex_distances) {
    result.model_vertex_distances = to_reference.Distances(model.positions);
    result.reference_vertex_distances = to_model.Distances(reference.positions);
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

void WriteGeometryJson(const GeometryResult& result, const GeometryOptions& options,
                       const std::string& model_path, const std::string& reference_path,
                       const std::filesystem::path& path) {
  nlohmann::ordered_json json;
  json["version"] = 1;
  json["accuracy"] = Number(result.accuracy);
  json["accuracy_fraction"] = result.accuracy_fraction;
  nlohmann::ordered_json tolerances = nlohmann::ordered_json::array();
  for (const ToleranceResult& r : result.tolerances) {
    tolerances.push_back({{"tolerance", r.tolerance},
                          {"completeness", Number(r.completeness)},
                          {"precision", Number(r.precision)},
                          {"recall", Number(r.recall)},
                          {"f_score", Number(r.f_score)}});
  }
  json["tolerances"] = tolerances;
  json["model"] = {{"path", model_path},
                   {"samples", result.model_samples},
                   {"area", result.model_area},
                   {"point_cloud", result.model_is_point_cloud},
                   {"mean_distance", Number(result.model_mean_distance)},
                   {"median_distance", Number(result.model_median_distance)}};
  json["reference"] = {{"path", reference_path},
                       {"samples", result.reference_samples},
                       {"area", result.reference_area},
                       {"point_cloud", result.reference_is_point_cloud},
                       {"mean_distance", Number(result.reference_mean_distance)},
                       {"median_distance", Number(result.reference_median_distance)}};
  json["samples_requested"] = options.samples;
  json["seed"] = options.seed;
  if (options.crop) {
    const auto& box = *options.crop;
    json["crop"] = {box[0].x(), box[0].y(), box[0].z(), box[1].x(), box[1].y(), box[1].z()};
  } else {
    json["crop"] = nullptr;
  }
  nlohmann::ordered_json transform = nlohmann::ordered_json::array();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) transform.push_back(options.model_from_input(r, c));
  }
  json["model_from_input"] = transform;
  json["seconds"] = result.seconds;
  WriteTextFileAtomically(path, json.dump(2) + "\n");
}

void WriteGeometryCsv(const GeometryResult& result, const std::filesystem::path& path) {
  std::string text = "tolerance,completeness,precision,recall,f_score,accuracy,accuracy_fraction\n";
  auto number = [](double v) { return std::isfinite(v) ? fmt::format("{:.9g}", v) : ""; };
  for (const ToleranceResult& r : result.tolerances) {
    text += fmt::format("{},{},{},{},{},{},{}\n", number(r.tolerance), number(r.completeness),
                        number(r.precision), number(r.recall), number(r.f_score),
                        number(result.accuracy), number(result.accuracy_fraction));
  }
  WriteTextFileAtomically(path, text);
}

void WriteDistancePly(const mesh::Mesh& mesh, const std::vector<float>& distances,
                      const std::filesystem::path& path) {
  REPHOTO_CHECK(distances.size() == mesh.vertex_count(), "{}: {} distances for {} vertices",
                path.string(), distances.size(), mesh.vertex_count());
  std::vector<double> finite;
  finite.reserve(distances.size());
  for (float d : distances) {
    if (std::isfinite(d)) finite.push_back(d);
  }
  const float low = static_cast<float>(Quantile(finite, 0.025));
  const float high = static_cast<float>(Quantile(finite, 0.975));
  mesh::Mesh out;
  out.positions = mesh.positions;
  out.normals = mesh.normals;
  out.faces = mesh.faces;
  out.colors.resize(distances.size());
  for (size_t i = 0; i < distances.size(); ++i) {
    const std::array<uint8_t, 3> rgb = project::ErrorColour(distances[i], low, high);
    out.colors[i] = Eigen::Vector3f(rgb[0], rgb[1], rgb[2]) / 255.0f;
  }
  out.SetScalar({"distance", distances});
  out.SetScalar({"quality", distances});  // the name MeshLab reads as vertex quality
  mesh::WritePly(path, out);
}

}  // namespace rephoto::geometry
