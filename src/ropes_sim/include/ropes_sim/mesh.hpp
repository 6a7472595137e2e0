#pragma once
/// @file mesh.hpp
/// Mesh: a triangle mesh ready for the renderer, with its materials: loaded from an OBJ file
/// (with its MTL materials and map_Kd textures) or a binary/ASCII STL file, or built from a
/// primitive (box, cylinder, sphere).

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace ropes::sim {

/// An 8-bit RGB image, rows top to bottom: rgb[(y * width + x) * 3 + c].
struct Texture {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;
};

/// The colour of a mesh part: `diffuse` (linear 0..1 RGB; MTL's Kd) times the texture's
/// colour at the vertex's uv when `texture` is set.
struct Material {
  std::string name;
  Eigen::Vector3f diffuse = Eigen::Vector3f::Ones();
  std::shared_ptr<const Texture> texture;
};

/// Triangles [first, first + count) (in vertices) drawn with materials[material].
struct MeshPart {
  int first = 0, count = 0, material = 0;
};

/// A triangle list: vertex v's attributes are vertices[v * 8 .. v * 8 + 8) = position xyz
/// (mesh frame, metres), unit normal xyz, texture uv. Three consecutive vertices make a
/// triangle, wound counter-clockwise seen from outside.
struct Mesh {
  static constexpr int kFloatsPerVertex = 8;
  std::vector<float> vertices;
  std::vector<MeshPart> parts;
  std::vector<Material> materials;
  /// What was read but could not be used (a material library, material or texture that
  /// does not exist, drawn plain white instead, as PyBullet does), "file:line: ..." each.
  std::vector<std::string> warnings;

  int vertex_count() const { return static_cast<int>(vertices.size()) / kFloatsPerVertex; }
};

/// Thrown for a mesh file that cannot be used; the message names the file (and line).
class MeshError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Loads an OBJ (.obj) or STL (.stl) file; the extension decides, case-insensitively.
/// OBJ: v, vt, vn and f records (polygons are fanned into triangles, negative indices count
/// from the end), mtllib/usemtl with Kd and map_Kd (PNG/JPEG, through OpenCV); a face without
/// normals gets its flat normal. STL: binary or ASCII, flat normals. Throws MeshError naming
/// the file, the line and the record for a missing file, an index out of range, a bad
/// number or a mesh without triangles; a missing material library, material or texture is
/// a warning (Mesh::warnings), not an error.
Mesh load_mesh(const std::filesystem::path& path);

/// A box with full extents `size`, centred at the origin.
Mesh make_box(const Eigen::Vector3d& size);
/// A closed cylinder of `radius` and `length` along z, centred at the origin, with
/// `segments` facets around (smooth normals on the side).
Mesh make_cylinder(double radius, double length, int segments = 32);
/// A UV sphere of `radius` at the origin.
Mesh make_sphere(double radius, int segments = 24);

}  // namespace ropes::sim
