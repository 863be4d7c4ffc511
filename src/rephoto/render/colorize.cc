#include "rephoto/render/colorize.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/progress.h"
#include "rephoto/io/image_io.h"
#include "rephoto/render/render_model.h"
#include "rephoto/render/visibility.h"
#include "rephoto/render/weighted_median.h"

namespace rephoto::render {
namespace {

// One photo's sample of a vertex (which vertex: the parallel ViewObservations::vertices).
struct Observation {
  float weight;
  Eigen::Vector3f color;
};

// A photo as decoded: 8-bit samples (JPEG, 8-bit PNG) or floats (16-bit PNG, EXR, PFM).
struct Photo {
  Image8 bytes;
  Image floats;
  bool is8 = false;
  int width() const { return is8 ? bytes.width() : floats.width(); }
  int height() const { return is8 ? bytes.height() : floats.height(); }
  int channels() const { return is8 ? bytes.channels() : floats.channels(); }
  bool empty() const { return is8 ? bytes.empty() : floats.empty(); }
};

// Sample values as io::ReadImage returns them (v / 255 for 8-bit, exactly).
inline float Value(const Image& image, int x, int y, int c) { return image.at(x, y, c); }
inline float Value(const Image8& image, int x, int y, int c) {
  return static_cast<float>(image.at(x, y, c)) / 255.f;
}

// Bilinear sample at continuous position (px, py), pixel-corner convention; the caller keeps
// (px, py) within [0.5, width - 0.5] x [0.5, height - 0.5].
template <typename ImageType>
Eigen::Vector3f SampleBilinear(const ImageType& photo, double px, double py) {
  const double x = px - 0.5, y = py - 0.5;
  int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  x0 = std::clamp(x0, 0, photo.width() - 1);
  y0 = std::clamp(y0, 0, photo.height() - 1);
  const int x1 = std::min(x0 + 1, photo.width() - 1), y1 = std::min(y0 + 1, photo.height() - 1);
  const float ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
  const int c = photo.channels();
  Eigen::Vector3f out;
  for (int k = 0; k < 3; ++k) {
    const int ch = c >= 3 ? k : 0;
    const float v00 = Value(photo, x0, y0, ch), v10 = Value(photo, x1, y0, ch);
    const float v01 = Value(photo, x0, y1, ch), v11 = Value(photo, x1, y1, ch);
    const float top = v00 + ax * (v10 - v00);
    const float bottom = v01 + ax * (v11 - v01);
    out[k] = top + ay * (bottom - top);
  }
  return out;
}

// Scratch space of RobustMean, reused from vertex to vertex.
struct RobustScratch {
  std::vector<std::pair<float, float>> pairs;
  std::vector<float> residuals;
};

Eigen::Vector3f RobustMean(const Observation* obs, size_t n, int iterations,
                           RobustScratch& scratch) {
  if (n == 1) return obs[0].color;
  std::vector<std::pair<float, float>>& pairs = scratch.pairs;
  Eigen::Vector3f estimate;
  for (int k = 0; k < 3; ++k) {
    pairs.clear();
    for (size_t i = 0; i < n; ++i) pairs.emplace_back(obs[i].color[k], obs[i].weight);
    estimate[k] = WeightedMedian(pairs);
  }
  std::vector<float>& residuals = scratch.residuals;
  residuals.resize(n);
  for (int it = 0; it < iterations; ++it) {
    pairs.clear();
    for (size_t i = 0; i < n; ++i) {
      residuals[i] = (obs[i].color - estimate).norm();
      pairs.emplace_back(residuals[i], obs[i].weight);
    }
    const float scale = std::max(1.4826f * WeightedMedian(pairs), 1.0f / 255.0f);
    const float c = 2.385f * scale;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double weight_sum = 0;
    for (size_t i = 0; i < n; ++i) {
      const float r = residuals[i] / c;
      const double w = obs[i].weight / (1.0 + r * r);
      sum += w * obs[i].color.cast<double>();
      weight_sum += w;
    }
    if (!(weight_sum > 0)) break;
    estimate = (sum / weight_sum).cast<float>();
  }
  return estimate;
}

// The vertices of one block that one view sees, in increasing order, with their observations
// (compact lists: no per-vertex scratch arrays, no global scatter).
struct ViewObservations {
  std::vector<uint32_t> vertices;
  std::vector<Observation> observations;
};

constexpr int64_t kBlock = 8192;

// Tests every vertex against one view (render/visibility.h: facing, inside the image and the
// usable field, unoccluded) and records what the view sees, per block.
void ObserveView(const mesh::Mesh& mesh, const std::vector<Eigen::Vector3f>& normals,
                 RTCScene rtc_scene, const scene::View& view, camera::Camera camera,
                 const Photo& photo, const ColorizeOptions& options,
                 std::vector<ViewObservations>& seen) {
  const size_t n = mesh.positions.size();
  const int64_t blocks = static_cast<int64_t>(seen.size());
  if (camera.width != photo.width() || camera.height != photo.height()) {
    camera = camera.Scaled(photo.width(), photo.height());
  }
  const ViewGeometry geometry(camera, view.cam_from_world);
  VisibilityRule rule;
  rule.min_facing_cosine = options.min_facing_cosine;
  rule.occlusion_epsilon = options.occlusion_epsilon;
  const double focal = camera.MeanFocalLength();
  ParallelFor(0, blocks, 1, [&](int64_t block_begin, int64_t block_end) {
    // Occlusion rays go 16 at a time (neighbouring vertices: a coherent packet from the
    // camera centre); the batch visits the unoccluded ones in vertex order.
    OcclusionBatch batch(rtc_scene, geometry.center, rule.occlusion_epsilon);
    struct Lane {
      uint32_t vertex;
      float weight;
      double px, py;
    };
    Lane lanes[16];
    int count = 0;
    ViewObservations* found = nullptr;
    auto record = [&](uint32_t lane) {
      const Lane& l = lanes[lane];
      found->vertices.push_back(l.vertex);
      found->observations.push_back({l.weight, photo.is8
                                                   ? SampleBilinear(photo.bytes, l.px, l.py)
                                                   : SampleBilinear(photo.floats, l.px, l.py)});
    };
    for (int64_t block = block_begin; block < block_end; ++block) {
      found = &seen[block];
      const int64_t begin = block * kBlock;
      const int64_t end = std::min(begin + kBlock, static_cast<int64_t>(n));
      for (int64_t i = begin; i < end; ++i) {
        const Eigen::Vector3d p = mesh.positions[i].cast<double>();
        const Eigen::Vector3d normal =
            normals.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(normals[i].cast<double>());
        const std::optional<SightingResult> sighting = Sighting(geometry, p, normal, rule);
        if (!sighting) continue;
        const double density = focal / sighting->distance;
        lanes[count] = {static_cast<uint32_t>(i),
                        static_cast<float>(sighting->cosine * density * density),
                        sighting->pixel.x(), sighting->pixel.y()};
        batch.Add(p, static_cast<uint32_t>(count), record);
        if (++count == 16) count = 0;  // the batch traced and visited the 16 lanes
      }
      batch.Flush(record);  // a block's list holds its own vertices only
      count = 0;
    }
  });
}

// Each vertex's colour: the robust mean of its observations in view order.
VertexColors FuseObservations(size_t n, const std::vector<std::vector<ViewObservations>>& seen,
                              const ColorizeOptions& options, size_t* total_observations) {
  const int64_t blocks = (static_cast<int64_t>(n) + kBlock - 1) / kBlock;
  // Each vertex's observations in view order (deterministic), gathered per block by walking
  // every view's list of that block.
  VertexColors out;
  out.colors.assign(n, Eigen::Vector3f::Zero());
  out.view_count = {"view_count", std::vector<float>(n, 0.0f)};
  for (const auto& view_blocks : seen) {
    for (const ViewObservations& list : view_blocks) *total_observations += list.vertices.size();
  }
  ParallelFor(0, blocks, 1, [&](int64_t block_begin, int64_t block_end) {
    RobustScratch scratch;
    std::vector<Observation> gathered;
    std::vector<size_t> cursor(seen.size());
    for (int64_t block = block_begin; block < block_end; ++block) {
      std::fill(cursor.begin(), cursor.end(), 0);
      const int64_t begin = block * kBlock;
      const int64_t end = std::min(begin + kBlock, static_cast<int64_t>(n));
      for (int64_t i = begin; i < end; ++i) {
        gathered.clear();
        for (size_t v = 0; v < seen.size(); ++v) {
          const ViewObservations& list = seen[v][block];
          if (cursor[v] < list.vertices.size() &&
              list.vertices[cursor[v]] == static_cast<uint32_t>(i)) {
            gathered.push_back(list.observations[cursor[v]++]);
          }
        }
        out.view_count.values[i] = static_cast<float>(gathered.size());
        if (gathered.empty()) continue;
        out.colors[i] =
            RobustMean(gathered.data(), gathered.size(), options.irls_iterations, scratch)
                .cwiseMax(0.0f)
                .cwiseMin(1.0f);
      }
    }
  });
  return out;
}

}  // namespace

VertexColors ColorizeVertices(const RenderModel& model, const scene::Scene& scene,
                              const std::vector<size_t>& views, const ColorizeOptions& options,
                              ColorizeReport* report) {
  const mesh::Mesh& mesh = model.mesh();
  for (size_t v : views) {
    REPHOTO_CHECK(v < scene.views.size(), "colorize: view index {} out of range ({} views)", v,
                  scene.views.size());
  }
  const size_t n = mesh.positions.size();
  std::vector<Eigen::Vector3f> computed_normals;
  if (mesh.normals.empty() && !mesh.faces.empty()) computed_normals = ComputeVertexNormals(mesh);
  const std::vector<Eigen::Vector3f>& normals =
      mesh.normals.empty() ? computed_normals : mesh.normals;
  RTCScene rtc_scene = model.scene();

  // Vertices are tested and their colours fused in fixed blocks, in parallel. seen[v][b]: the
  // vertices of block b that view v sees, with their observations.
  const int64_t blocks = (static_cast<int64_t>(n) + kBlock - 1) / kBlock;
  std::vector<std::vector<ViewObservations>> seen(
      views.size(), std::vector<ViewObservations>(static_cast<size_t>(blocks)));
  std::unique_ptr<Progress> progress;
  if (options.show_progress) progress = std::make_unique<Progress>("colorize", views.size());
  // Photos are decoded two at a time (decoding dominates; one core each) into two reused
  // buffers, then processed in view order, so the result does not depend on the thread count.
  constexpr size_t kBatch = 2;
  std::vector<Photo> batch(kBatch);
  for (size_t position = 0; position < views.size(); ++position) {
    const size_t view_index = views[position];
    const scene::View& view = scene.views[view_index];
    if (position % kBatch == 0) {
      const size_t count = std::min(kBatch, views.size() - position);
      ParallelFor(0, static_cast<int64_t>(count), 1, [&](int64_t begin, int64_t end) {
        for (int64_t b = begin; b < end; ++b) {
          Photo& photo = batch[b];
          photo.is8 = io::ReadImage8(scene.views[views[position + b]].image_path, &photo.bytes,
                                     &photo.floats);
        }
      });
    }
    const Photo& photo = batch[position % kBatch];  // buffers reused: no zeroing, no faults
    REPHOTO_CHECK(photo.channels() >= 1 && photo.channels() <= 4 && !photo.empty(),
                  "{}: unsupported photo ({} channels)", view.image_path.string(),
                  photo.channels());
    ObserveView(mesh, normals, rtc_scene, view, scene.CameraOf(view), photo, options,
                seen[position]);
    if (progress) progress->Advance(view.name);
  }
  if (progress) progress->Finish();
  size_t total_observations = 0;
  VertexColors out = FuseObservations(n, seen, options, &total_observations);
  if (report != nullptr) {
    report->vertices = n;
    report->observations = total_observations;
    report->colored_vertices = static_cast<size_t>(std::count_if(
        out.view_count.values.begin(), out.view_count.values.end(), [](float c) { return c > 0; }));
  }
  return out;
}

mesh::Mesh ColorizeMesh(const mesh::Mesh& mesh, const scene::Scene& scene,
                        const std::vector<size_t>& views, const ColorizeOptions& options,
                        ColorizeReport* report) {
  mesh.Validate("mesh");
  mesh::Mesh geometry;  // positions, faces and normals only: the occlusion model
  geometry.positions = mesh.positions;
  geometry.faces = mesh.faces;
  geometry.normals = mesh.normals;
  geometry.radii = mesh.radii;
  ModelOptions model_options;
  model_options.load_textures = false;
  const RenderModel model(std::move(geometry), model_options, "mesh");
  VertexColors colors = ColorizeVertices(model, scene, views, options, report);
  mesh::Mesh out = mesh;
  out.colors = std::move(colors.colors);
  out.SetScalar(std::move(colors.view_count));
  return out;
}

}  // namespace rephoto::render
