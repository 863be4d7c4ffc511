#include "rephoto/project/project.h"

#include <gmock/gmock.h>

#include <cmath>
#include <cstring>
#include <fstream>

#include "rephoto/core/colormap.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/parallel.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/render/render.h"
#include "rephoto/testing/testing.h"

namespace rephoto::project {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// The hand-built scene (all numbers chosen so the expectations follow by hand):
// - Two pinhole cameras, f = 400 px, 200 x 200, principal point (100, 100), looking along +z
//   (identity rotation). Camera 1 at the origin, camera 2 at (0.5, 0, 0). A point (x, y, z)
//   projects in camera 1 to (400 x / z + 100, 400 y / z + 100), in camera 2 to
//   (400 (x - 0.5) / z + 100, ...): on the plane z = 5 camera 2's pixels are camera 1's minus
//   40, on z = 2.5 minus 80 (integers, so fractional pixel positions are the same in both).
// - A plane z = 5: a 5 x 5 grid with x, y in {-0.995, -0.4975, 0, 0.4975, 0.995}, which
//   camera 1 sees at pixels {20.4, 60.2, 100, 139.8, 179.6} (camera 2: x - 40). The outermost
//   vertices sit 0.1 px inside their pixel's centre, so the pixel containing each vertex is
//   covered by the plane (no silhouette ambiguity).
// - An occluder z = 2.5: a 3 x 3 grid, x in {0.4025, 0.5, 0.5975}, y in {-0.5975, 0, 0.5975}:
//   camera 1 pixels x {164.4, 180, 195.6}, y {4.4, 100, 195.6} (its border vertices, too, lie
//   0.1 px inside their pixel's centre). It casts a shadow on the plane x in [0.805, 1.195] for
//   camera 1 (hides column x = 0.995) and x in [0.305, 0.695] for camera 2 (hides column
//   x = 0.4975); in y it covers the whole plane in both.
// - One loose vertex (0, 0, 10) behind the plane: hidden in both views (never seen).
// Camera 2 does not see column x = -0.995 (pixel -19.6, outside the image).
constexpr float kPlane[5] = {-0.995f, -0.4975f, 0.0f, 0.4975f, 0.995f};
constexpr float kOccluderX[3] = {0.4025f, 0.5f, 0.5975f};
constexpr float kOccluderY[3] = {-0.5975f, 0.0f, 0.5975f};

camera::Camera Pinhole() {
  camera::Camera camera;
  camera.model = camera::CameraModel::kPinhole;
  camera.width = 200;
  camera.height = 200;
  camera.params = {400, 400, 100, 100};
  return camera;
}

camera::Pose At(double x) {
  camera::Pose pose;
  pose.translation = Eigen::Vector3d(-x, 0, 0);  // centre (x, 0, 0), identity rotation
  return pose;
}

// Vertex indices: plane (row j, column i) = 5 j + i; occluder (j, i) = 25 + 3 j + i; loose 34.
size_t PlaneIndex(int column, int row) { return 5 * row + column; }
size_t OccluderIndex(int column, int row) { return 25 + 3 * row + column; }
constexpr size_t kLoose = 34;

void AddGrid(mesh::Mesh* mesh, int columns, int rows) {
  const uint32_t base = static_cast<uint32_t>(mesh->positions.size()) - columns * rows;
  for (int j = 0; j + 1 < rows; ++j) {
    for (int i = 0; i + 1 < columns; ++i) {
      const uint32_t a = base + j * columns + i, b = a + 1, c = a + columns, d = c + 1;
      mesh->faces.push_back({a, b, d});
      mesh->faces.push_back({a, d, c});
    }
  }
}

mesh::Mesh MakeScene(bool point_cloud) {
  mesh::Mesh mesh;
  for (int j = 0; j < 5; ++j) {
    for (int i = 0; i < 5; ++i) mesh.positions.emplace_back(kPlane[i], kPlane[j], 5.0f);
  }
  if (!point_cloud) AddGrid(&mesh, 5, 5);
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 3; ++i) mesh.positions.emplace_back(kOccluderX[i], kOccluderY[j], 2.5f);
  }
  if (!point_cloud) AddGrid(&mesh, 3, 3);
  mesh.positions.emplace_back(0.0f, 0.0f, 10.0f);
  if (point_cloud) {
    // View-facing discs: plane points 0.3 (neighbours 0.4975 apart overlap), occluder points
    // 0.1; the loose point 0.05. The occluder needs more points to be a closed shadow caster:
    // fill its rectangle every 0.025 x 0.05 (extra points after index 34).
    mesh.radii.assign(mesh.positions.size(), 0.3f);
    for (size_t k = 25; k < 34; ++k) mesh.radii[k] = 0.1f;
    mesh.radii[kLoose] = 0.05f;
    for (float y = -0.55f; y <= 0.551f; y += 0.05f) {
      for (float x = 0.425f; x <= 0.576f; x += 0.025f) {
        mesh.positions.emplace_back(x, y, 2.5f);
        mesh.radii.push_back(0.1f);
      }
    }
  }
  return mesh;
}

// A constant error image (optionally with a NaN block [x0, x1) x [y0, y1)).
fs::path WriteConstant(const fs::path& path, float value, int nan_x0 = 0, int nan_x1 = 0,
                       int nan_y0 = 0, int nan_y1 = 0, int size = 200) {
  Image image(size, size, 1, value);
  for (int y = nan_y0; y < nan_y1; ++y) {
    for (int x = nan_x0; x < nan_x1; ++x) image.at(x, y) = std::nanf("");
  }
  io::WriteExr(path, image);
  return path;
}

struct Expected {
  float error;  // NaN = unseen
  uint32_t views;
};

// The hand computation for the constant images (camera 1: 0.2, camera 2: 0.6, camera 2 NaN
// around the plane's centre vertex).
std::vector<Expected> ExpectedConstant(size_t vertices) {
  std::vector<Expected> expected(vertices, {std::nanf(""), 0});
  for (int row = 0; row < 5; ++row) {
    expected[PlaneIndex(0, row)] = {0.2f, 1};  // outside camera 2
    expected[PlaneIndex(1, row)] = {0.4f, 2};
    expected[PlaneIndex(2, row)] = {0.4f, 2};
    expected[PlaneIndex(3, row)] = {0.2f, 1};  // hidden in camera 2
    expected[PlaneIndex(4, row)] = {0.6f, 1};  // hidden in camera 1
  }
  expected[PlaneIndex(2, 2)] = {0.2f, 1};  // camera 2's error is NaN there
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) expected[OccluderIndex(column, row)] = {0.4f, 2};
  }
  return expected;
}

std::vector<ProjectView> ConstantViews(const fs::path& dir) {
  // Camera 2 sees the plane's centre vertex (0, 0, 5) at pixel (60, 100): NaN on [55, 66) x
  // [95, 106) covers all 4 pixels around it.
  return {{Pinhole(), At(0), WriteConstant(dir / "a.exr", 0.2f), "a"},
          {Pinhole(), At(0.5), WriteConstant(dir / "b.exr", 0.6f, 55, 66, 95, 106), "b"}};
}

void ExpectMatches(const ProjectResult& result, const std::vector<Expected>& expected,
                   size_t count) {
  for (size_t i = 0; i < count; ++i) {
    SCOPED_TRACE(::testing::Message() << "vertex " << i);
    EXPECT_EQ(result.view_count[i], expected[i].views);
    if (std::isnan(expected[i].error)) {
      EXPECT_TRUE(std::isnan(result.vertex_error[i]));
    } else {
      EXPECT_NEAR(result.vertex_error[i], expected[i].error, 1e-6);
    }
  }
}

TEST(ProjectErrors, PlaneWithOccluderGivesTheHandComputedMeansAndCounts) {
  const fs::path dir = testing::MakeTempDir();
  const mesh::Mesh model = MakeScene(false);
  ASSERT_EQ(model.vertex_count(), 35u);
  const ProjectResult result = ProjectErrors(model, ConstantViews(dir), {});
  ASSERT_EQ(result.vertex_error.size(), 35u);
  ExpectMatches(result, ExpectedConstant(35), 35);
  EXPECT_EQ(result.seen_vertices, 34u);
  EXPECT_EQ(result.visible_vertices, 34u);  // the NaN-only vertex is still visible in camera 2
  // Camera 1 gives a value to all but the hidden column and the loose vertex (35 - 5 - 1);
  // camera 2 to all but the outside column, the hidden column, the NaN vertex and the loose one.
  EXPECT_THAT(result.view_seen_vertices, ::testing::ElementsAre(29u, 23u));
  // 34 finite values: 11 x 0.2, 18 x 0.4, 5 x 0.6. Percentile positions (n - 1) p = 33 p:
  // 2.5 % -> 0.825 (between two 0.2), 97.5 % -> 32.175 (between two 0.6).
  EXPECT_FLOAT_EQ(result.low, 0.2f);
  EXPECT_FLOAT_EQ(result.high, 0.6f);
}

TEST(ProjectErrors, DepthImagesOfTheErrorRenderingGiveTheSameAnswer) {
  // evaluate passes its own renderings' depth (4 jittered samples per pixel, the nearest kept)
  // instead of a second rendering: the hand-computed answer is the same.
  const fs::path dir = testing::MakeTempDir();
  std::vector<ProjectView> views = ConstantViews(dir);
  const render::RenderModel model(MakeScene(false));
  render::RenderOptions options;
  options.samples_per_pixel = 4;
  for (size_t v = 0; v < views.size(); ++v) {
    const render::Rephoto shot =
        render::RenderRephoto(model, views[v].camera, views[v].cam_from_world, options);
    views[v].depth_image = dir / ("depth" + std::to_string(v) + ".exr");
    io::WriteExr(views[v].depth_image, shot.depth);
  }
  const ProjectResult result = ProjectErrors(MakeScene(false), views, {});
  ExpectMatches(result, ExpectedConstant(35), 35);
  EXPECT_THAT(result.view_seen_vertices, ::testing::ElementsAre(29u, 23u));

  // The depth file is what decides: a depth map without surfaces hides everything.
  io::WriteExr(dir / "empty.exr", Image(200, 200, 1, std::nanf("")));
  views[0].depth_image = views[1].depth_image = dir / "empty.exr";
  EXPECT_EQ(ProjectErrors(MakeScene(false), views, {}).seen_vertices, 0u);
  // One that does not fit the error image is refused, naming it.
  io::WriteExr(dir / "small_depth.exr", Image(100, 100, 1, 5.0f));
  views[0].depth_image = dir / "small_depth.exr";
  try {
    ProjectErrors(MakeScene(false), views, {});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("small_depth.exr"));
  }
}

TEST(ProjectErrors, PercentilesInterpolateBetweenOrderStatistics) {
  const fs::path dir = testing::MakeTempDir();
  ProjectOptions options;
  options.low_percentile = 32;   // position 33 * 0.32 = 10.56: 0.2 + 0.56 * (0.4 - 0.2)
  options.high_percentile = 85;  // position 33 * 0.85 = 28.05: 0.4 + 0.05 * (0.6 - 0.4)
  const ProjectResult result = ProjectErrors(MakeScene(false), ConstantViews(dir), options);
  EXPECT_NEAR(result.low, 0.312f, 1e-6);
  EXPECT_NEAR(result.high, 0.41f, 1e-6);
  // t = (0.4 - 0.312) / (0.41 - 0.312) = 0.897959...; jet: red = 1.5 - |4t - 3| = 0.908163,
  // green = 1.5 - |4t - 2| < 0 -> 0, blue 0 -> (232, 0, 0).
  EXPECT_THAT(ErrorColour(0.4f, result.low, result.high), ::testing::ElementsAre(232, 0, 0));
  // Clamped: 0.2 below low -> t = 0 -> jet (0, 0, 0.5); 0.6 above high -> t = 1 -> (0.5, 0, 0).
  EXPECT_THAT(ErrorColour(0.2f, result.low, result.high), ::testing::ElementsAre(0, 0, 128));
  EXPECT_THAT(ErrorColour(0.6f, result.low, result.high), ::testing::ElementsAre(128, 0, 0));
  EXPECT_THAT(ErrorColour(std::nanf(""), result.low, result.high),
              ::testing::ElementsAre(128, 128, 128));
  // Mid-range: t = 0.5 -> (1.5 - |2 - 3|, 1.5 - |2 - 2|, 1.5 - |2 - 1|) = (0.5, 1.5, 0.5),
  // clamped to [0,1] -> (128, 255, 128).
  EXPECT_THAT(ErrorColour(0.5f, 0.0f, 1.0f), ::testing::ElementsAre(128, 255, 128));
  // A reversed fixed range (higher is better) maps high values to blue.
  EXPECT_THAT(ErrorColour(1.0f, 1.0f, 0.0f), ::testing::ElementsAre(0, 0, 128));
  // Equal ends: t = 0.
  EXPECT_THAT(ErrorColour(0.7f, 0.7f, 0.7f), ::testing::ElementsAre(0, 0, 128));

  options.higher_is_better = true;  // a similarity: the range runs backwards
  const ProjectResult reversed = ProjectErrors(MakeScene(false), ConstantViews(dir), options);
  EXPECT_NEAR(reversed.low, 0.41f, 1e-6);
  EXPECT_NEAR(reversed.high, 0.312f, 1e-6);
  EXPECT_THAT(ErrorColour(0.2f, reversed.low, reversed.high), ::testing::ElementsAre(128, 0, 0));
  options.higher_is_better = false;

  options.fixed_range = std::make_pair(0.0f, 2.0f);
  const ProjectResult fixed = ProjectErrors(MakeScene(false), ConstantViews(dir), options);
  EXPECT_EQ(fixed.low, 0.0f);
  EXPECT_EQ(fixed.high, 2.0f);
}

TEST(ProjectErrors, BilinearSampleOverFiniteDepthAgreeingPixels) {
  const fs::path dir = testing::MakeTempDir();
  // Camera 1 only. An affine error e = 0.01 x + 0.002 y at pixel centres (x + 0.5, y + 0.5):
  // bilinear interpolation reproduces it exactly, so a plane vertex at pixel p gets
  // 0.01 p.x + 0.002 p.y. Except at the plane's border: a vertex at 179.6 has neighbours 179
  // and 180, whose centre 180.5 lies off the plane (world 1.00625 > 0.995, empty depth), so only
  // 179 counts and the sample is taken at 179.5; likewise 20.4 -> 20.5 (pixel 19 is off).
  Image ramp(200, 200, 1);
  for (int y = 0; y < 200; ++y) {
    for (int x = 0; x < 200; ++x) ramp.at(x, y) = 0.01f * (x + 0.5f) + 0.002f * (y + 0.5f);
  }
  // Vertex (column 1, row 2) = (-0.4975, 0, 5) is at pixel (60.2, 100): its 4 pixels are
  // (59, 99) (60, 99) (59, 100) (60, 100) with weights 0.3*0.5, 0.7*0.5, 0.3*0.5, 0.7*0.5.
  // Making (60, 100) NaN (the pixel containing the vertex) leaves the other three, renormalized.
  ramp.at(60, 100) = std::nanf("");
  io::WriteExr(dir / "ramp.exr", ramp);
  const ProjectResult result =
      ProjectErrors(MakeScene(false), {{Pinhole(), At(0), dir / "ramp.exr", "ramp"}}, {});
  const double pixels[5] = {20.5, 60.2, 100.0, 139.8, 179.5};
  for (int row = 0; row < 5; ++row) {
    for (int column = 0; column < 4; ++column) {  // column 4 is hidden by the occluder
      if (column == 1 && row == 2) continue;
      SCOPED_TRACE(::testing::Message() << "plane vertex " << column << ", " << row);
      EXPECT_EQ(result.view_count[PlaneIndex(column, row)], 1u);
      EXPECT_NEAR(result.vertex_error[PlaneIndex(column, row)],
                  0.01 * pixels[column] + 0.002 * pixels[row], 2e-5);
    }
  }
  auto e = [](int x, int y) { return 0.01 * (x + 0.5) + 0.002 * (y + 0.5); };
  const double expected = (0.15 * e(59, 99) + 0.35 * e(60, 99) + 0.15 * e(59, 100)) / 0.65;
  EXPECT_EQ(result.view_count[PlaneIndex(1, 2)], 1u);
  EXPECT_NEAR(result.vertex_error[PlaneIndex(1, 2)], expected, 2e-5);
  EXPECT_EQ(result.view_count[PlaneIndex(4, 2)], 0u);
}

TEST(ProjectErrors, PointCloudDiscsGiveTheSameAnswer) {
  const fs::path dir = testing::MakeTempDir();
  const mesh::Mesh cloud = MakeScene(true);
  ASSERT_TRUE(cloud.is_point_cloud());
  const ProjectResult result = ProjectErrors(cloud, ConstantViews(dir), {});
  ASSERT_EQ(result.vertex_error.size(), cloud.vertex_count());
  ExpectMatches(result, ExpectedConstant(35), 35);
  // The extra occluder points are seen by both cameras.
  for (size_t i = 35; i < cloud.vertex_count(); ++i) {
    EXPECT_EQ(result.view_count[i], 2u) << "point " << i;
    EXPECT_NEAR(result.vertex_error[i], 0.4f, 1e-6) << "point " << i;
  }
}

TEST(ProjectErrors, DeterministicForAnyThreadCount) {
  const fs::path dir = testing::MakeTempDir();
  const std::vector<ProjectView> views = ConstantViews(dir);
  const ProjectResult all = ProjectErrors(MakeScene(false), views, {});
  ProjectResult one;
  {
    ThreadLimit limit(1);
    one = ProjectErrors(MakeScene(false), views, {});
  }
  ASSERT_EQ(all.vertex_error.size(), one.vertex_error.size());
  for (size_t i = 0; i < all.vertex_error.size(); ++i) {
    EXPECT_TRUE(std::memcmp(&all.vertex_error[i], &one.vertex_error[i], sizeof(float)) == 0);
  }
  EXPECT_EQ(all.view_count, one.view_count);
}

TEST(ProjectErrors, BadInputIsAClearError) {
  const fs::path dir = testing::MakeTempDir();
  // Error image whose size disagrees with its camera: names the file and both sizes.
  io::WriteExr(dir / "small.exr", Image(100, 80, 1, 0.5f));
  try {
    ProjectErrors(MakeScene(false), {{Pinhole(), At(0), dir / "small.exr", "small"}}, {});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("small.exr"));
    EXPECT_THAT(e.what(), HasSubstr("100x80"));
    EXPECT_THAT(e.what(), HasSubstr("200x200"));
  }
  // Three channels.
  io::WriteExr(dir / "rgb.exr", Image(200, 200, 3, 0.5f));
  EXPECT_THROW(
      {
        try {
          ProjectErrors(MakeScene(false), {{Pinhole(), At(0), dir / "rgb.exr", ""}}, {});
        } catch (const Error& e) {
          EXPECT_THAT(e.what(), HasSubstr("rgb.exr: error image has 3 channels"));
          throw;
        }
      },
      Error);
  // Missing file.
  EXPECT_THROW(ProjectErrors(MakeScene(false), {{Pinhole(), At(0), dir / "none.exr", ""}}, {}),
               Error);
  // No vertices.
  try {
    ProjectErrors(mesh::Mesh{}, {}, {});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("no vertices"));
  }
  ProjectOptions bad;
  bad.low_percentile = 90;
  bad.high_percentile = 10;
  EXPECT_THROW(ProjectErrors(MakeScene(false), {}, bad), Error);
  // No views: nothing seen, NaN range.
  const ProjectResult none = ProjectErrors(MakeScene(false), {}, {});
  EXPECT_EQ(none.seen_vertices, 0u);
  EXPECT_TRUE(std::isnan(none.low) && std::isnan(none.high));
}

TEST(ProjectErrors, CamerasScaledToHalfResolutionImagesWhenAllowed) {
  const fs::path dir = testing::MakeTempDir();
  // 100 x 100 error images of the 200 x 200 cameras: every pixel position halves (plane
  // vertices at 10.2 ... 89.8, still 0.1 px inside their pixels' centres; camera 2 shifted by
  // 20 px), so the hand computation of the full-resolution case holds unchanged. Camera 2's NaN
  // block moves to [27, 33) x [47, 53) around the centre vertex at (30, 50).
  const std::vector<ProjectView> views = {
      {Pinhole(), At(0), WriteConstant(dir / "a.exr", 0.2f, 0, 0, 0, 0, 100), "a"},
      {Pinhole(), At(0.5), WriteConstant(dir / "b.exr", 0.6f, 27, 33, 47, 53, 100), "b"}};
  EXPECT_THROW(ProjectErrors(MakeScene(false), views, {}), Error);
  ProjectOptions options;
  options.scale_cameras = true;
  const ProjectResult result = ProjectErrors(MakeScene(false), views, options);
  ExpectMatches(result, ExpectedConstant(35), 35);
  // Another aspect ratio is still an error.
  io::WriteExr(dir / "wide.exr", Image(200, 100, 1, 0.5f));
  EXPECT_THROW(ProjectErrors(MakeScene(false), {{Pinhole(), At(0), dir / "wide.exr", ""}}, options),
               Error);
}

TEST(WriteProjectedPly, ReadsBackWithErrorAndViewsProperties) {
  const fs::path dir = testing::MakeTempDir();
  const mesh::Mesh model = MakeScene(false);
  const ProjectResult result = ProjectErrors(model, ConstantViews(dir), {});
  const fs::path out = dir / "out" / "projected.ply";
  WriteProjectedPly(model, result, out);
  const mesh::Mesh back = mesh::ReadPly(out);
  ASSERT_EQ(back.vertex_count(), model.vertex_count());
  EXPECT_EQ(back.faces, model.faces);
  EXPECT_EQ(back.positions, model.positions);
  ASSERT_EQ(back.colors.size(), model.vertex_count());
  ASSERT_EQ(back.scalars.size(), 3u);
  EXPECT_EQ(back.scalars[0].name, "error");
  EXPECT_EQ(back.scalars[1].name, "quality");
  EXPECT_EQ(back.scalars[2].name, "views");
  for (size_t i = 0; i < model.vertex_count(); ++i) {
    SCOPED_TRACE(::testing::Message() << "vertex " << i);
    const std::array<uint8_t, 3> rgb = ErrorColour(result.vertex_error[i], 0.2f, 0.6f);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(back.colors[i][c] * 255.0f, rgb[c], 1e-3);
    if (std::isnan(result.vertex_error[i])) {
      EXPECT_TRUE(std::isnan(back.scalars[0].values[i]));
    } else {
      EXPECT_EQ(back.scalars[0].values[i], result.vertex_error[i]);
    }
    EXPECT_TRUE(
        std::memcmp(&back.scalars[1].values[i], &back.scalars[0].values[i], sizeof(float)) == 0);
    EXPECT_EQ(back.scalars[2].values[i], static_cast<float>(result.view_count[i]));
  }
  // Unseen: grey; 0.2 = low: dark blue; 0.6 = high: dark red.
  EXPECT_NEAR(back.colors[kLoose].x() * 255, 128, 1e-3);
  EXPECT_NEAR(back.colors[PlaneIndex(0, 0)].z() * 255, 128, 1e-3);
  EXPECT_NEAR(back.colors[PlaneIndex(4, 0)].x() * 255, 128, 1e-3);
  // The header declares the types MeshLab/CloudCompare expect.
  std::ifstream file(out, std::ios::binary);
  std::string header, line;
  while (std::getline(file, line) && line != "end_header") header += line + "\n";
  EXPECT_THAT(header, HasSubstr("format binary_little_endian 1.0"));
  EXPECT_THAT(header, HasSubstr("property uchar red"));
  EXPECT_THAT(header, HasSubstr("property float error\nproperty float quality\n"));
  EXPECT_THAT(header, HasSubstr("property uint views"));
  EXPECT_THAT(header, HasSubstr("property list uchar int vertex_indices"));

  // A result of another model is refused.
  mesh::Mesh other = model;
  other.positions.pop_back();
  EXPECT_THROW(WriteProjectedPly(other, result, dir / "bad.ply"), Error);
}

// A scene whose views are named like real formats: a subfolder, extensions; `clash` adds a
// view whose file name repeats another's in a different folder.
scene::Scene MakeNamedScene(bool clash = false) {
  scene::Scene scene;
  scene.cameras[1] = Pinhole();
  std::vector<std::string> names = {"images/a.jpg", "b.png", "c.png", "sub/d.png"};
  if (clash) names.push_back("other/a.jpg");
  for (const std::string& name : names) {
    scene::View view;
    view.name = name;
    view.camera_id = 1;
    view.cam_from_world = At(scene.views.size() * 0.1);
    scene.views.push_back(view);
  }
  return scene;
}

TEST(FindErrorImages, CompareRunDirectory) {
  const fs::path run = testing::MakeTempDir();
  for (const char* file : {"a.1-ncc.exr", "a.1-ncc.png", "b.1-ncc.exr", "b.dssim.exr",
                           "zzz.1-ncc.exr", "d.1-ncc.exr", "sub/d.1-ncc.exr"}) {
    WriteConstant(run / "errors" / file, 0.5f);
  }
  const scene::Scene scene = MakeNamedScene();
  size_t without = 99, unmatched = 99;
  const std::vector<ProjectView> views = FindErrorImages(scene, run, "1-ncc", &without, &unmatched);
  ASSERT_EQ(views.size(), 3u);
  EXPECT_EQ(views[0].name, "a");
  EXPECT_EQ(views[0].error_image, run / "errors" / "a.1-ncc.exr");
  EXPECT_EQ(views[0].cam_from_world, scene.views[0].cam_from_world);
  EXPECT_EQ(views[0].camera, Pinhole());
  EXPECT_EQ(views[1].name, "b");
  EXPECT_EQ(views[1].cam_from_world, scene.views[1].cam_from_world);
  EXPECT_EQ(views[2].name, "d");  // file stems are unique: "sub/d.png" -> "d"
  EXPECT_EQ(views[2].error_image, run / "errors" / "d.1-ncc.exr");
  EXPECT_EQ(views[2].cam_from_world, scene.views[3].cam_from_world);
  EXPECT_EQ(without, 1u);    // c
  EXPECT_EQ(unmatched, 2u);  // zzz, sub/d
  EXPECT_EQ(FindErrorImages(scene, run, "dssim", &without).size(), 1u);
  EXPECT_EQ(without, 3u);
  EXPECT_TRUE(FindErrorImages(scene, run, "census", &without).empty());
  EXPECT_EQ(without, 4u);
  EXPECT_THAT(ListErrorMetrics(run), ::testing::ElementsAre("1-ncc", "dssim"));
}

TEST(FindErrorImages, ClashingFileNamesUseRelativePaths) {
  const fs::path run = testing::MakeTempDir();
  for (const char* file :
       {"a.1-ncc.exr", "images/a.1-ncc.exr", "other/a.1-ncc.exr", "b.1-ncc.exr"}) {
    WriteConstant(run / "errors" / file, 0.5f);
  }
  const scene::Scene scene = MakeNamedScene(/*clash=*/true);
  size_t without = 99, unmatched = 99;
  const std::vector<ProjectView> views = FindErrorImages(scene, run, "1-ncc", &without, &unmatched);
  ASSERT_EQ(views.size(), 3u);
  EXPECT_EQ(views[0].name, "images/a");
  EXPECT_EQ(views[0].cam_from_world, scene.views[0].cam_from_world);
  EXPECT_EQ(views[1].name, "b");
  EXPECT_EQ(views[2].name, "other/a");
  EXPECT_EQ(views[2].cam_from_world, scene.views[4].cam_from_world);
  EXPECT_EQ(without, 2u);    // c, sub/d
  EXPECT_EQ(unmatched, 1u);  // the bare "a" belongs to neither a view
}

TEST(FindErrorImages, EvaluateRunDirectory) {
  const fs::path run = testing::MakeTempDir();
  WriteConstant(run / "folds" / "fold_01" / "errors" / "b.1-ncc.exr", 0.5f);
  WriteConstant(run / "folds" / "fold_00" / "errors" / "a.1-ncc.exr", 0.5f);
  WriteConstant(run / "folds" / "fold_00" / "errors" / "c.dssim.exr", 0.5f);
  WriteConstant(run / "folds" / "fold_01" / "errors" / "a.1-ncc.exr", 0.5f);  // a in two folds
  fs::create_directories(run / "folds" / "fold_02" / "reconstruction");       // failed fold
  const scene::Scene scene = MakeNamedScene();
  size_t without = 99;
  const std::vector<ProjectView> views = FindErrorImages(scene, run, "1-ncc", &without);
  ASSERT_EQ(views.size(), 3u);
  EXPECT_EQ(views[0].name, "fold_00/a");
  EXPECT_EQ(views[1].name, "fold_01/a");
  EXPECT_EQ(views[2].name, "fold_01/b");
  EXPECT_EQ(views[2].error_image, run / "folds" / "fold_01" / "errors" / "b.1-ncc.exr");
  EXPECT_EQ(without, 2u);  // c, d
  EXPECT_THAT(ListErrorMetrics(run), ::testing::ElementsAre("1-ncc", "dssim"));
}

TEST(FindErrorImages, NotARunDirectory) {
  const fs::path dir = testing::MakeTempDir();
  const scene::Scene scene = MakeNamedScene();
  size_t without = 0;
  try {
    FindErrorImages(scene, dir / "missing", "1-ncc", &without);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("missing: run directory does not exist"));
  }
  try {
    FindErrorImages(scene, dir, "1-ncc", &without);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("not a run directory"));
  }
  EXPECT_TRUE(ListErrorMetrics(dir).empty());
}

}  // namespace
}  // namespace rephoto::project

namespace rephoto::project {
namespace {

// Issue 32: a coarse mesh's vertices sample the error only at its corners; each face also gets
// the mean of its 4 interior sample points. One quad (2 triangles) at z = 5 filling camera 1's
// view, error 0 left of pixel column 100 (x < 0 on the plane) and 1 right of it. Triangle
// (a, b, d) has its points at x = -0.33, 0.66, 0.66 (sub-centroids) and 0.33 (centroid): 3 of
// 4 right, error 0.75; triangle (a, d, c) at -0.33, 0.33, -0.66 and -0.33: 0.25. The corners
// get 0 (left) and 1 (right).
TEST(ProjectErrors, FacesCarryTheMeanOfTheirInteriorSamples) {
  const fs::path dir = testing::MakeTempDir();
  mesh::Mesh quad;
  for (float y : {-0.995f, 0.995f}) {
    for (float x : {-0.995f, 0.995f}) quad.positions.emplace_back(x, y, 5.0f);
  }
  quad.faces = {{0, 1, 3}, {0, 3, 2}};
  Image error(200, 200, 1, 0.f);
  for (int y = 0; y < 200; ++y) {
    for (int x = 100; x < 200; ++x) error.at(x, y) = 1.f;
  }
  io::WriteExr(dir / "half.exr", error);
  const ProjectResult result =
      ProjectErrors(quad, {{Pinhole(), At(0), dir / "half.exr", "half"}}, {});
  ASSERT_EQ(result.face_error.size(), 2u);
  EXPECT_NEAR(result.face_error[0], 0.75, 1e-6);
  EXPECT_NEAR(result.face_error[1], 0.25, 1e-6);
  EXPECT_NEAR(result.vertex_error[0], 0, 1e-6);
  EXPECT_NEAR(result.vertex_error[1], 1, 1e-6);
  // The PLY carries them per face; the mesh reader still reads it.
  WriteProjectedPly(quad, result, dir / "quad.ply");
  const std::string text = ReadFileToString(dir / "quad.ply");
  EXPECT_THAT(text, HasSubstr("property list uchar int vertex_indices\nproperty uchar red\n"
                              "property uchar green\nproperty uchar blue\nproperty float error\n"
                              "property float quality\nend_header"));
  const mesh::Mesh back = mesh::ReadPly(dir / "quad.ply");
  EXPECT_EQ(back.face_count(), 2u);
  // Face 0's record: count 3, indices 0 1 3, colour of 0.75 over the result's range, error.
  const size_t body = text.find("end_header\n") + 11;
  const size_t vertex_bytes = 4 * (3 * 4 + 3 + 4 + 4 + 4);
  const size_t face0 = body + vertex_bytes;
  const std::array<uint8_t, 3> rgb = ErrorColour(0.75f, result.low, result.high);
  EXPECT_EQ(static_cast<uint8_t>(text[face0 + 13]), rgb[0]);
  float stored = 0;
  std::memcpy(&stored, text.data() + face0 + 16, 4);
  EXPECT_FLOAT_EQ(stored, result.face_error[0]);
  // A face under 4 pixels takes its corners' samples of the view: a 3.2 x 1.2 pixel rectangle
  // (x = +-0.02, y = +-0.0075 at z = 5: pixels 98.4 .. 101.6, 99.4 .. 100.6; each corner 0.1 px
  // inside its pixel's centre, diagonal 3.4 px). Its left corners sample only pixel 98 (the
  // pixel left of it is not covered): 0; its right corners only pixel 101: 1. Face (a, b, d)
  // (0 + 1 + 1) / 3, face (a, d, c) (0 + 1 + 0) / 3 (the 4 interior points would give 0.75
  // and 0.25).
  mesh::Mesh small = quad;
  for (Eigen::Vector3f& p : small.positions) {
    p.x() = p.x() > 0 ? 0.02f : -0.02f;
    p.y() = p.y() > 0 ? 0.0075f : -0.0075f;
  }
  const ProjectResult tiny =
      ProjectErrors(small, {{Pinhole(), At(0), dir / "half.exr", "half"}}, {});
  EXPECT_NEAR(tiny.vertex_error[0], 0, 1e-6);
  EXPECT_NEAR(tiny.vertex_error[1], 1, 1e-6);
  EXPECT_NEAR(tiny.face_error[0], 2.0 / 3, 1e-6);
  EXPECT_NEAR(tiny.face_error[1], 1.0 / 3, 1e-6);
  ProjectOptions no_faces;
  no_faces.face_errors = false;
  EXPECT_TRUE(ProjectErrors(small, {{Pinhole(), At(0), dir / "half.exr", "half"}}, no_faces)
                  .face_error.empty());
  // Point clouds have no faces.
  mesh::Mesh points = quad;
  points.faces.clear();
  EXPECT_TRUE(ProjectErrors(points, {{Pinhole(), At(0), dir / "half.exr", "half"}}, {})
                  .face_error.empty());
}

}  // namespace
}  // namespace rephoto::project
