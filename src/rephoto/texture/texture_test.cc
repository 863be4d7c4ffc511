// TextureMesh on a scene with known ground truth (issue 22's acceptance): the demo scene's
// finely coloured mesh photographed by rephoto at known cameras, a coarse version of it
// (97 % of the faces removed by meshoptimizer, as the demo's "simplified" model), textured from
// the training photos only and rendered at held-out cameras. Its 1-NCC (rephoto's metric, as
// `rephoto compare` computes it) must be at most half that of the same coarse mesh coloured
// by render::ColorizeMesh from the same photos, and >= 99 % of the faces the held-out views
// see must be textured from a photo.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <numeric>

#include "rephoto/core/file.h"
#include "rephoto/degrade/degrade.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/obj.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/metrics/validity.h"
#include "rephoto/render/colorize.h"
#include "rephoto/render/render.h"
#include "rephoto/synth/demo_scene.h"
#include "rephoto/testing/testing.h"
#include "rephoto/texture/texture_mesh.h"
#include "rephoto/texture/view_selection.h"

namespace rephoto::texture {
namespace {

Image Rgb(const Image& rgba) {
  Image rgb(rgba.width(), rgba.height(), 3);
  for (size_t p = 0; p < rgb.pixel_count(); ++p) {
    for (int c = 0; c < 3; ++c) rgb.data()[3 * p + c] = rgba.data()[4 * p + c];
  }
  return rgb;
}

struct Fixture {
  std::filesystem::path dir;
  scene::Scene scene;
  std::vector<Image> photos;
  mesh::Mesh truth;
  mesh::Mesh coarse;
  std::vector<size_t> train, test;
};

// 12 photos of 400x300 around the demo object; every third one is held out.
const Fixture& GetFixture() {
  static const Fixture* fixture = [] {
    auto* f = new Fixture;
    f->dir = testing::MakeTempDir();
    synth::DemoSceneOptions options;
    options.image_width = 400;
    options.image_height = 300;
    options.camera_count = 12;
    options.ground_cells = 200;
    options.object_bands = 120;
    f->truth = synth::MakeDemoMesh(options);
    const mesh::Mesh& truth = f->truth;
    f->scene = synth::MakeDemoScene(options, f->dir / "images");
    const render::RenderModel model(truth);
    render::RenderOptions fine;
    fine.samples_per_pixel = 16;
    for (size_t i = 0; i < f->scene.views.size(); ++i) {
      const scene::View& view = f->scene.views[i];
      const render::Rephoto clean =
          render::RenderRephoto(model, f->scene.CameraOf(view), view.cam_from_world, fine);
      const double gain = 1.0 + 0.06 * ((i % 3) - 1.0);  // exposure differences
      f->photos.push_back(synth::SimulatePhoto(clean.color, gain, 0.01, 500 + i));
      io::WritePng(view.image_path, f->photos.back());
      (i % 3 == 1 ? f->test : f->train).push_back(i);
    }
    degrade::DegradeOptions simplify;
    simplify.simplify = 0.97f;
    f->coarse = degrade::Degrade(truth, simplify);
    f->coarse.colors.clear();
    return f;
  }();
  return *fixture;
}

// Mean over the held-out views of each view's masked mean 1-NCC.
double HeldOutOneMinusNcc(const mesh::Mesh& model_mesh, const Fixture& f) {
  const render::RenderModel model(model_mesh);
  double sum = 0;
  for (size_t i : f.test) {
    const scene::View& view = f.scene.views[i];
    const render::Rephoto r =
        render::RenderRephoto(model, f.scene.CameraOf(view), view.cam_from_world);
    const Mask valid = metrics::CombineMasks(metrics::PhotoValidity(f.photos[i], {}),
                                             metrics::RephotoValidity(r.color));
    const auto result =
        metrics::ComputeMetric(metrics::Metric::kOneMinusNcc, f.photos[i], Rgb(r.color), valid);
    EXPECT_GT(result.evaluated, 1000u);
    sum += result.mean;
  }
  return sum / static_cast<double>(f.test.size());
}

// Textures `coarse` from the training photos and checks the acceptance criteria.
void ExpectHalfTheErrorOfVertexColours(const mesh::Mesh& coarse) {
  const Fixture& f = GetFixture();
  const TexturedMesh textured = TextureMesh(coarse, f.scene, f.train);
  const std::filesystem::path obj = f.dir / "out" / "textured.obj";
  WriteTexturedObj(obj, textured);
  const mesh::Mesh read = mesh::ReadObj(obj);
  ASSERT_TRUE(read.is_textured());
  const double textured_error = HeldOutOneMinusNcc(read, f);
  const double colorized_error =
      HeldOutOneMinusNcc(render::ColorizeMesh(coarse, f.scene, f.train), f);
  std::printf("held-out 1-NCC: textured %.4f, vertex colours %.4f (%zu faces, %zu patches)\n",
              textured_error, colorized_error, textured.report.faces, textured.report.patches);
  EXPECT_LE(textured_error, 0.5 * colorized_error);

  // Faces the held-out photos see (the candidate test of view_selection.h), and how many of
  // them got texels from a training photo.
  mesh::Mesh geometry;
  geometry.positions = coarse.positions;
  geometry.faces = coarse.faces;
  const render::RenderModel model(std::move(geometry));
  CandidateOptions whole;
  whole.partial_min_fraction = 0;  // faces a held-out photo sees whole
  const Candidates seen = ComputeCandidates(model, f.scene, f.test, whole);
  size_t visible = 0, textured_visible = 0;
  for (size_t face = 0; face < seen.face_count(); ++face) {
    if (seen.offsets[face] == seen.offsets[face + 1]) continue;
    ++visible;
    textured_visible += textured.face_views[face] >= 0;
  }
  std::printf("held-out views see %zu faces, %zu of them textured\n", visible, textured_visible);
  EXPECT_GE(static_cast<double>(textured_visible), 0.99 * static_cast<double>(visible));
  const TextureReport& r = textured.report;
  EXPECT_EQ(r.textured_faces + r.filled_faces + r.default_faces, r.faces);
  EXPECT_LE(r.views_used, f.train.size());
  EXPECT_LE(r.mrf_energy, r.mrf_initial_energy);
}

TEST(TextureMesh, HalvesTheErrorOfVertexColoursAtHeldOutViews) {
  ExpectHalfTheErrorOfVertexColours(GetFixture().coarse);
}

TEST(TextureMesh, HalvesTheErrorWhenTheGroundIsTwoTriangles) {
  // With 90 % of the faces removed meshoptimizer keeps more of the object and makes the flat
  // ground two triangles that no photo sees whole and that the object hides in part in every
  // photo: they are textured from partial views, their hidden texels from other photos.
  degrade::DegradeOptions simplify;
  simplify.simplify = 0.9f;
  mesh::Mesh coarse = degrade::Degrade(GetFixture().truth, simplify);
  coarse.colors.clear();
  ExpectHalfTheErrorOfVertexColours(coarse);
}

TEST(TextureMesh, WritersRoundTrip) {
  const Fixture& f = GetFixture();
  TextureOptions options;
  options.texel_scale = 0.5;
  options.max_atlas_size = 256;  // forces several atlases
  const TexturedMesh textured = TextureMesh(f.coarse, f.scene, f.train, options);
  ASSERT_GE(textured.atlases.size(), 2u);
  const std::filesystem::path folder = f.dir / "writers";
  WriteTexturedObj(folder / "m.obj", textured);
  WriteTexturedPly(folder / "m.ply", textured);
  WriteTextureReport(folder / "m.json", textured.report);
  const mesh::Mesh obj = mesh::ReadObj(folder / "m.obj");
  const mesh::Mesh ply = mesh::ReadPly(folder / "m.ply");
  // The OBJ groups faces by atlas (stable within each); the PLY keeps the face order.
  std::vector<size_t> obj_order(textured.mesh.faces.size());
  std::iota(obj_order.begin(), obj_order.end(), size_t{0});
  std::stable_sort(obj_order.begin(), obj_order.end(), [&](size_t a, size_t b) {
    return textured.mesh.face_materials[a] < textured.mesh.face_materials[b];
  });
  std::vector<size_t> ply_order(obj_order.size());
  std::iota(ply_order.begin(), ply_order.end(), size_t{0});
  for (const auto& [m, order] : {std::pair{&obj, &obj_order}, std::pair{&ply, &ply_order}}) {
    ASSERT_EQ(m->faces.size(), textured.mesh.faces.size());
    ASSERT_EQ(m->wedge_texcoords.size(), 3 * m->faces.size());
    ASSERT_EQ(m->materials.size(), textured.atlases.size());
    for (size_t i = 0; i < m->materials.size(); ++i) {
      EXPECT_EQ(m->materials[i].diffuse_texture.filename(),
                "m_atlas_" + std::to_string(i) + ".png");
      EXPECT_TRUE(std::filesystem::exists(m->materials[i].diffuse_texture));
    }
    for (size_t face = 0; face < m->faces.size(); ++face) {
      const size_t source = (*order)[face];
      ASSERT_EQ(m->faces[face], textured.mesh.faces[source]);
      EXPECT_EQ(m->FaceMaterial(face), textured.mesh.face_materials[source]);
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2f t = m->wedge_texcoords[3 * face + k];
        const Eigen::Vector2f expected = textured.mesh.wedge_texcoords[3 * source + k];
        EXPECT_TRUE(t.x() >= 0 && t.x() <= 1 && t.y() >= 0 && t.y() <= 1) << face;
        EXPECT_NEAR(t.x(), expected.x(), 1e-6);
        EXPECT_NEAR(t.y(), expected.y(), 1e-6);
      }
    }
  }
  const auto json = nlohmann::json::parse(ReadFileToString(folder / "m.json"));
  EXPECT_EQ(json["schema"], "rephoto.texture/1");
  EXPECT_EQ(json["faces"], textured.mesh.faces.size());
  EXPECT_EQ(json["atlases"], textured.atlases.size());
  EXPECT_TRUE(json["seconds"].contains("selection"));
  // Only the named files: no temporary left behind.
  size_t files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    (void)entry;
    ++files;
  }
  EXPECT_EQ(files, 3 + 1 + textured.atlases.size());  // obj, mtl, ply, json + atlases
}

TEST(TextureMesh, UnseenFacesAreFilledAndCounted) {
  // Two views of one side only: the faces they miss are filled from textured neighbours.
  const Fixture& f = GetFixture();
  const TexturedMesh textured = TextureMesh(f.coarse, f.scene, {0, 2});
  const TextureReport& r = textured.report;
  EXPECT_GT(r.filled_faces, 0u);
  EXPECT_EQ(r.textured_faces + r.filled_faces + r.default_faces, r.faces);
  size_t unseen = 0;
  for (int v : textured.face_views) unseen += v < 0;
  EXPECT_EQ(unseen, r.filled_faces + r.default_faces);
}

TEST(TextureMesh, PhotoConsistencyDropsTheOddColour) {
  // Four views agree on a grey, one sees red (an occluder): the red one is dropped.
  Candidates c;
  c.offsets = {0, 5};
  for (int v = 0; v < 5; ++v) {
    FaceCandidate item;
    item.view = static_cast<uint32_t>(v);
    item.quality = 1;
    item.color = v == 3 ? Eigen::Vector3f(0.9f, 0.1f, 0.1f)
                        : Eigen::Vector3f::Constant(0.5f + 0.01f * static_cast<float>(v));
    c.items.push_back(item);
  }
  EXPECT_EQ(RemoveInconsistentCandidates(&c, {}), 1u);
  ASSERT_EQ(c.items.size(), 4u);
  for (const FaceCandidate& item : c.items) EXPECT_NE(item.view, 3u);
}

TEST(TextureMesh, RefusesBadInput) {
  const Fixture& f = GetFixture();
  EXPECT_NE(testing::ErrorOf([&] { TextureMesh(f.coarse, f.scene, {99}); }).find("out of range"),
            std::string::npos);
  mesh::Mesh points;
  points.positions = {Eigen::Vector3f::Zero()};
  EXPECT_NE(testing::ErrorOf([&] { TextureMesh(points, f.scene, {0}); }).find("no faces"),
            std::string::npos);
  TextureOptions bad;
  bad.texel_scale = 2;
  EXPECT_NE(testing::ErrorOf([&] { TextureMesh(f.coarse, f.scene, {0}, bad); }).find("texel scale"),
            std::string::npos);
}

}  // namespace
}  // namespace rephoto::texture
