// rephoto degrade MODEL --out OUT.ply [--texture-noise N] [--geometry-noise N] [--simplify F]
//                 [--seed S] [--frequency K]
// Applies the paper's synthetic defects (Section 4.1) to a mesh or point cloud; see
// rephoto/degrade/degrade.h for the definitions. Deterministic for a seed.
#include <fmt/format.h>

#include <filesystem>
#include <memory>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/degrade/degrade.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/mesh/read_mesh.h"

namespace rephoto::cli {
namespace {

struct DegradeArguments {
  std::string model;
  std::string out;
  degrade::DegradeOptions options;
};

CommandRunner SetupDegrade(CLI::App& app) {
  auto args = std::make_shared<DegradeArguments>();
  app.add_option("MODEL", args->model, "Mesh or point cloud (PLY, OBJ)")->required();
  app.add_option("--out", args->out,
                 "Output PLY; noisy textures of a textured mesh are written next to it as "
                 "<stem>_<material>.png")
      ->required();
  app.add_option("--texture-noise", args->options.texture_noise,
                 "Maximum offset per RGB channel, colour units in [0,1]")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--geometry-noise", args->options.geometry_noise,
                 "Maximum displacement along normals, fraction of the bounding-box diagonal")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--simplify", args->options.simplify,
                 "Fraction of the faces removed by edge collapse, in [0,1)")
      ->check(CLI::Range(0.0, 0.9999))
      ->capture_default_str();
  app.add_option("--frequency", args->options.noise_frequency,
                 "Noise features per bounding-box diagonal")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--seed", args->options.seed, "Noise seed")->capture_default_str();
  return [args] {
    const mesh::Mesh model = mesh::ReadMesh(args->model);
    const std::filesystem::path out = std::filesystem::absolute(args->out);
    args->options.texture_dir = out.parent_path();
    args->options.texture_prefix = out.stem().string();
    degrade::DegradeReport report;
    mesh::Mesh degraded = degrade::Degrade(model, args->options, &report);
    // Texture paths relative to the PLY's folder where possible, so the files move together.
    for (auto& material : degraded.materials) {
      if (material.diffuse_texture.empty()) continue;
      const auto relative =
          std::filesystem::absolute(material.diffuse_texture).lexically_relative(out.parent_path());
      if (!relative.empty() && *relative.begin() != "..") material.diffuse_texture = relative;
    }
    mesh::WritePly(out, degraded);
    LogInfo(fmt::format("degrade: {} -> {} ({} -> {} vertices, extent {:.4g})", args->model,
                        args->out, report.vertices_before, report.vertices_after, report.extent));
    return static_cast<int>(ExitCode::kOk);
  };
}

REPHOTO_COMMAND(40, "degrade",
                "Add synthetic defects to a model: texture noise, geometry noise, simplification",
                SetupDegrade);

}  // namespace
}  // namespace rephoto::cli
