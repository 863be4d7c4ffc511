// The renderer factory's resolution rules, its errors, and its wiring. The byte comparisons below
// are wiring tests: they check that MakeRenderer builds the renderer the caller would build by
// hand from the same settings (the renderers' own correctness is tested in render/, splat/ and
// ibr/ against independent references).
#include "rephoto/representation/make_renderer.h"

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>

#include "rephoto/core/error.h"
#include "rephoto/ibr/training_views.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/synth/demo_files.h"
#include "rephoto/testing/testing.h"

namespace rephoto::representation {
namespace {

namespace fs = std::filesystem;
using render::ViewRepresentation;

// Same size, channels and bytes (NaN depths compare equal when their bits are).
void ExpectSameBytes(const Image& a, const Image& b, const char* what) {
  ASSERT_EQ(a.width(), b.width()) << what;
  ASSERT_EQ(a.height(), b.height()) << what;
  ASSERT_EQ(a.channels(), b.channels()) << what;
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0) << what;
}

// The same bytes, and some pixels covered (so that two empty images do not pass).
void ExpectSameRephoto(const render::Rephoto& a, const render::Rephoto& b) {
  size_t covered = 0;
  for (int y = 0; y < a.color.height(); ++y) {
    for (int x = 0; x < a.color.width(); ++x) covered += a.color.at(x, y, 3) > 0;
  }
  EXPECT_GT(covered, 0u);
  ExpectSameBytes(a.color, b.color, "color");
  ExpectSameBytes(a.depth, b.depth, "depth");
}

// A small demo scene on disk (photos, COLMAP cameras, the truth mesh), a Gaussian model made
// from the mesh's vertices, and a point cloud.
class MakeRendererTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(rephoto::testing::MakeTempDir());
    synth::DemoSceneOptions options;
    options.image_width = 64;
    options.image_height = 48;
    options.camera_count = 12;  // 30 degrees apart: ibr's plane sweep finds neighbours
    options.ground_cells = 16;
    options.object_bands = 12;
    files_ =
        new synth::DemoSceneFiles(synth::WriteDemoSceneFiles(options, *dir_ / "demo", [](size_t) {
          return synth::PhotoSettings{1, 0, 0};
        }));
    const mesh::Mesh truth = mesh::ReadMesh(files_->truth);
    splat::GaussianModel gaussians;
    for (size_t v = 0; v < truth.positions.size(); v += 3) {
      gaussians.positions.push_back(truth.positions[v]);
      gaussians.scales.push_back(Eigen::Vector3f::Constant(0.05f));
      gaussians.rotations.push_back(Eigen::Vector4f(1, 0, 0, 0));
      gaussians.opacities.push_back(0.8f);
      for (int c = 0; c < 3; ++c) gaussians.sh.push_back(0.1f * static_cast<float>(c));
    }
    splat::WriteInriaPly(*dir_ / "gaussians.ply", gaussians);
    mesh::Mesh cloud;
    cloud.positions = truth.positions;
    cloud.colors = truth.colors;
    mesh::WritePly(*dir_ / "cloud.ply", cloud);
  }
  static void TearDownTestSuite() {
    delete files_;
    delete dir_;
  }

  static const scene::Scene& Scene() { return files_->scene; }
  static fs::path Gaussians() { return *dir_ / "gaussians.ply"; }
  static fs::path Cloud() { return *dir_ / "cloud.ply"; }
  static fs::path Truth() { return files_->truth; }
  // All views but `held_out`.
  static TrainingPhotos AllBut(size_t held_out) {
    TrainingPhotos training{&Scene(), {}, {}};
    for (size_t v = 0; v < Scene().views.size(); ++v) {
      if (v != held_out) training.views.push_back(v);
    }
    return training;
  }
  static render::Rephoto RenderView(render::ViewRenderer& renderer, size_t v) {
    render::Rephoto out;
    const scene::View& view = Scene().views[v];
    renderer.Render(Scene().CameraOf(view), view.cam_from_world, &out);
    return out;
  }

  static inline fs::path* dir_ = nullptr;
  static inline synth::DemoSceneFiles* files_ = nullptr;
};

TEST_F(MakeRendererTest, AutoResolvesGaussianFilesAndKeepsMeshes) {
  EXPECT_EQ(ResolveRepresentation(ViewRepresentation::kAuto, Gaussians()),
            ViewRepresentation::kGaussians);
  EXPECT_EQ(ResolveRepresentation(ViewRepresentation::kAuto, Truth()), ViewRepresentation::kAuto);
  EXPECT_EQ(ResolveRepresentation(ViewRepresentation::kAuto, Cloud()), ViewRepresentation::kAuto);
  EXPECT_EQ(ResolveRepresentation(ViewRepresentation::kAuto, {}), ViewRepresentation::kAuto);
  // A representation asked for is kept, whatever the file holds.
  EXPECT_EQ(ResolveRepresentation(ViewRepresentation::kVdt, Gaussians()), ViewRepresentation::kVdt);
  EXPECT_EQ(ResolveRepresentation(ViewRepresentation::kIbr, Gaussians()), ViewRepresentation::kIbr);
  EXPECT_EQ(ResolveRepresentation(ViewRepresentation::kGaussians, Truth()),
            ViewRepresentation::kGaussians);
}

TEST_F(MakeRendererTest, LoadsWhatTheRepresentationRenders) {
  const RendererSettings settings;
  const Models gaussians = LoadModels(ViewRepresentation::kGaussians, Gaussians(), settings);
  EXPECT_TRUE(gaussians.gaussians && !gaussians.mesh && !gaussians.proxy);
  const Models mesh = LoadModels(ViewRepresentation::kAuto, Truth(), settings);
  ASSERT_TRUE(mesh.mesh && !mesh.gaussians && !mesh.proxy);
  EXPECT_EQ(mesh.mesh->representation(), render::Representation::kVertexColoredMesh);
  const Models cloud = LoadModels(ViewRepresentation::kAuto, Cloud(), settings);
  ASSERT_TRUE(cloud.mesh);
  EXPECT_EQ(cloud.mesh->representation(), render::Representation::kPointCloud);
  const Models proxy = LoadModels(ViewRepresentation::kVdt, Truth(), settings);
  EXPECT_TRUE(proxy.proxy && !proxy.mesh && !proxy.gaussians);
  // ibr needs no model: nothing is read, even when a path is given.
  const Models ibr = LoadModels(ViewRepresentation::kIbr, {}, settings);
  EXPECT_TRUE(!ibr.mesh && !ibr.gaussians && !ibr.proxy);
}

TEST_F(MakeRendererTest, MissingModelsAreErrors) {
  const RendererSettings settings;
  using rephoto::testing::ErrorOf;
  EXPECT_EQ(ErrorOf([&] { LoadModels(ViewRepresentation::kVdt, {}, settings); }),
            "--representation vdt needs a model (the geometry proxy)");
  EXPECT_EQ(ErrorOf([&] { MakeRenderer(ViewRepresentation::kVdt, {}, AllBut(0), settings); }),
            "--representation vdt needs a model (the geometry proxy)");
  EXPECT_EQ(ErrorOf([&] { LoadModels(ViewRepresentation::kAuto, {}, settings); }),
            "--representation auto needs a model (a mesh or point cloud)");
  EXPECT_EQ(ErrorOf([&] { MakeRenderer(ViewRepresentation::kGaussians, {}, {}, settings); }),
            "--representation gaussians needs a model (3D Gaussians)");
  // A Gaussian file left as auto is not rendered as a mesh by mistake.
  const Models gaussians = LoadModels(ViewRepresentation::kGaussians, Gaussians(), settings);
  EXPECT_EQ(ErrorOf([&] { MakeRenderer(ViewRepresentation::kAuto, gaussians, {}, settings); }),
            "--representation auto needs a model (a mesh or point cloud)");
  const Models cloud = LoadModels(ViewRepresentation::kAuto, Cloud(), settings);
  EXPECT_EQ(ErrorOf([&] { MakeRenderer(ViewRepresentation::kVdt, cloud, AllBut(0), settings); }),
            "--representation vdt needs a mesh as geometry proxy (got a point cloud)");
}

TEST(MakeRendererNames, EnumsAreParsedOnceOrRejected) {
  EXPECT_EQ(RepresentationFromName("vdt", "--representation"), ViewRepresentation::kVdt);
  EXPECT_EQ(GaussianModeFromName("antialiased", "--gaussian-mode"),
            splat::GaussianMode::kAntialiased);
  EXPECT_THROW(RepresentationFromName("nerf", "--representation"), UsageError);
  EXPECT_EQ(rephoto::testing::ErrorOf([] { GaussianModeFromName("mip", "--gaussian-mode"); }),
            "--gaussian-mode mip: expected classic or antialiased");
}

TEST_F(MakeRendererTest, MeshRendererIsTheDirectOne) {
  RendererSettings settings;
  settings.render.samples_per_pixel = 3;
  settings.render.backfaces = false;
  const Models models = LoadModels(ViewRepresentation::kAuto, Truth(), settings);
  const auto made = MakeRenderer(ViewRepresentation::kAuto, models, {}, settings);
  render::ModelViewRenderer direct(models.mesh, settings.render);
  ExpectSameRephoto(RenderView(*made, 1), RenderView(direct, 1));
}

TEST_F(MakeRendererTest, GaussianRendererIsTheDirectOne) {
  RendererSettings settings;
  settings.gaussians.mode = splat::GaussianMode::kAntialiased;
  settings.gaussians.background = Eigen::Vector3f(1, 1, 1);
  const Models models = LoadModels(ResolveRepresentation(ViewRepresentation::kAuto, Gaussians()),
                                   Gaussians(), settings);
  const auto made = MakeRenderer(ViewRepresentation::kGaussians, models, {}, settings);
  render::GaussianViewRenderer direct(models.gaussians, settings.gaussians);
  ExpectSameRephoto(RenderView(*made, 2), RenderView(direct, 2));
}

TEST_F(MakeRendererTest, ImageBasedRenderersAreTheDirectOnes) {
  RendererSettings settings;
  settings.image_based.k_best = 2;
  settings.image_based.plane_sweep.num_planes = 16;
  const TrainingPhotos training = AllBut(0);
  ibr::ImageBasedOptions options = settings.image_based;
  options.scene_points = ibr::ScenePoints(Scene());

  const Models proxy = LoadModels(ViewRepresentation::kVdt, Truth(), settings);
  const auto vdt = MakeRenderer(ViewRepresentation::kVdt, proxy, training, settings);
  ibr::ImageBasedViewRenderer direct_vdt(ibr::ImageBasedRenderer::Vdt(
      *proxy.proxy, ibr::TrainingViewsFromScene(Scene(), training.views), options));
  ExpectSameRephoto(RenderView(*vdt, 0), RenderView(direct_vdt, 0));

  // ibr renders without a model (depth maps by plane sweep here).
  const auto ibr = MakeRenderer(ViewRepresentation::kIbr, {}, training, settings);
  ibr::ImageBasedViewRenderer direct_ibr(
      ibr::ImageBasedRenderer::Ibr(ibr::TrainingViewsFromScene(Scene(), training.views), options));
  ExpectSameRephoto(RenderView(*ibr, 0), RenderView(direct_ibr, 0));
}

TEST_F(MakeRendererTest, LeaveOneOutRendersEachViewFromTheOthers) {
  RendererSettings settings;
  const Models proxy = LoadModels(ViewRepresentation::kVdt, Truth(), settings);
  const fs::path out = rephoto::testing::MakeTempDir();
  RenderLeaveOneOut(ViewRepresentation::kVdt, proxy, Scene(), {1, 3}, {"one", "three"}, {},
                    settings, out);
  const auto from_others = MakeRenderer(ViewRepresentation::kVdt, proxy, AllBut(3), settings);
  render::Rephoto expected = RenderView(*from_others, 3);
  fs::create_directories(out / "expected");
  render::WriteRephoto(out / "expected", "three", &expected);
  EXPECT_TRUE(fs::is_regular_file(out / "one.png"));
  EXPECT_EQ(rephoto::testing::ErrorOf([&] {
              RenderLeaveOneOut(ViewRepresentation::kAuto, proxy, Scene(), {1}, {"one"}, {},
                                settings, out);
            }),
            "leave-one-out rendering is for vdt and ibr, not auto");
  for (const char* ext : {".png", ".depth.exr"}) {
    const auto read = [](const fs::path& path) {
      std::ifstream in(path, std::ios::binary);
      return std::string(std::istreambuf_iterator<char>(in), {});
    };
    EXPECT_EQ(read(out / (std::string("three") + ext)),
              read(out / "expected" / (std::string("three") + ext)))
        << ext;
  }
}

}  // namespace
}  // namespace rephoto::representation
