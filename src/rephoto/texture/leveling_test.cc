// Seam leveling (leveling.h) against an independent solution of the energy the header states:
// the same terms written as rows of a dense weighted least-squares problem (one row per seam
// pair, per face edge, per variable) and solved by Householder QR, instead of the code's sparse
// normal equations and conjugate gradients. Two photos of constant, different colours (an
// exposure difference), so every f(v, l) is that photo's colour.
#include "rephoto/texture/leveling.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <map>
#include <utility>
#include <vector>

#include "rephoto/io/image_io.h"
#include "rephoto/testing/testing.h"

namespace rephoto::texture {
namespace {

// A 4 x 3 vertex grid in the plane z = 0 (x in [0, 3], y in [0, 2]): 6 quads, 12 triangles.
mesh::Mesh Grid() {
  mesh::Mesh mesh;
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) mesh.positions.emplace_back(x, y, 0);
  }
  for (int y = 0; y < 2; ++y) {
    for (int x = 0; x < 3; ++x) {
      const uint32_t a = y * 4 + x, b = a + 1, c = a + 4, d = c + 1;
      mesh.faces.push_back({a, b, d});
      mesh.faces.push_back({a, d, c});
    }
  }
  return mesh;
}

TEST(LevelSeams, MatchesADenseLeastSquaresSolutionOfTheStatedEnergy) {
  const mesh::Mesh mesh = Grid();
  // Labels per face (quads row-major, two triangles each): view 0, 1, 0 in the bottom row,
  // view 1, 1, and none in the top row.
  const std::vector<int> labels = {0, 0, 1, 1, 0, 0, 1, 1, 1, 1, -1, -1};
  // Two photos of constant colour (k / 255: exact in an 8-bit PNG), seen from above.
  const std::filesystem::path dir = testing::MakeTempDir();
  const Eigen::Vector3f colors[2] = {Eigen::Vector3f(60, 100, 140) / 255.0f,
                                     Eigen::Vector3f(120, 90, 200) / 255.0f};
  scene::Scene scene;
  scene.cameras[0] = camera::Camera{camera::CameraModel::kPinhole, 64, 64, {40, 40, 32, 32}};
  for (int l = 0; l < 2; ++l) {
    Image photo(64, 64, 3);
    for (int y = 0; y < 64; ++y) {
      for (int x = 0; x < 64; ++x) {
        for (int c = 0; c < 3; ++c) photo.at(x, y, c) = colors[l][c];
      }
    }
    scene::View view;
    view.name = "p" + std::to_string(l) + ".png";
    view.image_path = dir / view.name;
    io::WritePng(view.image_path, photo);
    // Above the grid's centre (1.5, 1) at height 3 + l, looking down: cam = R (X - C).
    view.cam_from_world.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
    view.cam_from_world.translation =
        -view.cam_from_world.rotation * Eigen::Vector3d(1.5 + 0.1 * l, 1.0, 3.0 + l);
    scene.views.push_back(view);
  }
  LevelingOptions options;
  options.tolerance = 1e-12;
  options.max_iterations = 10000;
  LevelingReport report;
  const ColorAdjustment adjustment =
      LevelSeams(mesh, MakeVertexFaces(mesh), labels, scene, {0, 1}, options, &report);

  // The reference. Variables: (vertex, label) for each label of the faces around the vertex.
  std::map<std::pair<int, int>, int> index;
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    if (labels[f] < 0) continue;
    for (uint32_t v : mesh.faces[f]) {
      index.emplace(std::make_pair(static_cast<int>(v), labels[f]), 0);
    }
  }
  int n = 0;
  for (auto& [key, i] : index) i = n++;
  std::vector<Eigen::VectorXd> rows;
  std::vector<Eigen::Vector3d> targets;
  auto add_row = [&](double weight, int i, int j, const Eigen::Vector3d& target) {
    Eigen::VectorXd row = Eigen::VectorXd::Zero(n);
    row[i] += std::sqrt(weight);
    if (j >= 0) row[j] -= std::sqrt(weight);
    rows.push_back(row);
    targets.push_back(std::sqrt(weight) * target);
  };
  // Seams: (f(v,l) + g(v,l)) - (f(v,m) + g(v,m)) -> rows g(v,l) - g(v,m) = f(v,m) - f(v,l).
  size_t seam_terms = 0;
  for (int v = 0; v < static_cast<int>(mesh.positions.size()); ++v) {
    for (int l = 0; l < 2; ++l) {
      for (int m = l + 1; m < 2; ++m) {
        if (!index.count({v, l}) || !index.count({v, m})) continue;
        add_row(1.0, index[{v, l}], index[{v, m}], (colors[m] - colors[l]).cast<double>());
        ++seam_terms;
      }
    }
  }
  // Smoothness: every edge of every labelled face.
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    if (labels[f] < 0) continue;
    for (int k = 0; k < 3; ++k) {
      add_row(options.smoothness, index[{static_cast<int>(mesh.faces[f][k]), labels[f]}],
              index[{static_cast<int>(mesh.faces[f][(k + 1) % 3]), labels[f]}],
              Eigen::Vector3d::Zero());
    }
  }
  for (int i = 0; i < n; ++i) add_row(options.regularization, i, -1, Eigen::Vector3d::Zero());
  Eigen::MatrixXd a(rows.size(), n);
  Eigen::MatrixXd b(rows.size(), 3);
  for (size_t r = 0; r < rows.size(); ++r) {
    a.row(r) = rows[r].transpose();
    b.row(r) = targets[r].transpose();
  }
  const Eigen::MatrixXd g = a.colPivHouseholderQr().solve(b);

  EXPECT_EQ(report.variables, static_cast<size_t>(n));
  EXPECT_EQ(report.seam_terms, seam_terms);
  EXPECT_GT(seam_terms, 3u);
  double largest = 0;
  for (const auto& [key, i] : index) {
    const Eigen::Vector3f got = adjustment.At(key.first, key.second);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(got[c], g(i, c), 1e-5) << "vertex " << key.first << " label " << key.second;
      largest = std::max(largest, std::abs(g(i, c)));
    }
  }
  EXPECT_GT(largest, 0.05);  // the offsets are not trivially zero
  // What leveling is for: across each seam the adjusted colours nearly meet (the jump was up to
  // 60/255 in a channel).
  for (int v = 0; v < static_cast<int>(mesh.positions.size()); ++v) {
    if (!index.count({v, 0}) || !index.count({v, 1})) continue;
    const Eigen::Vector3f side0 = colors[0] + adjustment.At(v, 0);
    const Eigen::Vector3f side1 = colors[1] + adjustment.At(v, 1);
    EXPECT_LT((side0 - side1).cwiseAbs().maxCoeff(), 0.1 * 60 / 255.0) << "vertex " << v;
  }
}

}  // namespace
}  // namespace rephoto::texture
