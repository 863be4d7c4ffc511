#include "rephoto/texture/leveling.h"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>
#include <algorithm>

#include "rephoto/core/parallel.h"
#include "rephoto/texture/photo.h"

namespace rephoto::texture {

ColorAdjustment LevelSeams(const mesh::Mesh& mesh, const VertexFaces& vertex_faces,
                           const std::vector<int>& face_labels, const scene::Scene& scene,
                           const std::vector<size_t>& views, const LevelingOptions& options,
                           LevelingReport* report) {
  const size_t vertex_count = mesh.positions.size();
  ColorAdjustment out;
  out.offsets.assign(vertex_count + 1, 0);
  for (size_t v = 0; v < vertex_count; ++v) {
    const size_t start = out.labels.size();
    for (uint32_t i = vertex_faces.offsets[v]; i < vertex_faces.offsets[v + 1]; ++i) {
      const int l = face_labels[vertex_faces.faces[i]];
      if (l >= 0 &&
          std::find(out.labels.begin() + start, out.labels.end(), l) == out.labels.end()) {
        out.labels.push_back(l);
      }
    }
    std::sort(out.labels.begin() + start, out.labels.end());
    out.offsets[v + 1] = static_cast<uint32_t>(out.labels.size());
  }
  const size_t n = out.labels.size();
  out.values.assign(n, Eigen::Vector3f::Zero());
  LevelingReport local;
  local.variables = n;

  // Seam colours f(v, l), photo by photo.
  std::vector<std::vector<uint32_t>> seam_vertices_of(views.size());
  for (size_t v = 0; v < vertex_count; ++v) {
    if (out.offsets[v + 1] - out.offsets[v] < 2) continue;
    ++local.seam_vertices;
    for (uint32_t i = out.offsets[v]; i < out.offsets[v + 1]; ++i) {
      seam_vertices_of[out.labels[i]].push_back(static_cast<uint32_t>(v));
    }
  }
  std::vector<Eigen::Vector3f> seam_color(n, Eigen::Vector3f::Zero());
  std::vector<uint8_t> has_color(n, 0);
  Photo photo;
  for (size_t l = 0; l < views.size(); ++l) {
    if (seam_vertices_of[l].empty()) continue;
    photo.Load(scene, scene.views[views[l]]);
    const auto& list = seam_vertices_of[l];
    ParallelFor(0, static_cast<int64_t>(list.size()), 1024, [&](int64_t begin, int64_t end) {
      for (int64_t k = begin; k < end; ++k) {
        const uint32_t v = list[k];
        const Eigen::Vector3d p = mesh.positions[v].cast<double>();
        Eigen::Vector3f sum = Eigen::Vector3f::Zero();
        int count = 0;
        auto add = [&](const Eigen::Vector3d& point) {
          const auto pixel = photo.Project(point);
          if (!pixel || !(pixel->x() >= 0.5 && pixel->x() <= photo.width() - 0.5 &&
                          pixel->y() >= 0.5 && pixel->y() <= photo.height() - 0.5)) {
            return;
          }
          sum += photo.Sample(pixel->x(), pixel->y());
          ++count;
        };
        add(p);
        for (uint32_t i = vertex_faces.offsets[v]; i < vertex_faces.offsets[v + 1]; ++i) {
          for (uint32_t w : mesh.faces[vertex_faces.faces[i]]) {
            if (w != v) add(p + 0.25 * (mesh.positions[w].cast<double>() - p));
          }
        }
        if (count == 0) continue;
        for (uint32_t i = out.offsets[v]; i < out.offsets[v + 1]; ++i) {
          if (out.labels[i] == static_cast<int>(l)) {
            seam_color[i] = sum / static_cast<float>(count);
            has_color[i] = 1;
          }
        }
      }
    });
  }

  // Normal equations.
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(n), 3);
  auto add_pair = [&](uint32_t i, uint32_t j, double w) {
    triplets.emplace_back(i, i, w);
    triplets.emplace_back(j, j, w);
    triplets.emplace_back(i, j, -w);
    triplets.emplace_back(j, i, -w);
  };
  for (size_t v = 0; v < vertex_count; ++v) {
    for (uint32_t i = out.offsets[v]; i < out.offsets[v + 1]; ++i) {
      for (uint32_t j = i + 1; j < out.offsets[v + 1]; ++j) {
        if (!has_color[i] || !has_color[j]) continue;
        // Row: g_i - g_j = f_j - f_i.
        add_pair(i, j, 1.0);
        const Eigen::Vector3d d = (seam_color[j] - seam_color[i]).cast<double>();
        rhs.row(i) += d.transpose();
        rhs.row(j) -= d.transpose();
        ++local.seam_terms;
      }
    }
  }
  auto index_of = [&](uint32_t vertex, int label) {
    for (uint32_t i = out.offsets[vertex]; i < out.offsets[vertex + 1]; ++i) {
      if (out.labels[i] == label) return i;
    }
    return out.offsets[vertex];  // unreachable: every corner of a labelled face has the label
  };
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const int l = face_labels[f];
    if (l < 0) continue;
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = mesh.faces[f][k], b = mesh.faces[f][(k + 1) % 3];
      if (a != b) add_pair(index_of(a, l), index_of(b, l), options.smoothness);
    }
  }
  for (size_t i = 0; i < n; ++i) triplets.emplace_back(i, i, options.regularization);
  if (local.seam_terms > 0) {
    Eigen::SparseMatrix<double> matrix(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
    matrix.setFromTriplets(triplets.begin(), triplets.end());
    std::vector<Eigen::Triplet<double>>().swap(triplets);
    Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> solver;
    solver.setMaxIterations(options.max_iterations);
    solver.setTolerance(options.tolerance);
    solver.compute(matrix);
    for (int c = 0; c < 3; ++c) {
      const Eigen::VectorXd x = solver.solve(rhs.col(c));
      local.iterations = std::max(local.iterations, static_cast<int>(solver.iterations()));
      for (size_t i = 0; i < n; ++i) out.values[i][c] = static_cast<float>(x[i]);
    }
  }
  if (report != nullptr) *report = local;
  return out;
}

}  // namespace rephoto::texture
