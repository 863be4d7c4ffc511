#include "rephoto/report/view3d.h"

#include <fmt/format.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/stats.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/report/html.h"
#include "rephoto/report/thumbnails.h"
#include "rephoto/report/view3d_assets.h"
#include "rephoto/scene/colmap.h"

namespace rephoto::report {

View3dCamera MakeView3dCamera(const camera::Camera& intrinsics, const Eigen::Matrix3d& rotation,
                              const Eigen::Vector3d& translation, std::string name,
                              std::string role) {
  View3dCamera c;
  c.name = std::move(name);
  c.role = std::move(role);
  c.fx = intrinsics.FocalLengthX();
  c.fy = intrinsics.FocalLengthY();
  c.cx = intrinsics.PrincipalPointX();
  c.cy = intrinsics.PrincipalPointY();
  c.width = intrinsics.width;
  c.height = intrinsics.height;
  c.rotation = rotation;
  c.translation = translation;
  return c;
}
namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

namespace {

// An image of a COLMAP model as a camera of the view (its quaternion normalised).
View3dCamera CameraOfColmapImage(const scene::ColmapModel& colmap, const scene::ColmapImage& image,
                                 std::string name, std::string role) {
  const Eigen::Vector4d& q = image.quaternion;
  return MakeView3dCamera(colmap.cameras.at(image.camera_id),
                          Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix(),
                          image.translation, std::move(name), std::move(role));
}

static_assert(std::endian::native == std::endian::little, "the view's arrays are little-endian");

template <typename T>
std::string Base64Of(const T* data, size_t count) {
  return Base64(std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(data),
                                         count * sizeof(T)));
}

Json NumberOrNull(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

// Thumbnails stored once per view ("images"), cameras refer to them by index: the same photo's
// thumbnail appears in every run of a comparison.
struct ImageTable {
  Json images = Json::array();
  std::map<std::string, size_t> index;
  Json Add(const std::string& uri) {
    auto [it, added] = index.try_emplace(uri, images.size());
    if (added) images.push_back(uri);
    return it->second;
  }
};

Json CameraJson(const View3dCamera& c, ImageTable& table) {
  Json j;
  j["name"] = c.name;
  j["role"] = c.role;
  j["test_fold"] = c.test_fold;
  j["train_folds"] = c.train_folds;
  j["K"] = {c.fx, c.fy, c.cx, c.cy, c.width, c.height};
  Json r = Json::array();
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) r.push_back(c.rotation(i, k));
  }
  j["R"] = r;
  j["t"] = {c.translation.x(), c.translation.y(), c.translation.z()};
  j["error"] = NumberOrNull(c.error);
  if (!c.note.empty()) j["note"] = c.note;
  if (!c.photo_uri.empty()) j["photo"] = table.Add(c.photo_uri);
  if (!c.rephoto_uri.empty()) j["rephoto"] = table.Add(c.rephoto_uri);
  if (!c.error_uri.empty()) j["error_image"] = table.Add(c.error_uri);
  return j;
}

// Whether two vectors hold the same bytes.
template <typename T>
bool SameArray(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && !a.empty() &&
         std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

// Model `index` of `models` as JSON; an array equal to an earlier model's (runs of one mesh:
// the ground truth and its texture noise share positions and faces) is written as a reference
// "<name>_of": <earlier index> instead of a second copy.
Json ModelJson(const std::vector<View3dModel>& models, size_t index, ImageTable& table) {
  const View3dModel& m = models[index];
  REPHOTO_CHECK(!m.positions.empty(), "3D view: model '{}' has no vertices", m.label);
  const size_t n = m.positions.size();
  REPHOTO_CHECK((m.error.empty() || m.error.size() == n) && (m.colors.empty() || m.colors.size() == n) &&
                    (m.unseen.empty() || m.unseen.size() == n),
                "3D view: model '{}': per-vertex arrays do not match its {} vertices", m.label, n);
  Json j;
  j["label"] = m.label;
  j["metric"] = m.metric;
  j["low"] = NumberOrNull(m.low);
  j["high"] = NumberOrNull(m.high);
  j["kind"] = m.faces.empty() ? "points" : "mesh";
  j["vertices"] = n;
  j["faces"] = m.faces.size();
  j["original_vertices"] = m.original_vertices;
  j["original_faces"] = m.original_faces;
  auto earlier = [&](auto member) -> int {
    for (size_t k = 0; k < index; ++k) {
      if (SameArray(models[k].*member, m.*member)) return static_cast<int>(k);
    }
    return -1;
  };
  if (const int k = earlier(&View3dModel::positions); k >= 0) {
    j["positions_of"] = k;
  } else {
    j["positions"] = Base64Of(reinterpret_cast<const float*>(m.positions.data()), 3 * n);
  }
  if (!m.faces.empty()) {
    if (const int k = earlier(&View3dModel::faces); k >= 0) {
      j["indices_of"] = k;
    } else {
      j["indices"] =
          Base64Of(reinterpret_cast<const uint32_t*>(m.faces.data()), 3 * m.faces.size());
    }
  }
  if (!m.error.empty()) j["error"] = Base64Of(m.error.data(), n);
  if (!m.colors.empty()) {
    if (const int k = earlier(&View3dModel::colors); k >= 0) {
      j["colors_of"] = k;
    } else {
      j["colors"] = Base64Of(reinterpret_cast<const uint8_t*>(m.colors.data()), 3 * n);
    }
  }
  if (!m.unseen.empty()) j["unseen"] = Base64Of(m.unseen.data(), n);
  j["folds"] = m.folds;
  Json cameras = Json::array();
  for (const View3dCamera& c : m.cameras) cameras.push_back(CameraJson(c, table));
  j["cameras"] = cameras;
  if (!m.note.empty()) j["note"] = m.note;
  return j;
}

// Keeps the vertices in `keep` (sorted, unique), remapping faces.
void KeepVertices(View3dModel& m, const std::vector<uint32_t>& keep) {
  std::vector<uint32_t> remap(m.positions.size(), UINT32_MAX);
  for (size_t i = 0; i < keep.size(); ++i) remap[keep[i]] = static_cast<uint32_t>(i);
  auto gather = [&](auto& values) {
    if (values.empty()) return;
    std::remove_reference_t<decltype(values)> out;
    out.reserve(keep.size());
    for (uint32_t k : keep) out.push_back(values[k]);
    values = std::move(out);
  };
  gather(m.positions);
  gather(m.error);
  gather(m.colors);
  gather(m.unseen);
  for (auto& face : m.faces) {
    for (uint32_t& index : face) index = remap[index];
  }
}

// "comment colour range (jet) low L high H; ..." of project::WriteProjectedPly.
bool ReadColourRange(const fs::path& ply, float* low, float* high) {
  std::ifstream in(ply, std::ios::binary);  // the header is the first few hundred bytes
  std::string head(4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(in.gcount()));
  const size_t end = head.find("end_header");
  if (end != std::string::npos) head.resize(end);
  static const std::regex range(R"(colour range \(jet\) low (\S+) high (\S+?);)");
  std::smatch match;
  if (!std::regex_search(head, match, range)) return false;
  try {
    *low = std::stof(match[1].str());
    *high = std::stof(match[2].str());
  } catch (const std::exception&) {
    return false;
  }
  return std::isfinite(*low) && std::isfinite(*high);
}

// The photos of a run: each once, with the folds in which it was tested or trained, from
// RUN/split/<fold>/{test,train}/sparse.
void AddRunCameras(const run::RunData& run, View3dModel& model) {
  const fs::path split = run.dir / "split";
  std::error_code ec;
  if (!fs::is_directory(split, ec)) return;
  std::vector<fs::path> folds;
  for (const fs::directory_entry& entry : fs::directory_iterator(split, ec)) {
    if (entry.is_directory() && entry.path().filename().string().rfind("fold_", 0) == 0) {
      folds.push_back(entry.path());
    }
  }
  std::sort(folds.begin(), folds.end());
  std::map<std::string, size_t> index;
  for (size_t f = 0; f < folds.size(); ++f) {
    model.folds.push_back(folds[f].filename().string());
    for (const char* part : {"test", "train"}) {
      const fs::path sparse = folds[f] / part / "sparse";
      if (!scene::DetectColmapFormat(sparse)) continue;
      const scene::ColmapModel colmap = scene::ReadColmapModel(sparse);
      for (const scene::ColmapImage& image : colmap.images) {
        auto [it, added] = index.try_emplace(image.name, model.cameras.size());
        if (added) {
          View3dCamera c = CameraOfColmapImage(colmap, image, image.name, "photo");
          model.cameras.push_back(std::move(c));
        }
        View3dCamera& c = model.cameras[it->second];
        if (std::string(part) == "test") {
          c.test_fold = static_cast<int>(f);
        } else {
          c.train_folds.push_back(static_cast<int>(f));
        }
      }
    }
  }
}

std::string Stem(const std::string& name) { return fs::path(name).replace_extension("").string(); }

// Image errors and thumbnails of the evaluated photos.
void AddImages(const run::RunData& run, const std::string& metric, int thumbnail_width,
               View3dModel& model) {
  const int m = run.MetricIndex(metric);
  const std::optional<metrics::Metric> parsed = metrics::ParseMetric(metric);
  std::map<std::string, const run::ImageRow*> rows;  // by stem (per_image.csv names are stems)
  for (const run::ImageRow& image : run.images) rows[Stem(image.name)] = &image;
  std::vector<std::pair<View3dCamera*, const run::ImageRow*>> jobs;
  for (View3dCamera& c : model.cameras) {
    const auto it = rows.find(Stem(c.name));
    if (it == rows.end()) continue;
    if (m >= 0 && it->second->status == "ok") c.error = it->second->metrics[m];
    if (thumbnail_width > 0 && it->second->status == "ok") jobs.push_back({&c, it->second});
  }
  ForEachThumbnailJob(static_cast<int64_t>(jobs.size()), [&](int64_t i,
                                                              ThumbnailScratch* scratch) {
    View3dCamera& c = *jobs[i].first;
    const run::ImageRow& image = *jobs[i].second;
    c.photo_uri = PhotoThumbnail(run.PhotoPath(image), thumbnail_width, scratch).data_uri;
    Thumbnail rephoto, mask;
    RenderThumbnails(run.RenderPath(image), thumbnail_width, &rephoto, &mask, scratch);
    c.rephoto_uri = rephoto.data_uri;
    if (parsed) {
      const fs::path errors = run.ImageDir(image) / "errors";
      const std::string stem = image.name + "." + metric;
      c.error_uri = ErrorThumbnail(errors / (stem + ".exr"), errors / (stem + ".png"), *parsed,
                                   thumbnail_width, scratch)
                        .data_uri;
    }
  });
}

// The run's model colours (run.json inputs.model.path), when readable and matching.
void AddModelColours(const run::RunData& run, const mesh::Mesh& projected, View3dModel& model) {
  const Json& j = run.run;
  std::string path;
  if (j.is_object() && j.contains("inputs") && j["inputs"].is_object() &&
      j["inputs"].contains("model") && j["inputs"]["model"].is_object() &&
      j["inputs"]["model"].value("path", Json()).is_string()) {
    path = j["inputs"]["model"]["path"].get<std::string>();
  }
  if (path.empty()) {
    model.note = "model colours: the run names no model file";
    return;
  }
  const fs::path readable = run.Readable(path);
  if (readable.empty()) {
    model.note = "model colours: " + path + " lies outside the run and the folders named";
    return;
  }
  try {
    const mesh::Mesh m = mesh::ReadMesh(readable);
    if (m.vertex_count() != projected.vertex_count() || m.colors.size() != m.vertex_count()) {
      model.note = "model colours: " + path + " has no vertex colours for these vertices";
      return;
    }
    model.colors.resize(m.colors.size());
    for (size_t i = 0; i < m.colors.size(); ++i) {
      for (int c = 0; c < 3; ++c) {
        model.colors[i][c] = static_cast<uint8_t>(
            std::lround(255.f * std::clamp(m.colors[i][c], 0.f, 1.f)));
      }
    }
  } catch (const Error& e) {
    model.note = std::string("model colours: ") + e.what();
  }
}

}  // namespace

namespace {

// For every original vertex, the nearest of the kept ones (indices into `kept`; among kept
// vertices at exactly the same distance the lowest index), by a uniform grid over the kept
// vertices (searched ring by ring until a ring past the best distance). The grid is the kept
// indices sorted by cell with an open-addressing table from cell to its run of indices: one
// probe per cell, no allocation per cell (a hash map of vectors was 15 % of a report's CPU).
std::vector<uint32_t> NearestKept(const std::vector<Eigen::Vector3f>& positions,
                                  const std::vector<uint32_t>& kept) {
  Eigen::Vector3f lo = positions[kept[0]], hi = lo;
  for (uint32_t k : kept) {
    lo = lo.cwiseMin(positions[k]);
    hi = hi.cwiseMax(positions[k]);
  }
  const float diagonal = std::max((hi - lo).norm(), 1e-12f);
  // About one kept vertex per cell on a surface: cell = diagonal / sqrt(kept).
  const float cell = diagonal / std::sqrt(static_cast<float>(kept.size()));
  auto key = [&](const Eigen::Vector3f& p) {
    return Eigen::Vector3i(static_cast<int>(std::floor((p.x() - lo.x()) / cell)),
                           static_cast<int>(std::floor((p.y() - lo.y()) / cell)),
                           static_cast<int>(std::floor((p.z() - lo.z()) / cell)));
  };
  // Cells as 3 x 21 bits (offset by 2^20); cells beyond that range hold no kept vertex (kept
  // vertices lie in [0, sqrt(kept)] cells on each axis) and are skipped.
  constexpr int64_t kBias = int64_t{1} << 20;
  auto pack = [](const Eigen::Vector3i& c, uint64_t* packed) {
    const int64_t x = c.x() + kBias, y = c.y() + kBias, z = c.z() + kBias;
    if (x < 0 || y < 0 || z < 0 || x >= 2 * kBias || y >= 2 * kBias || z >= 2 * kBias) {
      return false;
    }
    *packed = (static_cast<uint64_t>(x) << 42) | (static_cast<uint64_t>(y) << 21) |
              static_cast<uint64_t>(z);
    return true;
  };
  std::vector<std::pair<uint64_t, uint32_t>> sorted(kept.size());
  for (uint32_t i = 0; i < kept.size(); ++i) {
    uint64_t packed = 0;
    pack(key(positions[kept[i]]), &packed);  // always in range (see above)
    sorted[i] = {packed, i};
  }
  std::sort(sorted.begin(), sorted.end());
  struct Slot {
    uint64_t key = ~uint64_t{0};  // empty (no packed cell has all bits set)
    uint32_t begin = 0, end = 0;
  };
  size_t cells = 0;
  for (size_t i = 0; i < sorted.size(); ++i) cells += i == 0 || sorted[i].first != sorted[i - 1].first;
  const size_t capacity = std::bit_ceil(2 * cells);
  const size_t mask = capacity - 1;
  const int shift = 64 - std::countr_zero(capacity);  // Fibonacci hashing: the product's top bits
  auto slot_of = [shift](uint64_t k) {
    return static_cast<size_t>((k * 0x9E3779B97F4A7C15ull) >> shift);
  };
  std::vector<Slot> table(capacity);
  for (size_t i = 0; i < sorted.size();) {
    size_t j = i;
    while (j < sorted.size() && sorted[j].first == sorted[i].first) ++j;
    size_t s = slot_of(sorted[i].first);
    while (table[s].key != ~uint64_t{0}) s = (s + 1) & mask;
    table[s] = {sorted[i].first, static_cast<uint32_t>(i), static_cast<uint32_t>(j)};
    i = j;
  }
  auto find = [&](uint64_t k) -> const Slot* {
    for (size_t s = slot_of(k);; s = (s + 1) & mask) {
      if (table[s].key == k) return &table[s];
      if (table[s].key == ~uint64_t{0}) return nullptr;
    }
  };
  std::vector<uint32_t> nearest(positions.size(), 0);
  ParallelFor(0, static_cast<int64_t>(positions.size()), 4096, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      const Eigen::Vector3f& p = positions[v];
      const Eigen::Vector3i c = key(p);
      float best = std::numeric_limits<float>::infinity();
      uint32_t best_index = 0;
      for (int ring = 0; ring < 64; ++ring) {
        for (int dz = -ring; dz <= ring; ++dz) {
          for (int dy = -ring; dy <= ring; ++dy) {
            // Only the ring's shell: all of x unless y or z is on it, else its two ends.
            const bool shell = std::max(std::abs(dy), std::abs(dz)) == ring;
            for (int dx = -ring; dx <= ring; dx += shell || ring == 0 ? 1 : 2 * ring) {
              uint64_t packed = 0;
              if (!pack(c + Eigen::Vector3i(dx, dy, dz), &packed)) continue;
              const Slot* slot = find(packed);
              if (slot == nullptr) continue;
              for (uint32_t k = slot->begin; k < slot->end; ++k) {
                const uint32_t i = sorted[k].second;
                const float d = (positions[kept[i]] - p).squaredNorm();
                if (d < best || (d == best && i < best_index)) {
                  best = d;
                  best_index = i;
                }
              }
            }
          }
        }
        // Every cell of the next ring is at least `ring * cell` away.
        if (best <= (ring * cell) * (ring * cell)) break;
      }
      nearest[v] = best_index;
    }
  });
  return nearest;
}

}  // namespace

void DecimateForBrowser(View3dModel& m, const View3dLimits& limits) {
  m.original_vertices = std::max(m.original_vertices, m.positions.size());
  m.original_faces = std::max(m.original_faces, m.faces.size());
  if (m.faces.empty()) {
    if (m.positions.size() <= limits.max_points || limits.max_points == 0) return;
    const size_t step = (m.positions.size() + limits.max_points - 1) / limits.max_points;
    std::vector<uint32_t> keep;
    for (size_t i = 0; i < m.positions.size(); i += step) keep.push_back(static_cast<uint32_t>(i));
    KeepVertices(m, keep);
    return;
  }
  const bool simplify = m.faces.size() > limits.max_faces && limits.max_faces > 0;
  if (simplify) {
    // Vertex clustering (meshopt_simplifySloppy): even triangles everywhere, where an
    // edge-collapse simplifier leaves long slivers across flat regions along which a few
    // vertices' errors would be interpolated (streaks).
    const size_t index_count = 3 * m.faces.size();
    std::vector<unsigned int> simplified(index_count);
    const auto* indices = reinterpret_cast<const unsigned int*>(m.faces.data());
    const auto* vertices = reinterpret_cast<const float*>(m.positions.data());
    const size_t count = meshopt_simplifySloppy(simplified.data(), indices, index_count, vertices,
                                                m.positions.size(), sizeof(Eigen::Vector3f),
                                                3 * limits.max_faces, 1.f, nullptr);
    m.faces.resize(count / 3);
    std::memcpy(m.faces.data(), simplified.data(), count * sizeof(unsigned int));
  }
  // Drop vertices no face uses (simplified away, or never used).
  std::vector<uint8_t> used(m.positions.size(), 0);
  for (const auto& face : m.faces) {
    for (uint32_t index : face) used[index] = 1;
  }
  std::vector<uint32_t> keep;
  for (size_t i = 0; i < used.size(); ++i) {
    if (used[i]) keep.push_back(static_cast<uint32_t>(i));
  }
  if (simplify && !keep.empty() && !m.error.empty()) {
    // A kept vertex stands for the original vertices nearest to it: it shows their mean error
    // (finite ones; NaN when none was seen), not its own single sample.
    const std::vector<uint32_t> nearest = NearestKept(m.positions, keep);
    std::vector<double> sum(keep.size(), 0.0);
    std::vector<uint32_t> count(keep.size(), 0), members(keep.size(), 0), hole(keep.size(), 0);
    for (size_t v = 0; v < m.positions.size(); ++v) {
      ++members[nearest[v]];
      if (std::isfinite(m.error[v])) {
        sum[nearest[v]] += m.error[v];
        ++count[nearest[v]];
      }
      if (!m.unseen.empty()) hole[nearest[v]] += m.unseen[v];
    }
    for (size_t i = 0; i < keep.size(); ++i) {
      m.error[keep[i]] = count[i] > 0 ? static_cast<float>(sum[i] / count[i]) : NAN;
      // Unseen (suggest): when most of the vertices it stands for are.
      if (!m.unseen.empty()) m.unseen[keep[i]] = 2 * hole[i] > members[i] ? 1 : 0;
    }
  }
  if (keep.size() != m.positions.size()) KeepVertices(m, keep);
}

namespace {

// One projected PLY of a run as a model of the view (see LoadRunView3d).
View3dModel LoadProjected(const run::RunData& run, const fs::path& ply, const std::string& metric,
                          int thumbnail_width, const View3dLimits& limits, bool model_colours) {
  View3dModel model;
  model.label = run.dir.filename().empty() ? run.dir.parent_path().filename().string()
                                           : run.dir.filename().string();
  model.metric = metric;
  // The cameras do not depend on the mesh: the photos' thumbnails (decoding full-size images)
  // are made while the PLY files are read and decimated (serial work), on separate fields.
  AddRunCameras(run, model);
  ParallelInvoke(
      [&] {
        const mesh::Mesh projected = mesh::ReadMesh(ply);
        model.positions = projected.positions;
        model.faces = projected.faces;
        for (const mesh::VertexScalar& scalar : projected.scalars) {
          if (scalar.name == "error") model.error = scalar.values;
        }
        REPHOTO_CHECK(!model.error.empty(), "{}: no vertex property 'error'", ply.string());
        if (!ReadColourRange(ply, &model.low, &model.high)) {
          std::vector<double> finite;
          for (float e : model.error) {
            if (std::isfinite(e)) finite.push_back(e);
          }
          if (!finite.empty()) {
            model.low = static_cast<float>(Quantile(finite, 0.025));
            model.high = static_cast<float>(Quantile(finite, 0.975));
            const auto parsed = metrics::ParseMetric(metric);
            if (parsed && metrics::HigherIsBetter(*parsed)) std::swap(model.low, model.high);
          }
        }
        if (model_colours) {
          AddModelColours(run, projected, model);
        } else {
          model.note = "model colours: not shown for per-fold models";
        }
        DecimateForBrowser(model, limits);
      },
      [&] { AddImages(run, metric, thumbnail_width, model); });
  return model;
}

}  // namespace

std::optional<View3dModel> LoadRunView3d(const run::RunData& run, const std::string& metric,
                                         int thumbnail_width, const View3dLimits& limits) {
  const fs::path ply = run.dir / "projected" / (metric + ".ply");
  std::error_code ec;
  if (!fs::is_regular_file(ply, ec)) return std::nullopt;
  return LoadProjected(run, ply, metric, thumbnail_width, limits, /*model_colours=*/true);
}

std::vector<View3dModel> LoadRunView3dModels(const run::RunData& run, const std::string& metric,
                                             int thumbnail_width, const View3dLimits& limits) {
  std::vector<View3dModel> models;
  if (std::optional<View3dModel> one = LoadRunView3d(run, metric, thumbnail_width, limits)) {
    models.push_back(std::move(*one));
    return models;
  }
  std::vector<fs::path> folds;
  std::error_code ec;
  const std::string suffix = "." + metric + ".ply";
  for (fs::directory_iterator it(run.dir / "projected", ec), end; !ec && it != end;
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("fold_", 0) == 0 && name.size() > suffix.size() &&
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
      folds.push_back(it->path());
    }
  }
  std::sort(folds.begin(), folds.end());
  for (const fs::path& ply : folds) {
    View3dModel model =
        LoadProjected(run, ply, metric, thumbnail_width, limits, /*model_colours=*/false);
    const std::string name = ply.filename().string();
    model.label = name.substr(0, name.size() - suffix.size());
    models.push_back(std::move(model));
  }
  return models;
}

std::vector<View3dCamera> LoadSuggestedCameras(const fs::path& dir) {
  const fs::path file = dir / "suggestions.json";
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return {};
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(ReadFileToString(file));
  } catch (const nlohmann::json::exception& e) {
    throw Error(fmt::format("{}: not valid JSON: {}", file.string(), e.what()));
  }
  REPHOTO_CHECK(json.is_object() && json.contains("suggestions") && json["suggestions"].is_array(),
                "{}: expected an object with a \"suggestions\" list", file.string());
  const scene::ColmapModel colmap = scene::ReadColmapModel(dir / "sparse");
  std::map<std::string, const scene::ColmapImage*> images;
  for (const scene::ColmapImage& image : colmap.images) images[image.name] = &image;
  const double unobserved = json.value("unobserved_area", 0.0);
  std::vector<View3dCamera> cameras;
  for (const auto& s : json["suggestions"]) {
    REPHOTO_CHECK(s.is_object() && s.value("name", nlohmann::json()).is_string(),
                  "{}: a suggestion without a name", file.string());
    const std::string name = s["name"].get<std::string>();
    const auto it = images.find(name);
    REPHOTO_CHECK(it != images.end(), "{}: suggestion \"{}\" is not in {}", file.string(), name,
                  (dir / "sparse").string());
    const scene::ColmapImage& image = *it->second;
    View3dCamera c = CameraOfColmapImage(colmap, image, name, "suggested");
    const double area = s.value("unobserved_area", NAN);
    if (std::isfinite(area) && unobserved > 0) {
      c.note = fmt::format("sees {:.1f} % of the surface no photo sees", 100 * area / unobserved);
    }
    const auto mean_error = s.value("mean_error", nlohmann::json());
    if (mean_error.is_number()) c.error = mean_error.get<double>();
    cameras.push_back(std::move(c));
  }
  return cameras;
}

std::string View3dHtml(const View3dData& data, const std::string& id) {
  REPHOTO_CHECK(!id.empty() && std::all_of(id.begin(), id.end(),
                                           [](char c) {
                                             return std::isalnum(static_cast<unsigned char>(c)) ||
                                                    c == '-' || c == '_';
                                           }),
                "3D view: invalid element id '{}'", id);
  REPHOTO_CHECK(!data.models.empty(), "3D view '{}': no model", id);
  Json j;
  REPHOTO_CHECK(data.mode == "error" || data.mode == "model" || data.mode == "unseen",
                "3D view '{}': unknown colour mode '{}'", id, data.mode);
  j["title"] = data.title;
  j["mode"] = data.mode;
  Json models = Json::array();
  ImageTable table;
  for (size_t k = 0; k < data.models.size(); ++k) {
    models.push_back(ModelJson(data.models, k, table));
  }
  j["models"] = models;
  Json suggested = Json::array();
  for (const View3dCamera& c : data.suggested) suggested.push_back(CameraJson(c, table));
  j["suggested"] = suggested;
  j["images"] = table.images;
  // JSON inside <script>: "</" must not appear (it could close the element); "<\/" is the
  // same JSON string.
  std::string text = j.dump(-1, ' ', false, Json::error_handler_t::replace);
  for (size_t p = text.find("</"); p != std::string::npos; p = text.find("</", p + 3)) {
    text.replace(p, 2, "<\\/");
  }
  return fmt::format(
      "<div class=\"view3d\" id=\"{0}\">"
      "<div class=\"v3-bar\">"
      "<label class=\"v3-model-label\">model <select class=\"v3-model\"></select></label>"
      "<span class=\"v3-modes\" role=\"group\" aria-label=\"colour\">"
      "<button type=\"button\" data-mode=\"error\" aria-pressed=\"true\">error</button>"
      "<button type=\"button\" data-mode=\"model\">model colour</button>"
      "<button type=\"button\" data-mode=\"unseen\">seen by no photo</button></span>"
      "<label>cameras <select class=\"v3-fold\"></select></label>"
      "<span class=\"v3-legend\"></span></div>"
      "<div class=\"v3-main\"><div class=\"v3-canvas\"></div><div class=\"v3-info\" "
      "aria-live=\"polite\"><p class=\"muted\">Drag to orbit, wheel to zoom, right-drag to pan. "
      "Click a camera for its photo, rephoto and error image, or the surface for the views "
      "that see it.</p></div></div>"
      "<div class=\"v3-colorbar\"></div><p class=\"v3-note muted\"></p>"
      "<noscript><p>The 3D view needs JavaScript and WebGL.</p></noscript>"
      "<script type=\"application/json\" class=\"v3-data\">{1}</script></div>\n",
      id, text);
}

std::string View3dScripts() {
  static const char* kCss = R"css(
.view3d { border: 1px solid var(--line, #d8d8dc); padding: 8px; margin: 8px 0 16px; background: #fafafa; }
.view3d .v3-bar { display: flex; flex-wrap: wrap; gap: 12px; align-items: center; margin-bottom: 6px; }
.view3d .v3-modes button { font: inherit; padding: 2px 8px; border: 1px solid #bbb; background: #fff; cursor: pointer; }
.view3d .v3-modes button[aria-pressed="true"] { background: #1d1d1f; color: #fff; border-color: #1d1d1f; }
.view3d .v3-main { display: flex; gap: 10px; align-items: stretch; }
.view3d .v3-canvas { flex: 1 1 auto; min-width: 0; height: 520px; position: relative; background: #fff; border: 1px solid #ddd; }
.view3d .v3-canvas canvas { display: block; width: 100%; height: 100%; }
.view3d .v3-info { flex: 0 0 300px; max-height: 520px; overflow-y: auto; font-size: 13px; }
.view3d .v3-info img { width: 100%; height: auto; display: block; margin: 2px 0 6px; border: 1px solid #ddd; }
.view3d .v3-info table { font-size: 12px; }
.view3d .v3-colorbar { display: flex; align-items: center; gap: 8px; font-size: 12px; margin-top: 6px; }
.view3d .v3-colorbar .bar { width: 260px; height: 12px; border: 1px solid #888; }
.view3d .v3-legend span { display: inline-block; margin-right: 10px; font-size: 12px; }
.view3d .v3-legend i { display: inline-block; width: 10px; height: 10px; margin-right: 3px; vertical-align: middle; }
@media (max-width: 900px) { .view3d .v3-main { flex-direction: column; } .view3d .v3-info { flex-basis: auto; } }
)css";
  return fmt::format(
      "<style>{}</style>\n<script>/* three.js r111, MIT licence, (c) 2010-2019 three.js authors "
      "(Debian libjs-three) */\n{}</script>\n<script>{}</script>\n<script>{}</script>\n",
      kCss, internal::kThreeJs, internal::kOrbitControlsJs, internal::kView3dJs);
}

}  // namespace rephoto::report
