#include "rephoto/texture/texture_mesh.h"

#include <chrono>
#include <cmath>
#include <deque>

#include "rephoto/core/error.h"
#include "rephoto/render/render_model.h"
#include "rephoto/texture/atlas.h"
#include "rephoto/texture/leveling.h"
#include "rephoto/texture/mrf.h"
#include "rephoto/texture/topology.h"
#include "rephoto/texture/view_selection.h"

namespace rephoto::texture {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Colours of the faces without a label: the colour of the labelled face that a breadth-first
// search over face_pairs from all labelled faces (in face order) reaches them from first.
// Returns per face the colour (labelled faces keep `colors`); counts filled and default faces.
std::vector<Eigen::Vector3f> FillUnseen(size_t face_count,
                                        const std::vector<std::pair<uint32_t, uint32_t>>& pairs,
                                        const std::vector<int>& labels,
                                        std::vector<Eigen::Vector3f> colors, size_t* filled,
                                        size_t* defaulted) {
  std::vector<uint32_t> offsets(face_count + 1, 0), neighbours(2 * pairs.size());
  for (const auto& [a, b] : pairs) ++offsets[a + 1], ++offsets[b + 1];
  for (size_t f = 0; f < face_count; ++f) offsets[f + 1] += offsets[f];
  std::vector<uint32_t> fill(offsets.begin(), offsets.end() - 1);
  for (const auto& [a, b] : pairs) neighbours[fill[a]++] = b, neighbours[fill[b]++] = a;
  std::vector<uint8_t> reached(face_count, 0);
  std::deque<uint32_t> queue;
  for (size_t f = 0; f < face_count; ++f) {
    if (labels[f] >= 0) reached[f] = 1, queue.push_back(static_cast<uint32_t>(f));
  }
  *filled = *defaulted = 0;
  while (!queue.empty()) {
    const uint32_t f = queue.front();
    queue.pop_front();
    for (uint32_t i = offsets[f]; i < offsets[f + 1]; ++i) {
      const uint32_t g = neighbours[i];
      if (reached[g]) continue;
      reached[g] = 1;
      colors[g] = colors[f];
      ++*filled;
      queue.push_back(g);
    }
  }
  for (size_t f = 0; f < face_count; ++f) {
    if (!reached[f]) colors[f] = Eigen::Vector3f::Constant(0.5f), ++*defaulted;
  }
  return colors;
}

}  // namespace

void TextureOptions::Check() const {
  REPHOTO_CHECK_USAGE(min_facing_cosine >= -1 && min_facing_cosine < 1,
                      "texture: min facing cosine {} must be in [-1, 1)", min_facing_cosine);
  REPHOTO_CHECK_USAGE(occlusion_epsilon >= 0 && occlusion_epsilon < 1,
                      "texture: occlusion epsilon {} must be in [0, 1)", occlusion_epsilon);
  REPHOTO_CHECK_USAGE(gradient_floor >= 0 && std::isfinite(gradient_floor),
                      "texture: gradient floor {} must be >= 0", gradient_floor);
  REPHOTO_CHECK_USAGE(partial_min_fraction >= 0 && partial_min_fraction <= 1,
                      "texture: partial fraction {} must be in [0, 1]", partial_min_fraction);
  REPHOTO_CHECK_USAGE(consistency_bandwidth > 0 && consistency_min_threshold >= 0,
                      "texture: consistency bandwidth {} must be > 0 and threshold {} >= 0",
                      consistency_bandwidth, consistency_min_threshold);
  REPHOTO_CHECK_USAGE(smoothness >= 0 && std::isfinite(smoothness),
                      "texture: smoothness {} must be >= 0", smoothness);
  REPHOTO_CHECK_USAGE(mrf_cycles >= 0, "texture: MRF cycles {} must be >= 0", mrf_cycles);
  REPHOTO_CHECK_USAGE(leveling_smoothness > 0 && std::isfinite(leveling_smoothness),
                      "texture: leveling smoothness {} must be > 0", leveling_smoothness);
  REPHOTO_CHECK_USAGE(texel_scale > 0 && texel_scale <= 1,
                      "texture: texel scale {} must be in (0, 1]", texel_scale);
  REPHOTO_CHECK_USAGE(max_atlas_size >= 64 && max_atlas_size <= 32768,
                      "texture: atlas size {} must be in [64, 32768]", max_atlas_size);
  REPHOTO_CHECK_USAGE(padding >= 0 && padding <= 64, "texture: padding {} must be in [0, 64]",
                      padding);
}

TexturedMesh TextureMesh(const mesh::Mesh& input, const scene::Scene& scene,
                         const std::vector<size_t>& view_indices, const TextureOptions& options) {
  options.Check();
  input.Validate("mesh");
  REPHOTO_CHECK(!input.faces.empty(), "mesh: no faces (a point cloud cannot be textured)");
  for (size_t v : view_indices) {
    REPHOTO_CHECK(v < scene.views.size(), "texture: view index {} out of range ({} views)", v,
                  scene.views.size());
  }
  const auto start = std::chrono::steady_clock::now();
  TexturedMesh out;
  TextureReport& report = out.report;
  mesh::Mesh& mesh = out.mesh;
  mesh.positions = input.positions;
  mesh.faces = input.faces;
  mesh.normals = input.normals;
  report.vertices = mesh.positions.size();
  report.faces = mesh.faces.size();
  report.views_given = view_indices.size();

  auto stage = std::chrono::steady_clock::now();
  const std::vector<std::pair<uint32_t, uint32_t>> pairs = FacePairs(mesh);
  Candidates candidates;
  mesh::Mesh geometry;
  geometry.positions = mesh.positions;
  geometry.faces = mesh.faces;
  render::ModelOptions model_options;
  model_options.load_textures = false;
  const render::RenderModel model(std::move(geometry), model_options, "mesh");
  {
    CandidateOptions candidate_options;
    candidate_options.min_facing_cosine = options.min_facing_cosine;
    candidate_options.occlusion_epsilon = options.occlusion_epsilon;
    candidate_options.gradient_floor = options.gradient_floor;
    candidate_options.partial_min_fraction = options.partial_min_fraction;
    candidate_options.show_progress = options.show_progress;
    candidates = ComputeCandidates(model, scene, view_indices, candidate_options);
  }
  report.candidates = candidates.items.size();
  report.seconds_visibility = SecondsSince(stage);

  stage = std::chrono::steady_clock::now();
  if (options.photo_consistency) {
    ConsistencyOptions consistency;
    consistency.bandwidth = options.consistency_bandwidth;
    consistency.min_threshold = options.consistency_min_threshold;
    report.inconsistent_candidates = RemoveInconsistentCandidates(&candidates, consistency);
  }
  report.seconds_consistency = SecondsSince(stage);

  stage = std::chrono::steady_clock::now();
  PottsOptions potts_options;
  potts_options.max_cycles = options.mrf_cycles;
  const PottsResult selection =
      SolvePotts(MakeViewSelectionProblem(candidates, pairs, options.smoothness), potts_options);
  const std::vector<int>& labels = selection.labels;
  report.mrf_initial_energy = selection.initial_energy;
  report.mrf_energy = selection.energy;
  report.mrf_moves = selection.moves;
  report.seconds_selection = SecondsSince(stage);

  stage = std::chrono::steady_clock::now();
  const VertexFaces vertex_faces = MakeVertexFaces(mesh);
  ColorAdjustment adjustment;
  if (options.seam_leveling) {
    LevelingOptions leveling;
    leveling.smoothness = options.leveling_smoothness;
    LevelingReport leveling_report;
    adjustment =
        LevelSeams(mesh, vertex_faces, labels, scene, view_indices, leveling, &leveling_report);
    report.seam_vertices = leveling_report.seam_vertices;
    report.leveling_iterations = leveling_report.iterations;
  }
  report.seconds_leveling = SecondsSince(stage);

  stage = std::chrono::steady_clock::now();
  std::vector<Eigen::Vector3f> colors(mesh.faces.size(), Eigen::Vector3f::Zero());
  std::vector<uint8_t> view_used(view_indices.size(), 0);
  std::vector<uint8_t> partial(mesh.faces.size(), 0);
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    if (labels[f] < 0) continue;
    view_used[labels[f]] = 1;
    ++report.textured_faces;
    for (uint32_t k = candidates.offsets[f]; k < candidates.offsets[f + 1]; ++k) {
      if (static_cast<int>(candidates.items[k].view) == labels[f]) {
        colors[f] = candidates.items[k].color;
        partial[f] = candidates.items[k].partial ? 1 : 0;
        report.partial_faces += partial[f];
      }
    }
    for (int k = 0; k < 3; ++k) colors[f] += adjustment.At(mesh.faces[f][k], labels[f]) / 3.0f;
  }
  report.visible_faces = report.textured_faces;
  for (uint8_t used : view_used) report.views_used += used;
  colors = FillUnseen(mesh.faces.size(), pairs, labels, std::move(colors), &report.filled_faces,
                      &report.default_faces);
  AtlasOptions atlas_options;
  atlas_options.texel_scale = options.texel_scale;
  atlas_options.max_atlas_size = options.max_atlas_size;
  atlas_options.padding = options.padding;
  atlas_options.occlusion_epsilon = options.occlusion_epsilon;
  Atlases atlases = BuildAtlases(mesh, pairs, labels, colors, adjustment, model, partial, scene,
                                 view_indices, atlas_options);
  report.reassigned_texels = atlases.reassigned_texels;
  report.patches = atlases.patches;
  report.atlases = atlases.images.size();
  report.atlas_texels = atlases.texels;
  mesh.wedge_texcoords = std::move(atlases.wedge_texcoords);
  mesh.face_materials = std::move(atlases.face_atlas);
  for (size_t i = 0; i < atlases.images.size(); ++i) {
    mesh::Material material;
    material.name = "atlas_" + std::to_string(i);
    mesh.materials.push_back(material);
  }
  out.atlases = std::move(atlases.images);
  out.face_views.resize(mesh.faces.size());
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    out.face_views[f] = labels[f] >= 0 ? static_cast<int>(view_indices[labels[f]]) : -1;
  }
  report.seconds_atlas = SecondsSince(stage);
  report.seconds_total = SecondsSince(start);
  return out;
}

}  // namespace rephoto::texture
