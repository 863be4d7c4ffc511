#include "rephoto/mesh/obj.h"

#include <gmock/gmock.h>

#include <sstream>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/testing/testing.h"

namespace rephoto::mesh {
namespace {

using ::testing::HasSubstr;

TEST(ObjTest, ReadsQuadWithTextureAndNormals) {
  const auto dir = testing::MakeTempDir();
  WriteTextFileAtomically(dir / "quad.mtl",
                          "newmtl plain\nKd 0.5 0.25 1\n"
                          "newmtl textured\nKd 1 1 1\nmap_Kd textures/wall.png\n");
  WriteTextFileAtomically(dir / "quad.obj",
                          "mtllib quad.mtl\n"
                          "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\n"
                          "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                          "vn 0 0 1\nvn 0 0 -1\n"
                          "usemtl textured\n"
                          "f 1/1/1 2/2/1 3/3/1 4/4/1\n"
                          "usemtl plain\n"
                          "f 2/2/1 5/1/1 3/3/1\n");
  const Mesh mesh = ReadMesh(dir / "quad.obj");
  ASSERT_EQ(mesh.vertex_count(), 5u);
  ASSERT_EQ(mesh.face_count(), 3u);
  EXPECT_EQ(mesh.faces[0], (Triangle{0, 1, 2}));
  EXPECT_EQ(mesh.faces[1], (Triangle{0, 2, 3}));
  EXPECT_EQ(mesh.faces[2], (Triangle{1, 4, 2}));
  ASSERT_EQ(mesh.wedge_texcoords.size(), 9u);
  EXPECT_EQ(mesh.wedge_texcoords[4], Eigen::Vector2f(1, 1));
  EXPECT_EQ(mesh.wedge_texcoords[7], Eigen::Vector2f(0, 0));
  ASSERT_EQ(mesh.materials.size(), 2u);
  EXPECT_EQ(mesh.materials[0].diffuse, Eigen::Vector3f(0.5f, 0.25f, 1));
  EXPECT_EQ(mesh.materials[1].diffuse_texture, dir / "textures/wall.png");
  EXPECT_EQ(mesh.face_materials, (std::vector<int>{1, 1, 0}));
  ASSERT_EQ(mesh.normals.size(), 5u);
  EXPECT_EQ(mesh.normals[0], Eigen::Vector3f(0, 0, 1));
  EXPECT_TRUE(mesh.colors.empty());
  EXPECT_TRUE(mesh.is_textured());
}

TEST(ObjTest, VertexColorsAndErrors) {
  const auto dir = testing::MakeTempDir();
  WriteTextFileAtomically(dir / "c.obj", "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n");
  const Mesh mesh = ReadMesh(dir / "c.obj");
  ASSERT_EQ(mesh.colors.size(), 3u);
  EXPECT_EQ(mesh.colors[1], Eigen::Vector3f(0, 1, 0));

  WriteTextFileAtomically(dir / "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
  try {
    ReadMesh(dir / "bad.obj");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("bad.obj: "));
  }
  EXPECT_THROW(ReadMesh(dir / "missing.obj"), Error);
  WriteTextFileAtomically(dir / "model.stl", "solid x\n");
  EXPECT_THROW(ReadMesh(dir / "model.stl"), Error);
}

TEST(ObjTest, StreamsGiveTheSameMeshAsFiles) {
  std::istringstream obj(
      "mtllib anything.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
      "usemtl wall\nf 1/1 2/2 3/3\n");
  std::istringstream mtl("newmtl wall\nKd 0.5 0.5 0.5\nmap_Kd wall.png\n");
  const Mesh mesh = ReadObj(obj, "stream.obj", "/models", &mtl);
  ASSERT_EQ(mesh.face_count(), 1u);
  ASSERT_EQ(mesh.materials.size(), 1u);
  EXPECT_EQ(mesh.materials[0].diffuse_texture, std::filesystem::path("/models/wall.png"));
  EXPECT_EQ(mesh.face_materials, (std::vector<int>{0}));
  std::istringstream bad("v 0 0 0\nf 1 2 3\n");
  try {
    ReadObj(bad, "bad.obj");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("bad.obj: face 0: vertex index 1 out of range"));
  }
}

TEST(ObjTest, StatementsRephotoDoesNotUseAreIgnored) {
  // Skin weights, free-form curves, points and lines: tinyobjloader rejected the whole file
  // for "vw 0 -1 0.5" (negative joint) and converted "vw 1 5e30" to int (undefined behaviour).
  std::istringstream obj(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nvw 0 -1 0.5\nvw 1 55555555555555555555555555555000000\n"
      "vp 0.5\nl 1 2\np 3\nt crease 2/1/0 1 2\n  f 1 2 3\n");
  std::istringstream mtl("newmtl m\nKd 1 0 0\nillum 99999999999999999999\n");
  const Mesh mesh = ReadObj(obj, "weights.obj", "", &mtl);
  EXPECT_EQ(mesh.vertex_count(), 3u);
  EXPECT_EQ(mesh.face_count(), 1u);
}

}  // namespace
}  // namespace rephoto::mesh
