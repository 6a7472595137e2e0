#include "ropes_sim/mesh.hpp"

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>

#include <cstring>
#include <fstream>

namespace ropes::sim {
namespace {

namespace fs = std::filesystem;

fs::path mesh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("ropes_sim_mesh_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void write(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

std::string error_of(const fs::path& path) {
  try {
    load_mesh(path);
  } catch (const MeshError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Mesh, ObjWithMaterialsTextureQuadsAndNegativeIndices) {
  const fs::path dir = mesh_dir("obj");
  cv::Mat texture(2, 2, CV_8UC3, cv::Scalar(0, 0, 255));  // BGR: red
  ASSERT_TRUE(cv::imwrite((dir / "red.png").string(), texture));
  write(dir / "m.mtl", "newmtl grey\nKd 0.5 0.5 0.5\n\nnewmtl tex\nKd 1 1 1\nmap_Kd red.png\n");
  write(dir / "m.obj",
        "# a quad and a triangle\nmtllib m.mtl\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 1\nvn 0 0 1\n"
        "usemtl grey\nf 1/1/1 2/1/1 3/2/1 4/2/1\n"
        "usemtl tex\nf -4 -3 -1\n");
  const Mesh mesh = load_mesh(dir / "m.obj");
  ASSERT_EQ(mesh.parts.size(), 2u);
  EXPECT_EQ(mesh.parts[0].count, 6);  // the quad, fanned
  EXPECT_EQ(mesh.parts[1].count, 3);
  EXPECT_EQ(mesh.vertex_count(), 9);
  EXPECT_FLOAT_EQ(mesh.materials[0].diffuse.x(), 0.5f);
  ASSERT_TRUE(mesh.materials[1].texture);
  EXPECT_EQ(mesh.materials[1].texture->width, 2);
  EXPECT_EQ(mesh.materials[1].texture->rgb[0], 255);  // R of an RGB texel
  EXPECT_EQ(mesh.materials[1].texture->rgb[2], 0);
  // the triangle without normals gets its flat normal, +z for this winding
  const float* v = mesh.vertices.data() + 6 * Mesh::kFloatsPerVertex;
  EXPECT_FLOAT_EQ(v[5], 1.0f);
  EXPECT_TRUE(mesh.warnings.empty());
}

TEST(Mesh, MissingMaterialLibraryIsAWarningNotAnError) {
  const fs::path dir = mesh_dir("nomtl");
  write(dir / "m.obj", "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n");
  const Mesh mesh = load_mesh(dir / "m.obj");
  ASSERT_EQ(mesh.warnings.size(), 2u);
  EXPECT_NE(mesh.warnings[0].find("gone.mtl"), std::string::npos);
  EXPECT_EQ(mesh.materials[0].diffuse, Eigen::Vector3f::Ones());
  // a texture that is not there: the material keeps its colour, without a texture
  write(dir / "t.mtl", "newmtl grey\nKd 0.5 0.5 0.5\nmap_Kd gone.png\n");
  write(dir / "t.obj", "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl grey\nf 1 2 3\n");
  const Mesh textured = load_mesh(dir / "t.obj");
  ASSERT_EQ(textured.warnings.size(), 1u);
  EXPECT_NE(textured.warnings[0].find("t.mtl:3: texture"), std::string::npos)
      << textured.warnings[0];
  EXPECT_FALSE(textured.materials[0].texture);
  EXPECT_FLOAT_EQ(textured.materials[0].diffuse.x(), 0.5f);
}

// found by fuzz/mesh: a material library or texture whose name the file system refuses
// (longer than NAME_MAX) threw filesystem_error out of load_mesh; it is a missing file
TEST(Mesh, AMaterialFileNameTooLongIsAMissingFile) {
  const fs::path dir = mesh_dir("longname");
  const std::string name(300, 'm');
  write(dir / "m.obj", "mtllib " + name + ".mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const Mesh mesh = load_mesh(dir / "m.obj");
  ASSERT_EQ(mesh.warnings.size(), 1u);
  EXPECT_NE(mesh.warnings[0].find(name), std::string::npos) << mesh.warnings[0];
  write(dir / "t.mtl", "newmtl grey\nmap_Kd " + name + ".png\n");
  write(dir / "t.obj", "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl grey\nf 1 2 3\n");
  EXPECT_EQ(load_mesh(dir / "t.obj").warnings.size(), 1u);
  EXPECT_NE(error_of(dir / (name + ".obj")).find("does not exist"), std::string::npos)
      << error_of(dir / (name + ".obj"));
}

TEST(Mesh, BadObjFilesNameTheFileAndLine) {
  const fs::path dir = mesh_dir("bad");
  write(dir / "range.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n");
  EXPECT_NE(error_of(dir / "range.obj").find("range.obj:3: vertex index 3 is out of range"),
            std::string::npos)
      << error_of(dir / "range.obj");
  write(dir / "number.obj", "v 0 zero 0\n");
  EXPECT_NE(error_of(dir / "number.obj").find("number.obj:1: 'zero' is not a finite number"),
            std::string::npos);
  write(dir / "empty.obj", "v 0 0 0\n");
  EXPECT_NE(error_of(dir / "empty.obj").find("has no faces"), std::string::npos);
  EXPECT_NE(error_of(dir / "missing.obj").find("missing.obj: mesh file does not exist"),
            std::string::npos);
  write(dir / "shape.dae", "<collada/>");
  EXPECT_NE(error_of(dir / "shape.dae").find("unsupported mesh format '.dae'"), std::string::npos);
}

TEST(Mesh, BinaryAndAsciiStlGiveTheSameTriangles) {
  const fs::path dir = mesh_dir("stl");
  write(dir / "a.stl",
        "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
        "endloop\nendfacet\nendsolid t\n");
  std::string binary(80, ' ');
  const std::uint32_t count = 1;
  binary.append(reinterpret_cast<const char*>(&count), 4);
  const float f[12] = {0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0};
  binary.append(reinterpret_cast<const char*>(f), sizeof f);
  binary.append(2, '\0');
  write(dir / "b.STL", binary);
  const Mesh a = load_mesh(dir / "a.stl"), b = load_mesh(dir / "b.STL");
  EXPECT_EQ(a.vertices, b.vertices);
  EXPECT_EQ(a.vertex_count(), 3);
  EXPECT_FLOAT_EQ(a.vertices[5], 1.0f);  // flat normal +z
  write(dir / "c.stl", "not an stl");
  EXPECT_NE(error_of(dir / "c.stl").find("neither a binary STL"), std::string::npos);
}

// the primitives are closed and wound outwards: the divergence theorem gives their volume
double volume(const Mesh& m) {
  double v = 0;
  for (int t = 0; t < m.vertex_count(); t += 3) {
    Eigen::Vector3d p[3];
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 3; ++i)
        p[k][i] = m.vertices[static_cast<std::size_t>((t + k) * Mesh::kFloatsPerVertex + i)];
    v += p[0].dot(p[1].cross(p[2])) / 6.0;
  }
  return v;
}

TEST(Mesh, PrimitivesAreClosedAndOutwardWound) {
  EXPECT_NEAR(volume(make_box(Eigen::Vector3d(1, 2, 3))), 6.0, 1e-5);
  EXPECT_NEAR(volume(make_cylinder(0.5, 2.0, 256)), M_PI * 0.25 * 2.0, 1e-3);
  EXPECT_NEAR(volume(make_sphere(1.0, 256)), 4.0 / 3.0 * M_PI, 2e-3);
}

}  // namespace
}  // namespace ropes::sim
