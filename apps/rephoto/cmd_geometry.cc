// rephoto geometry MODEL --reference GT --out DIR [--tolerances 0.001,0.002,0.005]
//                  [--accuracy-fraction 0.9] [--samples N] [--seed S]
//                  [--crop MINX,MINY,MINZ,MAXX,MAXY,MAXZ] [--transform 16 numbers | FILE]
//                  [--no-ply]
// Geometric accuracy and completeness (Middlebury) and precision, recall and F-score (ETH3D,
// Tanks and Temples) of a mesh or point cloud against a ground-truth surface, from exact
// point-to-surface distances of seeded area-uniform samples (src/rephoto/geometry/geometry.h).
// Writes DIR/geometry.json, DIR/geometry.csv and, unless --no-ply, DIR/model_distance.ply and
// DIR/reference_distance.ply (jet-coloured per-vertex distance, float "distance").
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/geometry/geometry.h"
#include "rephoto/mesh/read_mesh.h"

namespace rephoto::cli {
namespace {

struct GeometryArguments {
  std::string model;
  std::string reference;
  std::string out;
  std::vector<double> crop;
  std::vector<std::string> transform;
  bool no_ply = false;
  geometry::GeometryOptions options;
};

// 16 numbers on the command line, or one file holding 16 numbers (row-major 4x4; whitespace or
// commas), as the alignment files of Tanks and Temples.
Eigen::Matrix4d ParseTransform(const std::vector<std::string>& words) {
  std::string text;
  std::string source = "--transform";
  if (words.size() == 1 && std::filesystem::is_regular_file(words[0])) {
    source = words[0];
    text = ReadFileToString(words[0]);
  } else {
    for (const std::string& w : words) text += w + " ";
  }
  for (char& c : text) {
    if (c == ',') c = ' ';
  }
  std::istringstream stream(text);
  std::vector<double> values;
  std::string word;
  while (stream >> word) {
    try {
      size_t used = 0;
      values.push_back(std::stod(word, &used));
      REPHOTO_CHECK_USAGE(used == word.size(), "{}: '{}' is not a number", source, word);
    } catch (const std::logic_error&) {
      throw UsageError(fmt::format("{}: '{}' is not a number", source, word));
    }
  }
  REPHOTO_CHECK_USAGE(values.size() == 16,
                      "{}: a 4x4 transform needs 16 numbers (row-major), got {}", source,
                      values.size());
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i) m(i / 4, i % 4) = values[static_cast<size_t>(i)];
  return m;
}

CommandRunner SetupGeometry(CLI::App& app) {
  auto args = std::make_shared<GeometryArguments>();
  geometry::GeometryOptions& o = args->options;
  app.add_option("model", args->model, "Reconstruction: mesh or point cloud (.ply, .obj)")
      ->required();
  app.add_option("--reference", args->reference,
                 "Ground truth: mesh or point cloud (.ply, .obj), in the units of the tolerances")
      ->required();
  app.add_option("--out", args->out, "Output folder")->required();
  app.add_option("--tolerances", o.tolerances,
                 "Distance thresholds for completeness, precision, recall and F-score "
                 "(reference units, comma-separated)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--accuracy-fraction", o.accuracy_fraction,
                 "Accuracy is the distance within which this fraction of the model lies")
      ->capture_default_str();
  app.add_option("--samples", o.samples,
                 "Area-uniform samples per surface (a point cloud gives at most its points)")
      ->capture_default_str();
  app.add_option("--seed", o.seed, "Seed of the samples")->capture_default_str();
  app.add_option("--crop,--mask-box", args->crop,
                 "Only samples inside this box count: MINX,MINY,MINZ,MAXX,MAXY,MAXZ "
                 "(reference frame)")
      ->delimiter(',')
      ->expected(6);
  app.add_option("--transform", args->transform,
                 "4x4 transform applied to the model first: 16 numbers row-major, or a file "
                 "holding them")
      ->delimiter(',')
      ->expected(1, 16);
  app.add_flag("--no-ply", args->no_ply, "Do not write the distance-coloured PLYs");
  return [args]() {
    geometry::GeometryOptions options = args->options;
    if (!args->crop.empty()) {
      const auto& c = args->crop;
      options.crop = {{Eigen::Vector3d(c[0], c[1], c[2]), Eigen::Vector3d(c[3], c[4], c[5])}};
    }
    if (!args->transform.empty()) options.model_from_input = ParseTransform(args->transform);
    options.vertex_distances = !args->no_ply;
    options.Check();

    const mesh::Mesh model = mesh::ReadMesh(args->model);
    const mesh::Mesh reference = mesh::ReadMesh(args->reference);
    const geometry::GeometryResult result =
        geometry::EvaluateGeometry(model, reference, options, args->model, args->reference);
    const std::filesystem::path out = args->out;
    geometry::WriteGeometryJson(result, options, args->model, args->reference,
                                out / "geometry.json");
    geometry::WriteGeometryCsv(result, out / "geometry.csv");
    if (!args->no_ply) {
      geometry::WriteDistancePly(geometry::TransformMesh(model, options.model_from_input),
                                 result.model_vertex_distances, out / "model_distance.ply");
      geometry::WriteDistancePly(reference, result.reference_vertex_distances,
                                 out / "reference_distance.ply");
    }

    fmt::print("{} vs {}: {} and {} samples{}\n", args->model, args->reference,
               result.model_samples, result.reference_samples,
               options.crop ? " inside the crop box" : "");
    fmt::print("accuracy ({:g} % of the model within): {:.6g}\n", 100 * options.accuracy_fraction,
               result.accuracy);
    fmt::print("{:>12} {:>12} {:>10} {:>10} {:>10}\n", "tolerance", "completeness", "precision",
               "recall", "f_score");
    for (const geometry::ToleranceResult& t : result.tolerances) {
      fmt::print("{:>12.6g} {:>12.4f} {:>10.4f} {:>10.4f} {:>10.4f}\n", t.tolerance, t.completeness,
                 t.precision, t.recall, t.f_score);
    }
    fmt::print("wrote {} ({:.2f} s)\n", (out / "geometry.json").string(), result.seconds);
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(55, "geometry",
                "Geometric accuracy, completeness, precision/recall/F-score against a "
                "ground-truth surface",
                SetupGeometry);

}  // namespace rephoto::cli
