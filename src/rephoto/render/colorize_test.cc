#include "rephoto/render/colorize.h"

#include <gmock/gmock.h>

#include <chrono>
#include <cmath>
#include <numeric>

#include "rephoto/core/error.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/render/render.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/testing/testing.h"

namespace rephoto::render {
namespace {

// The colour painted on the world plane z = 2 at (x, y): linear, so bilinear sampling of a
// pinhole photo of it is exact up to 8-bit quantization.
Eigen::Vector3f PlaneColor(double x, double y) {
  return Eigen::Vector3f(static_cast<float>(0.5 + 0.2 * x), static_cast<float>(0.5 + 0.2 * y),
                         0.3f);
}

constexpr double kFocal = 100.0;

camera::Camera SmallCamera() {
  camera::Camera camera;
  camera.model = camera::CameraModel::kPinhole;
  camera.width = 160;
  camera.height = 120;
  camera.params = {kFocal, kFocal, 80.0, 60.0};
  return camera;
}

// A photo from a camera at `center` (no rotation) of the plane z = 2, or of a constant colour.
Image PhotoOfPlane(const Eigen::Vector3d& center, const Eigen::Vector3f* constant) {
  const camera::Camera camera = SmallCamera();
  Image photo(camera.width, camera.height, 3);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const double xn = (x + 0.5 - 80.0) / kFocal, yn = (y + 0.5 - 60.0) / kFocal;
      const double t = 2.0 - center.z();
      const Eigen::Vector3f c =
          constant ? *constant : PlaneColor(center.x() + t * xn, center.y() + t * yn);
      for (int k = 0; k < 3; ++k) photo.at(x, y, k) = c[k];
    }
  }
  return photo;
}

// A 21 x 21 vertex grid on z = 2 over [-0.5, 0.5]^2, normals towards the cameras (-z).
mesh::Mesh PlaneGrid() {
  mesh::Mesh mesh;
  const int n = 21;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      mesh.positions.emplace_back(-0.5f + i / 20.0f, -0.5f + j / 20.0f, 2.0f);
    }
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const uint32_t a = j * n + i;
      // (p1 - p0) x (p2 - p0) = -z: front side towards the cameras.
      mesh.faces.push_back({a, a + n, a + 1});
      mesh.faces.push_back({a + 1, a + n, a + n + 1});
    }
  }
  return mesh;
}

scene::Scene ThreeViewScene(const std::filesystem::path& dir) {
  scene::Scene scene;
  scene.cameras[1] = SmallCamera();
  const Eigen::Vector3d centers[3] = {{0.0, 0.0, 0.0}, {0.1, -0.05, 0.2}, {-0.1, 0.1, -0.6}};
  const Eigen::Vector3f magenta(1, 0, 1);
  for (int k = 0; k < 3; ++k) {
    scene::View view;
    view.name = fmt::format("view{}.png", k);
    view.image_path = dir / view.name;
    view.camera_id = 1;
    view.cam_from_world.translation = -centers[k];  // identity rotation
    // View 2 (the farthest, least weight) shows a wrong colour everywhere: an outlier.
    io::WritePng(view.image_path, PhotoOfPlane(centers[k], k == 2 ? &magenta : nullptr));
    scene.views.push_back(view);
  }
  return scene;
}

TEST(ColorizeTest, RecoversPlaneColoursRobustly) {
  const auto dir = testing::MakeTempDir();
  const scene::Scene scene = ThreeViewScene(dir);
  const mesh::Mesh mesh = PlaneGrid();
  ColorizeReport report;
  const mesh::Mesh colored = ColorizeMesh(mesh, scene, {0, 1, 2}, {}, &report);
  ASSERT_EQ(colored.colors.size(), mesh.positions.size());
  EXPECT_EQ(report.colored_vertices, mesh.positions.size());
  ASSERT_EQ(colored.scalars.back().name, "view_count");
  float worst = 0;
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const Eigen::Vector3f expected = PlaneColor(mesh.positions[i].x(), mesh.positions[i].y());
    worst = std::max(worst, (colored.colors[i] - expected).cwiseAbs().maxCoeff());
    EXPECT_EQ(colored.scalars.back().values[i], 3.0f);
  }
  EXPECT_LT(worst, 0.01f);  // the magenta view is rejected; 8-bit photos

  // Only the outlier and one good view: the weighted median follows the closer good view.
  const mesh::Mesh two = ColorizeMesh(mesh, scene, {0, 2}, {});
  EXPECT_LT((two.colors[220] - PlaneColor(0, 0)).cwiseAbs().maxCoeff(), 0.003f);
}

TEST(ColorizeTest, OcclusionAndFacing) {
  const auto dir = testing::MakeTempDir();
  const scene::Scene scene = ThreeViewScene(dir);
  mesh::Mesh mesh = PlaneGrid();
  // A small occluder at z = 1 in front of the plane's centre, seen from view 0 at the origin:
  // it hides the plane points with |x|, |y| < 0.2 (twice its half size 0.1).
  const uint32_t base = static_cast<uint32_t>(mesh.positions.size());
  mesh.positions.insert(mesh.positions.end(),
                        {Eigen::Vector3f(-0.1f, -0.1f, 1), Eigen::Vector3f(0.1f, -0.1f, 1),
                         Eigen::Vector3f(0.1f, 0.1f, 1), Eigen::Vector3f(-0.1f, 0.1f, 1)});
  mesh.faces.push_back({base, base + 3, base + 1});
  mesh.faces.push_back({base + 1, base + 3, base + 2});
  const mesh::Mesh colored = ColorizeMesh(mesh, scene, {0}, {});
  const auto& counts = colored.scalars.back().values;
  int hidden = 0;
  for (size_t i = 0; i < base; ++i) {
    const Eigen::Vector3f& p = mesh.positions[i];
    const bool behind = std::abs(p.x()) < 0.19f && std::abs(p.y()) < 0.19f;
    const bool clear = std::abs(p.x()) > 0.21f || std::abs(p.y()) > 0.21f;
    if (behind) {
      EXPECT_EQ(counts[i], 0.0f) << i;
      EXPECT_EQ(colored.colors[i], Eigen::Vector3f::Zero());
      ++hidden;
    } else if (clear) {
      EXPECT_EQ(counts[i], 1.0f) << i;
    }
  }
  EXPECT_EQ(hidden, 49);          // 7 x 7 grid points with |x|, |y| <= 0.15
  EXPECT_EQ(counts[base], 1.0f);  // the occluder itself is seen

  // Normals pointing away from every camera: nothing faces them.
  mesh::Mesh away = PlaneGrid();
  away.normals.assign(away.positions.size(), Eigen::Vector3f(0, 0, 1));
  ColorizeReport report;
  ColorizeMesh(away, scene, {0, 1, 2}, {}, &report);
  EXPECT_EQ(report.colored_vertices, 0u);
  EXPECT_THROW(ColorizeMesh(mesh, scene, {7}, {}), Error);
}

// Downscales by an integer factor with a box filter (area average).
TEST(ColorizeTest, SharedModelColoursRenderAsVertexColours) {
  // One BVH for colouring and rendering: the colours match ColorizeMesh's exactly, and the
  // plain model renders them once SetVertexColors gave them to it.
  const auto dir = testing::MakeTempDir();
  const scene::Scene scene = ThreeViewScene(dir);
  const mesh::Mesh mesh = PlaneGrid();
  const mesh::Mesh expected = ColorizeMesh(mesh, scene, {0, 1, 2}, {});
  RenderModel model(mesh);
  EXPECT_EQ(model.representation(), Representation::kPlainMesh);
  ColorizeReport report;
  VertexColors colors = ColorizeVertices(model, scene, {0, 1, 2}, {}, &report);
  EXPECT_EQ(report.colored_vertices, mesh.positions.size());
  ASSERT_EQ(colors.colors.size(), expected.colors.size());
  for (size_t i = 0; i < colors.colors.size(); ++i) {
    EXPECT_EQ(colors.colors[i], expected.colors[i]) << i;
    EXPECT_EQ(colors.view_count.values[i], expected.scalars.back().values[i]) << i;
  }
  EXPECT_EQ(colors.view_count.name, "view_count");
  model.SetVertexColors(colors.colors);
  model.SetVertexScalar(colors.view_count);
  model.SetVertexScalar(colors.view_count);  // replaces, does not add
  EXPECT_EQ(model.representation(), Representation::kVertexColoredMesh);
  EXPECT_EQ(model.mesh().scalars.size(), 1u);
  const Rephoto shot = RenderRephoto(model, scene.CameraOf(scene.views[0]),
                                     scene.views[0].cam_from_world, RenderOptions{});
  const int cx = shot.color.width() / 2, cy = shot.color.height() / 2;
  const Eigen::Vector3f centre(shot.color.at(cx, cy, 0), shot.color.at(cx, cy, 1),
                               shot.color.at(cx, cy, 2));
  EXPECT_LT((centre - PlaneColor(0, 0)).cwiseAbs().maxCoeff(), 0.02f);
  EXPECT_THROW(model.SetVertexColors(std::vector<Eigen::Vector3f>(3)), Error);
  EXPECT_THROW(model.SetVertexScalar({"x", std::vector<float>(3)}), Error);
}

Image BoxDownscale(const Image& image, int factor) {
  Image out(image.width() / factor, image.height() / factor, 3);
  for (int y = 0; y < out.height(); ++y) {
    for (int x = 0; x < out.width(); ++x) {
      for (int c = 0; c < 3; ++c) {
        double sum = 0;
        for (int dy = 0; dy < factor; ++dy) {
          for (int dx = 0; dx < factor; ++dx) sum += image.at(x * factor + dx, y * factor + dy, c);
        }
        out.at(x, y, c) = static_cast<float>(sum / (factor * factor));
      }
    }
  }
  return out;
}

Image Rgb(const Image& rgba) {
  Image out(rgba.width(), rgba.height(), 3);
  for (size_t i = 0; i < rgba.pixel_count(); ++i) {
    for (int c = 0; c < 3; ++c) out.data()[3 * i + c] = rgba.data()[4 * i + c];
  }
  return out;
}

TEST(ColorizeTest, SceauxColouredFromNinePhotosRephotographsTheTenth) {
  REPHOTO_REQUIRE_DATA("openmvs_sceaux");
  const auto dir = testing::SharedDataDir() / "openmvs_sceaux";
  scene::ReadSceneOptions scene_options;
  scene_options.image_root = dir / "images";
  const scene::Scene scene = scene::ReadScene(dir / "colmap_text_derived", scene_options);
  const mesh::Mesh mesh = mesh::ReadPly(dir / "scene_mesh_refine.ply");
  std::vector<size_t> training;
  size_t test_view = scene.views.size();
  for (size_t v = 0; v < scene.views.size(); ++v) {
    if (scene.views[v].name == "00009.jpg") test_view = v;
    if (scene.views[v].name < "00009.jpg") training.push_back(v);
  }
  ASSERT_EQ(training.size(), 9u);
  ASSERT_LT(test_view, scene.views.size());

  auto start = std::chrono::steady_clock::now();
  ColorizeReport report;
  const mesh::Mesh colored = ColorizeMesh(mesh, scene, training, {}, &report);
  const double colorize_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // Rephotograph at a quarter of the photo's resolution (708 x 532) and compare with the
  // photo box-downscaled by 4, where the rephoto fully covers the pixel.
  const scene::View& view = scene.views[test_view];
  const camera::Camera camera = scene.CameraOf(view).Scaled(708, 532);
  const Image photo = BoxDownscale(io::ReadImage(view.image_path), 4);
  ASSERT_EQ(photo.width(), 708);
  auto error_of = [&](const mesh::Mesh& m, Rephoto* out) {
    RenderModel model(m);
    *out = RenderRephoto(model, camera, view.cam_from_world);
    Mask valid(708, 532, 1);
    for (size_t i = 0; i < valid.pixel_count(); ++i) {
      valid.data()[i] = out->color.data()[4 * i + 3] == 1.0f ? 1 : 0;
    }
    return metrics::ComputeMetric(metrics::Metric::kOneMinusNcc, photo, Rgb(out->color), valid);
  };
  Rephoto rephoto, shuffled_rephoto;
  const auto colored_error = error_of(colored, &rephoto);
  mesh::Mesh shuffled = colored;
  std::vector<size_t> order(shuffled.colors.size());
  std::iota(order.begin(), order.end(), 0);
  auto rng = testing::MakeRng();
  std::shuffle(order.begin(), order.end(), rng);
  for (size_t i = 0; i < order.size(); ++i) shuffled.colors[i] = colored.colors[order[i]];
  const auto shuffled_error = error_of(shuffled, &shuffled_rephoto);

  // Completeness against the mesh's silhouette, rasterized independently in 2D: a pixel is
  // inside when its centre lies in some projected triangle (pinhole; all vertices in front).
  RenderOptions one;
  one.samples_per_pixel = 1;
  const Rephoto single = RenderRephoto(RenderModel(mesh), camera, view.cam_from_world, one);
  Mask silhouette(708, 532, 1);
  const double fx = camera.params[0], fy = camera.params[1], cx = camera.params[2],
               cy = camera.params[3];
  for (const mesh::Triangle& t : mesh.faces) {
    Eigen::Vector2d q[3];
    bool in_front = true;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p =
          view.cam_from_world.CamFromWorld(mesh.positions[t[k]].cast<double>());
      in_front &= p.z() > 0;
      q[k] = Eigen::Vector2d(fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy);
    }
    if (!in_front) continue;
    const int x0 =
        std::max(0, static_cast<int>(std::floor(std::min({q[0].x(), q[1].x(), q[2].x()}))));
    const int x1 =
        std::min(707, static_cast<int>(std::ceil(std::max({q[0].x(), q[1].x(), q[2].x()}))));
    const int y0 =
        std::max(0, static_cast<int>(std::floor(std::min({q[0].y(), q[1].y(), q[2].y()}))));
    const int y1 =
        std::min(531, static_cast<int>(std::ceil(std::max({q[0].y(), q[1].y(), q[2].y()}))));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2d c(x + 0.5, y + 0.5);
        double e[3];
        for (int k = 0; k < 3; ++k) {
          const Eigen::Vector2d a = q[k], b = q[(k + 1) % 3];
          e[k] = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
        }
        if ((e[0] >= 0 && e[1] >= 0 && e[2] >= 0) || (e[0] <= 0 && e[1] <= 0 && e[2] <= 0)) {
          silhouette.at(x, y) = 1;
        }
      }
    }
  }
  size_t inside = 0, disagree = 0;
  double coverage = 0;
  for (size_t i = 0; i < silhouette.pixel_count(); ++i) {
    inside += silhouette.data()[i];
    disagree += (single.color.data()[4 * i + 3] > 0) != (silhouette.data()[i] > 0);
    coverage += rephoto.color.data()[4 * i + 3];
  }
  std::printf(
      "sceaux: colorized %zu/%zu vertices (%zu observations) in %.2f s; rephoto of 00009 at "
      "708x532: 1-NCC %.4f (%zu windows) vs shuffled colours %.4f; completeness %.4f, "
      "silhouette %.4f, 1-spp coverage differs from the 2D silhouette at %zu of %zu pixels\n",
      report.colored_vertices, report.vertices, report.observations, colorize_seconds,
      colored_error.mean, colored_error.evaluated, shuffled_error.mean,
      coverage / silhouette.pixel_count(), static_cast<double>(inside) / silhouette.pixel_count(),
      disagree, inside);
  EXPECT_GT(report.colored_vertices, report.vertices * 95 / 100);
  EXPECT_GT(colored_error.evaluated, 100000u);
  EXPECT_LT(colored_error.mean, 0.6 * shuffled_error.mean);
  EXPECT_LT(disagree, inside / 1000 + 10);
}

}  // namespace
}  // namespace rephoto::render
