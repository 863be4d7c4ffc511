// TextureMesh end to end.
//
// Against closed forms (TextureMeshClosedForm): a textured plane photographed by pinhole
// cameras whose photos this file computes itself (ray-plane intersections with a known albedo
// and a known exposure gain per photo; not rephoto's renderer). Checked: which faces are
// textured and from which photo, against the visibility rule view_selection.h states applied
// to the corners' projections here; the textured colour at every face (the atlas sampled at the
// OBJ's texture coordinates) against the albedo; and, with photos of different exposure, that
// seam leveling joins the patches (the step across their seams, which is the exposure difference
// with leveling off, nearly vanishes).
//
// Issue 22's acceptance comparison (TextureMesh.HalvesTheError...): the demo scene's finely
// coloured mesh photographed by rephoto's renderer at known cameras, a coarse version of it (97 %
// of the faces removed by meshoptimizer, as the demo's "simplified" model), textured from the
// training photos only and rendered at held-out cameras. Its 1-NCC (as `rephoto compare`
// computes it) must be at most half that of the same coarse mesh coloured by
// render::ColorizeMesh from the same photos. Both sides go through the same renderer and metric:
// a relative comparison of two colouring methods, not a check of absolute values (those are the
// closed-form tests').
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>

#include "rephoto/camera/camera.h"
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

// ---------------------------------------------------------------------------------------------
// The closed-form scene. Its photos are computed here, not rendered by rephoto: the plane z = 0
// coloured by the albedo A(x, y) below, seen by three pinhole cameras whose image planes are
// parallel to it (looking straight down, each turned about its optical axis, at different
// heights); the mesh is the part x in [0, 6], y in [0, 3.5] of the plane, a grid of 0.25 x 0.25
// quads (two triangles each, normal +z). A photo pixel is gain x A at the intersection of the
// ray through its centre with the plane (the photos show the plane beyond the mesh too, so that
// nothing but A is sampled near the mesh's border). The projection of a plane parallel to
// the image plane is a similarity, so the photo is A composed with an affine map: a texture cut
// from it and mapped by the corners' projections (atlas.h) shows A exactly, up to 8-bit
// rounding and interpolation, at every surface point.
constexpr int kPlaneQuadsX = 24, kPlaneQuadsY = 14;
constexpr double kPlaneCell = 0.25;
constexpr int kPlaneWidth = 160, kPlaneHeight = 144;
constexpr double kPlaneFocal = 120;

// Range [0.3, 0.7] per channel; at most ~0.02 per photo pixel (about 60 pixels per unit), so a
// texture misplaced by one pixel is off by up to ~0.02; the curvature is small enough
// (|A''| <= 8 per unit^2, 0.003 per pixel^2) that bilinear interpolation is exact to 4e-4.
Eigen::Vector3d Albedo(double x, double y) {
  Eigen::Vector3d a;
  for (int c = 0; c < 3; ++c) {
    a[c] =
        0.5 + 0.15 * std::sin(6.0 * x + 4.0 * y + 2.0 * c) + 0.05 * std::cos(1.1 * x - 0.9 * y + c);
  }
  return a;
}

struct PlaneCamera {
  Eigen::Vector3d centre;
  double yaw;   // rotation about the optical axis, radians
  double gain;  // exposure: the photo is gain x A
};

camera::Pose PlanePose(const PlaneCamera& c) {
  // Looking down (-z): camera x along world x, camera y along world -y, then the yaw.
  const Eigen::Matrix3d down = Eigen::Vector3d(1, -1, -1).asDiagonal();
  camera::Pose pose;
  pose.rotation = Eigen::AngleAxisd(c.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * down;
  pose.translation = -pose.rotation * c.centre;
  return pose;
}

// Pixel position (corner convention) of a world point, pinhole, written out.
Eigen::Vector2d PlaneProject(const camera::Pose& pose, const Eigen::Vector3d& world) {
  const Eigen::Vector3d cam = pose.rotation * world + pose.translation;
  return {kPlaneFocal * cam.x() / cam.z() + kPlaneWidth / 2.0,
          kPlaneFocal * cam.y() / cam.z() + kPlaneHeight / 2.0};
}

struct PlaneScene {
  std::filesystem::path dir;
  scene::Scene scene;
  mesh::Mesh mesh;
  std::vector<PlaneCamera> cameras;
};

PlaneScene MakePlaneScene(const std::vector<double>& gains) {
  PlaneScene p;
  p.dir = testing::MakeTempDir();
  for (int j = 0; j <= kPlaneQuadsY; ++j) {
    for (int i = 0; i <= kPlaneQuadsX; ++i) {
      p.mesh.positions.emplace_back(kPlaneCell * i, kPlaneCell * j, 0);
    }
  }
  for (int j = 0; j < kPlaneQuadsY; ++j) {
    for (int i = 0; i < kPlaneQuadsX; ++i) {
      const uint32_t a = j * (kPlaneQuadsX + 1) + i, b = a + 1, c = a + kPlaneQuadsX + 1, d = c + 1;
      p.mesh.faces.push_back({a, b, d});
      p.mesh.faces.push_back({a, d, c});
    }
  }
  p.cameras = {{{1.0, 1.1, 2.0}, 0.0, gains[0]},
               {{3.0, 1.1, 2.1}, 0.25, gains[1]},
               {{5.0, 1.1, 2.2}, -0.2, gains[2]}};
  camera::Camera pinhole;
  pinhole.model = camera::CameraModel::kPinhole;
  pinhole.width = kPlaneWidth;
  pinhole.height = kPlaneHeight;
  pinhole.params = {kPlaneFocal, kPlaneFocal, kPlaneWidth / 2.0, kPlaneHeight / 2.0};
  p.scene.cameras[0] = pinhole;
  for (size_t k = 0; k < p.cameras.size(); ++k) {
    const PlaneCamera& c = p.cameras[k];
    scene::View view;
    view.name = "plane" + std::to_string(k) + ".png";
    view.image_path = p.dir / view.name;
    view.cam_from_world = PlanePose(c);
    Image photo(kPlaneWidth, kPlaneHeight, 3);
    for (int y = 0; y < kPlaneHeight; ++y) {
      for (int x = 0; x < kPlaneWidth; ++x) {
        // The ray through the pixel centre, camera to world, meets z = 0 at t = -C.z / d.z.
        const Eigen::Vector3d ray_cam((x + 0.5 - kPlaneWidth / 2.0) / kPlaneFocal,
                                      (y + 0.5 - kPlaneHeight / 2.0) / kPlaneFocal, 1.0);
        const Eigen::Vector3d ray = view.cam_from_world.rotation.transpose() * ray_cam;
        const Eigen::Vector3d hit = c.centre - c.centre.z() / ray.z() * ray;
        const Eigen::Vector3d colour = c.gain * Albedo(hit.x(), hit.y());
        for (int ch = 0; ch < 3; ++ch) {
          photo.at(x, y, ch) = static_cast<float>(std::clamp(colour[ch], 0.0, 1.0));
        }
      }
    }
    io::WritePng(view.image_path, photo);
    p.scene.views.push_back(view);
  }
  return p;
}

// Which cameras see face f whole, by the rule view_selection.h states (facing above the
// cosine 0.05, the three corners at least half a pixel inside the image; nothing occludes a
// single plane), and whether a camera sees none of it (all corners beyond one image border).
struct PlaneVisibility {
  std::vector<std::vector<int>> whole;  // per face, the cameras that see it whole
  std::vector<uint8_t> unseen;          // per face, no camera sees any part of it
};

PlaneVisibility ComputePlaneVisibility(const PlaneScene& p) {
  PlaneVisibility v;
  v.whole.resize(p.mesh.faces.size());
  v.unseen.assign(p.mesh.faces.size(), 1);
  for (size_t f = 0; f < p.mesh.faces.size(); ++f) {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (uint32_t i : p.mesh.faces[f]) centroid += p.mesh.positions[i].cast<double>() / 3;
    for (size_t k = 0; k < p.cameras.size(); ++k) {
      const camera::Pose pose = PlanePose(p.cameras[k]);
      const Eigen::Vector3d to_camera = (p.cameras[k].centre - centroid).normalized();
      bool inside = to_camera.z() > 0.05;  // the face normal is +z
      bool left = true, right = true, above = true, below = true;
      for (uint32_t i : p.mesh.faces[f]) {
        const Eigen::Vector2d px = PlaneProject(pose, p.mesh.positions[i].cast<double>());
        inside = inside && px.x() >= 0.5 && px.x() <= kPlaneWidth - 0.5 && px.y() >= 0.5 &&
                 px.y() <= kPlaneHeight - 0.5;
        left = left && px.x() < 0, right = right && px.x() > kPlaneWidth;
        above = above && px.y() < 0, below = below && px.y() > kPlaneHeight;
      }
      if (inside) v.whole[f].push_back(static_cast<int>(k));
      if (!(left || right || above || below)) v.unseen[f] = 0;
    }
  }
  return v;
}

// The textured model's colour at barycentric coordinates `b` of face f: its atlas sampled
// bilinearly (texel centres at half-integers, atlas.h's corner convention) at the wedge texture
// coordinates interpolated with `b`, as a renderer does.
Eigen::Vector3d AtlasColour(const TexturedMesh& t, size_t f, const Eigen::Vector3d& b) {
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();
  for (int k = 0; k < 3; ++k) uv += b[k] * t.mesh.wedge_texcoords[3 * f + k].cast<double>();
  const Image8& atlas = t.atlases.at(t.mesh.face_materials.at(f));
  const double x = uv.x() * atlas.width() - 0.5, y = (1 - uv.y()) * atlas.height() - 0.5;
  const int x0 = std::clamp(static_cast<int>(std::floor(x)), 0, atlas.width() - 2);
  const int y0 = std::clamp(static_cast<int>(std::floor(y)), 0, atlas.height() - 2);
  const double fx = std::clamp(x - x0, 0.0, 1.0), fy = std::clamp(y - y0, 0.0, 1.0);
  Eigen::Vector3d colour;
  for (int c = 0; c < 3; ++c) {
    colour[c] =
        ((1 - fx) * (1 - fy) * atlas.at(x0, y0, c) + fx * (1 - fy) * atlas.at(x0 + 1, y0, c) +
         (1 - fx) * fy * atlas.at(x0, y0 + 1, c) + fx * fy * atlas.at(x0 + 1, y0 + 1, c)) /
        255.0;
  }
  return colour;
}

Eigen::Vector3d SurfacePoint(const mesh::Mesh& mesh, size_t f, const Eigen::Vector3d& b) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) p += b[k] * mesh.positions[mesh.faces[f][k]].cast<double>();
  return p;
}

// Coverage against the closed form: every face some camera sees whole is textured from one of
// those cameras; every face no camera sees any part of is filled (a face cut by an image border
// may be either.
void ExpectClosedFormCoverage(const PlaneScene& p, const TexturedMesh& t) {
  const PlaneVisibility v = ComputePlaneVisibility(p);
  size_t whole = 0, unseen = 0, untextured = 0;
  for (size_t f = 0; f < p.mesh.faces.size(); ++f) {
    ASSERT_LE(v.whole[f].size(), 2u) << "scene: no face in three photos (no consistency check)";
    untextured += t.face_views[f] < 0;
    if (!v.whole[f].empty()) {
      ++whole;
      EXPECT_NE(std::find(v.whole[f].begin(), v.whole[f].end(), t.face_views[f]), v.whole[f].end())
          << "face " << f << " textured from view " << t.face_views[f];
    }
    if (v.unseen[f]) {
      ++unseen;
      EXPECT_EQ(t.face_views[f], -1) << "face " << f << " is in no photo";
    }
  }
  std::printf("plane: %zu faces, %zu seen whole, %zu in no photo, %zu untextured\n",
              p.mesh.faces.size(), whole, unseen, untextured);
  EXPECT_GT(whole, p.mesh.faces.size() / 2);  // the scene is what it is meant to be
  EXPECT_GT(unseen, 0u);
  EXPECT_EQ(t.report.filled_faces + t.report.default_faces, untextured);
  EXPECT_EQ(t.report.default_faces, 0u);  // one connected plane: every face can be filled
  EXPECT_EQ(t.report.textured_faces, p.mesh.faces.size() - untextured);
}

TEST(TextureMeshClosedForm, ColoursAreTheSceneWhereThePhotosAgree) {
  const PlaneScene p = MakePlaneScene({1.0, 1.0, 1.0});
  const TexturedMesh t = TextureMesh(p.mesh, p.scene, {0, 1, 2});
  ExpectClosedFormCoverage(p, t);
  // At every face seen whole, at its centroid and at three points towards its corners, the
  // textured colour is A there. Tolerance 0.008: the photo's and the atlas's 8-bit rounding
  // (0.002 each), two bilinear resamplings of a nearly linear function (4e-4 each), and seam
  // offsets fitted to that rounding noise; a texture off by one photo pixel is off by up to 0.02.
  const PlaneVisibility v = ComputePlaneVisibility(p);
  double worst = 0;
  for (size_t f = 0; f < p.mesh.faces.size(); ++f) {
    if (v.whole[f].empty()) continue;
    for (const Eigen::Vector3d& b :
         {Eigen::Vector3d(1.0 / 3, 1.0 / 3, 1.0 / 3), Eigen::Vector3d(0.7, 0.15, 0.15),
          Eigen::Vector3d(0.15, 0.7, 0.15), Eigen::Vector3d(0.15, 0.15, 0.7)}) {
      const Eigen::Vector3d point = SurfacePoint(p.mesh, f, b);
      const double error =
          (AtlasColour(t, f, b) - Albedo(point.x(), point.y())).cwiseAbs().maxCoeff();
      worst = std::max(worst, error);
      EXPECT_LE(error, 0.008) << "face " << f << " at " << b.transpose();
    }
  }
  std::printf("plane, equal exposures: largest colour error %.4f\n", worst);
}

// Per pair of views, the mean over the edges where their patches meet of the colour step
// across the edge (each side sampled near the edge's midpoint, A's own change between the two
// points subtracted), signed, per channel; and how many such edges there are.
std::map<std::pair<int, int>, std::pair<Eigen::Vector3d, int>> SeamSteps(const PlaneScene& p,
                                                                         const TexturedMesh& t) {
  std::map<std::pair<uint32_t, uint32_t>, std::vector<std::pair<size_t, int>>> edges;
  for (size_t f = 0; f < p.mesh.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = p.mesh.faces[f][k], b = p.mesh.faces[f][(k + 1) % 3];
      edges[{std::min(a, b), std::max(a, b)}].push_back({f, 3 - k - (k + 1) % 3});
    }
  }
  std::map<std::pair<int, int>, std::pair<Eigen::Vector3d, int>> steps;
  for (const auto& [edge, sides] : edges) {
    if (sides.size() != 2) continue;
    const auto [f, opposite_f] = sides[0];
    const auto [g, opposite_g] = sides[1];
    if (t.face_views[f] < 0 || t.face_views[g] < 0 || t.face_views[f] == t.face_views[g]) {
      continue;
    }
    // 10 % of the way from the edge's midpoint to the opposite corner.
    const auto near_edge = [](int opposite) {
      Eigen::Vector3d b = Eigen::Vector3d::Constant(0.45);
      b[opposite] = 0.1;
      return b;
    };
    const auto deviation = [&](size_t face, int opposite) {
      const Eigen::Vector3d b = near_edge(opposite);
      const Eigen::Vector3d point = SurfacePoint(p.mesh, face, b);
      return Eigen::Vector3d(AtlasColour(t, face, b) - Albedo(point.x(), point.y()));
    };
    std::pair<int, int> views{t.face_views[f], t.face_views[g]};
    Eigen::Vector3d step = deviation(f, opposite_f) - deviation(g, opposite_g);
    if (views.first > views.second) std::swap(views.first, views.second), step = -step;
    auto& [sum, count] = steps[views];
    if (count == 0) sum.setZero();
    sum += step;
    ++count;
  }
  for (auto& [views, step] : steps) step.first /= step.second;
  return steps;
}

TEST(TextureMeshClosedForm, SeamLevelingJoinsPhotosOfDifferentExposure) {
  // Exposures 0.8, 1.2 and 1.0: where the patches of photos 0 and 1 meet, their colours differ
  // by 0.4 A (0.12 to 0.28), where 1 and 2 meet by 0.2 A (0.06 to 0.14).
  const std::vector<double> gains = {0.8, 1.2, 1.0};
  const PlaneScene p = MakePlaneScene(gains);
  const TexturedMesh leveled = TextureMesh(p.mesh, p.scene, {0, 1, 2});
  ExpectClosedFormCoverage(p, leveled);
  TextureOptions off;
  off.seam_leveling = false;
  const TexturedMesh raw = TextureMesh(p.mesh, p.scene, {0, 1, 2}, off);

  const auto leveled_steps = SeamSteps(p, leveled);
  const auto raw_steps = SeamSteps(p, raw);
  for (const std::pair<int, int>& views : {std::pair{0, 1}, std::pair{1, 2}}) {
    ASSERT_TRUE(leveled_steps.count(views) && raw_steps.count(views))
        << "no seam between views " << views.first << " and " << views.second;
    const auto& [step, edges] = leveled_steps.at(views);
    const Eigen::Vector3d raw_step = raw_steps.at(views).first;
    std::printf(
        "seam %d-%d: %d edges, mean step leveled (%.4f %.4f %.4f), not leveled "
        "(%.4f %.4f %.4f)\n",
        views.first, views.second, edges, step[0], step[1], step[2], raw_step[0], raw_step[1],
        raw_step[2]);
    EXPECT_GE(edges, 5);
    // Without leveling the step is the exposure difference (a check of the scene: the photos
    // differ as intended) ...
    const double gain_step = gains[views.first] - gains[views.second];
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(raw_step[c], gain_step * 0.5, std::abs(gain_step) * 0.2 + 0.01) << c;
    }
    // ... and with leveling both sides meet: a mean step below 0.01 (a tenth or less of the
    // exposure step; left: A's variation along the seam, which per-vertex offsets follow only
    // at the vertices, and rounding).
    EXPECT_LT(step.cwiseAbs().maxCoeff(), 0.01);
  }
  // Leveling moves colours between the exposures, not beyond them: at every face seen whole,
  // min(gain) A - 0.03 <= colour <= max(gain) A + 0.03.
  const PlaneVisibility v = ComputePlaneVisibility(p);
  const Eigen::Vector3d centroid = Eigen::Vector3d::Constant(1.0 / 3);
  for (size_t f = 0; f < p.mesh.faces.size(); ++f) {
    if (v.whole[f].empty()) continue;
    const Eigen::Vector3d point = SurfacePoint(p.mesh, f, centroid);
    const Eigen::Vector3d a = Albedo(point.x(), point.y());
    const Eigen::Vector3d colour = AtlasColour(leveled, f, centroid);
    for (int c = 0; c < 3; ++c) {
      EXPECT_GE(colour[c], 0.8 * a[c] - 0.03) << "face " << f;
      EXPECT_LE(colour[c], 1.2 * a[c] + 0.03) << "face " << f;
    }
  }
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
