// mesh_fuzz: load_mesh on arbitrary OBJ (with its material library) and STL files. The
// input's sections (ropes_core/fuzz_input.hpp): "" is mesh.obj, "mtl" is mesh.mtl (what the
// corpus OBJ names in mtllib), "stl" is mesh.stl (binary or ASCII). Each loads, giving
// whole triangles whose indices stay inside the vertices, or is refused with a MeshError.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <string>

#include "ropes_core/fuzz_input.hpp"
#include "ropes_sim/mesh.hpp"

namespace {

// whole triangles, parts inside them, materials that exist, textures of their stated size
void check(const ropes::sim::Mesh& mesh) {
  const int vertices = mesh.vertex_count();
  if (mesh.vertices.size() % ropes::sim::Mesh::kFloatsPerVertex != 0 || vertices % 3 != 0)
    std::abort();
  for (const ropes::sim::MeshPart& part : mesh.parts)
    if (part.first < 0 || part.count < 0 || part.first + part.count > vertices ||
        part.material < 0 || part.material >= static_cast<int>(mesh.materials.size()))
      std::abort();
  for (const ropes::sim::Material& m : mesh.materials)
    if (m.texture && m.texture->rgb.size() != static_cast<std::size_t>(m.texture->width) *
                                                  static_cast<std::size_t>(m.texture->height) * 3)
      std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes;
  static const core::fuzz::ScratchDir scratch;
  static const std::map<std::string, std::string> files = {
      {"", "mesh.obj"}, {"mtl", "mesh.mtl"}, {"stl", "mesh.stl"}};
  scratch.clear();
  bool stl = false;
  for (const core::fuzz::Section& section : core::fuzz::split_sections(data, size)) {
    const auto it = files.find(section.name);
    if (it != files.end())
      scratch.write(it->second, section.bytes);
    stl = stl || section.name == "stl";
  }
  try {
    check(sim::load_mesh(scratch.path() / "mesh.obj"));
  } catch (const sim::MeshError&) {
  }
  if (stl) {
    try {
      check(sim::load_mesh(scratch.path() / "mesh.stl"));
    } catch (const sim::MeshError&) {
    }
  }
  return 0;
}
