#include "ropes_sim/mesh.hpp"

#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <system_error>

#include "ropes_core/file_io.hpp"

namespace ropes::sim {

namespace {

using Vec3 = Eigen::Vector3f;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string read_text(const std::filesystem::path& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw MeshError(path.string() + ": cannot open the " + what);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// whitespace-separated tokens of one line
std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i])))
      ++i;
    std::size_t j = i;
    while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j])))
      ++j;
    if (j > i)
      out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

// a parser's position for messages: "file:line"
struct Where {
  const std::filesystem::path& file;
  int line;
  std::string str() const { return file.string() + ":" + std::to_string(line); }
};

float parse_float(std::string_view token, const Where& where) {
  double value = 0.0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec != std::errc() || end != token.data() + token.size() || !std::isfinite(value))
    throw MeshError(where.str() + ": '" + std::string(token) + "' is not a finite number");
  return static_cast<float>(value);
}

Vec3 parse_vec3(const std::vector<std::string_view>& t, const Where& where) {
  if (t.size() < 4)
    throw MeshError(where.str() + ": '" + std::string(t[0]) + "' needs 3 numbers, got " +
                    std::to_string(t.size() - 1));
  return Vec3(parse_float(t[1], where), parse_float(t[2], where), parse_float(t[3], where));
}

std::shared_ptr<const Texture> load_texture(const std::filesystem::path& path, const Where& where) {
  const cv::Mat bgr = cv::imread(path.string(), cv::IMREAD_COLOR);
  if (bgr.empty())
    throw MeshError(where.str() + ": texture '" + path.string() +
                    "' does not exist or is not an image OpenCV can read");
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  auto texture = std::make_shared<Texture>();
  texture->width = rgb.cols;
  texture->height = rgb.rows;
  texture->rgb.resize(static_cast<std::size_t>(rgb.cols) * rgb.rows * 3);
  for (int y = 0; y < rgb.rows; ++y)
    std::memcpy(texture->rgb.data() + static_cast<std::size_t>(y) * rgb.cols * 3, rgb.ptr(y),
                static_cast<std::size_t>(rgb.cols) * 3);
  return texture;
}

// materials of one MTL file: newmtl, Kd, map_Kd (the last token is the file name)
void load_mtl(const std::filesystem::path& path, const Where& from,
              std::map<std::string, Material>* materials, std::vector<std::string>* warnings) {
  if (!core::is_regular_file(path)) {
    warnings->push_back(from.str() + ": material library '" + path.string() +
                        "' does not exist; its materials are drawn plain white");
    return;
  }
  const std::string text = read_text(path, "material library");
  std::istringstream lines(text);
  std::string line;
  Material* current = nullptr;
  for (int n = 1; std::getline(lines, line); ++n) {
    const Where where{path, n};
    const auto t = split(line);
    if (t.empty() || t[0][0] == '#')
      continue;
    if (t[0] == "newmtl") {
      if (t.size() < 2)
        throw MeshError(where.str() + ": 'newmtl' without a name");
      const std::string name(t[1]);
      current = &(*materials)[name];
      current->name = name;
    } else if (t[0] == "Kd" || t[0] == "map_Kd") {
      if (!current)
        throw MeshError(where.str() + ": '" + std::string(t[0]) + "' before newmtl");
      if (t[0] == "Kd") {
        current->diffuse = parse_vec3(t, where);
      } else {
        if (t.size() < 2)
          throw MeshError(where.str() + ": 'map_Kd' without a file name");
        const std::filesystem::path texture = path.parent_path() / std::string(t.back());
        if (core::is_regular_file(texture)) {
          current->texture = load_texture(texture, where);
        } else {
          warnings->push_back(where.str() + ": texture '" + texture.string() +
                              "' does not exist; drawn without it");
        }
      }
    }
  }
}

void append_vertex(std::vector<float>* out, const Vec3& p, const Vec3& n, float u, float v) {
  out->insert(out->end(), {p.x(), p.y(), p.z(), n.x(), n.y(), n.z(), u, v});
}

Vec3 flat_normal(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = (b - a).cross(c - a);
  const float norm = n.norm();
  return norm > 0.0f ? Vec3(n / norm) : Vec3(0.0f, 0.0f, 1.0f);
}

// one f-record corner "v", "v/t", "v//n" or "v/t/n": 0-based indices, -1 when absent
struct Corner {
  int v = -1, t = -1, n = -1;
};

int parse_index(std::string_view token, int count, const char* what, const Where& where) {
  long value = 0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec != std::errc() || end != token.data() + token.size() || value == 0)
    throw MeshError(where.str() + ": '" + std::string(token) + "' is not a valid " + what +
                    " index");
  const long index = value > 0 ? value - 1 : count + value;
  if (index < 0 || index >= count)
    throw MeshError(where.str() + ": " + what + " index " + std::to_string(value) +
                    " is out of range (" + std::to_string(count) + " defined so far)");
  return static_cast<int>(index);
}

Mesh load_obj(const std::filesystem::path& path) {
  const std::string text = read_text(path, "OBJ file");
  std::vector<Vec3> positions, normals;
  std::vector<Eigen::Vector2f> uvs;
  std::map<std::string, Material> library;
  std::vector<std::string> warnings;
  // triangles per material, in the order materials are first used
  std::vector<Material> used;
  std::vector<std::vector<float>> streams;
  std::map<std::string, int> used_index;
  int current = -1;
  const auto use = [&](const std::string& name, const Material& m) {
    const auto [it, inserted] = used_index.emplace(name, static_cast<int>(used.size()));
    if (inserted) {
      used.push_back(m);
      streams.emplace_back();
    }
    current = it->second;
  };

  std::istringstream lines(text);
  std::string line;
  for (int n = 1; std::getline(lines, line); ++n) {
    const Where where{path, n};
    const auto t = split(line);
    if (t.empty() || t[0][0] == '#')
      continue;
    if (t[0] == "v") {
      positions.push_back(parse_vec3(t, where));
    } else if (t[0] == "vn") {
      normals.push_back(parse_vec3(t, where));
    } else if (t[0] == "vt") {
      if (t.size() < 3)
        throw MeshError(where.str() + ": 'vt' needs 2 numbers");
      uvs.emplace_back(parse_float(t[1], where), parse_float(t[2], where));
    } else if (t[0] == "mtllib") {
      for (std::size_t i = 1; i < t.size(); ++i)
        load_mtl(path.parent_path() / std::string(t[i]), where, &library, &warnings);
    } else if (t[0] == "usemtl") {
      if (t.size() < 2)
        throw MeshError(where.str() + ": 'usemtl' without a name");
      const std::string name(t[1]);
      const auto it = library.find(name);
      if (it == library.end()) {
        warnings.push_back(where.str() + ": material '" + name +
                           "' is not defined by any material library; drawn plain white");
        Material plain;
        plain.name = name;
        use(name, plain);
      } else {
        use(name, it->second);
      }
    } else if (t[0] == "f") {
      if (t.size() < 4)
        throw MeshError(where.str() + ": a face needs at least 3 corners, got " +
                        std::to_string(t.size() - 1));
      if (current < 0)
        use("", Material{});
      std::vector<Corner> corners;
      for (std::size_t i = 1; i < t.size(); ++i) {
        const std::string_view c = t[i];
        const std::size_t s1 = c.find('/');
        const std::size_t s2 = s1 == std::string_view::npos ? s1 : c.find('/', s1 + 1);
        Corner corner;
        corner.v =
            parse_index(c.substr(0, s1), static_cast<int>(positions.size()), "vertex", where);
        if (s1 != std::string_view::npos) {
          const std::string_view tt = c.substr(s1 + 1, s2 == s1 ? s2 : s2 - s1 - 1);
          if (!tt.empty())
            corner.t = parse_index(tt, static_cast<int>(uvs.size()), "texture", where);
          if (s2 != std::string_view::npos)
            corner.n =
                parse_index(c.substr(s2 + 1), static_cast<int>(normals.size()), "normal", where);
        }
        corners.push_back(corner);
      }
      // fan the polygon into triangles
      for (std::size_t i = 1; i + 1 < corners.size(); ++i) {
        const Corner tri[3] = {corners[0], corners[i], corners[i + 1]};
        const Vec3 flat =
            flat_normal(positions[tri[0].v], positions[tri[1].v], positions[tri[2].v]);
        for (const Corner& k : tri) {
          const Vec3 normal = k.n >= 0 ? normals[k.n].normalized() : flat;
          const Eigen::Vector2f uv = k.t >= 0 ? uvs[k.t] : Eigen::Vector2f::Zero();
          append_vertex(&streams[current], positions[k.v], normal.allFinite() ? normal : flat,
                        uv.x(), uv.y());
        }
      }
    }
  }
  Mesh mesh;
  for (std::size_t m = 0; m < used.size(); ++m) {
    if (streams[m].empty())
      continue;
    MeshPart part;
    part.first = mesh.vertex_count();
    part.count = static_cast<int>(streams[m].size()) / Mesh::kFloatsPerVertex;
    part.material = static_cast<int>(mesh.materials.size());
    mesh.materials.push_back(used[m]);
    mesh.parts.push_back(part);
    mesh.vertices.insert(mesh.vertices.end(), streams[m].begin(), streams[m].end());
  }
  if (mesh.parts.empty())
    throw MeshError(path.string() + ": the OBJ file has no faces");
  mesh.warnings = std::move(warnings);
  return mesh;
}

Mesh single_part(std::vector<float> vertices) {
  Mesh mesh;
  mesh.vertices = std::move(vertices);
  mesh.materials.push_back(Material{});
  mesh.parts.push_back(MeshPart{0, mesh.vertex_count(), 0});
  return mesh;
}

Mesh load_stl(const std::filesystem::path& path) {
  const std::string data = read_text(path, "STL file");
  std::vector<float> out;
  const auto triangle = [&](const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 n = flat_normal(a, b, c);
    for (const Vec3* p : {&a, &b, &c})
      append_vertex(&out, *p, n, 0.0f, 0.0f);
  };
  std::uint32_t count = 0;
  if (data.size() >= 84)
    std::memcpy(&count, data.data() + 80, 4);
  if (data.size() >= 84 && data.size() == 84 + 50ull * count) {
    // binary: 80-byte header, count, then per triangle normal + 3 vertices (float32) + 2 bytes
    for (std::uint32_t i = 0; i < count; ++i) {
      float f[12];
      std::memcpy(f, data.data() + 84 + 50ull * i, sizeof f);
      triangle(Vec3(f[3], f[4], f[5]), Vec3(f[6], f[7], f[8]), Vec3(f[9], f[10], f[11]));
    }
  } else if (data.compare(0, 5, "solid") == 0) {
    std::istringstream lines(data);
    std::string line;
    std::vector<Vec3> corners;
    for (int n = 1; std::getline(lines, line); ++n) {
      const auto t = split(line);
      if (t.empty())
        continue;
      if (t[0] == "vertex")
        corners.push_back(parse_vec3(t, Where{path, n}));
      if (t[0] == "endfacet") {
        if (corners.size() != 3)
          throw MeshError(Where{path, n}.str() + ": a facet needs 3 vertices, got " +
                          std::to_string(corners.size()));
        triangle(corners[0], corners[1], corners[2]);
        corners.clear();
      }
    }
  } else {
    throw MeshError(path.string() + ": neither a binary STL (size " + std::to_string(data.size()) +
                    " bytes does not match its triangle count) nor an ASCII STL ('solid ...')");
  }
  if (out.empty())
    throw MeshError(path.string() + ": the STL file has no triangles");
  return single_part(std::move(out));
}

}  // namespace

Mesh load_mesh(const std::filesystem::path& path) {
  if (!core::is_regular_file(path))
    throw MeshError(path.string() + ": mesh file does not exist");
  const std::string ext = lower(path.extension().string());
  if (ext == ".obj")
    return load_obj(path);
  if (ext == ".stl")
    return load_stl(path);
  throw MeshError(path.string() + ": unsupported mesh format '" + ext +
                  "' (expected .obj or .stl)");
}

Mesh make_box(const Eigen::Vector3d& size) {
  const Vec3 h = (size / 2).cast<float>();
  std::vector<float> out;
  // each face: its normal axis and sign; corners counter-clockwise seen from outside
  for (int axis = 0; axis < 3; ++axis) {
    for (float sign : {1.0f, -1.0f}) {
      Vec3 n = Vec3::Zero();
      n[axis] = sign;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      Vec3 corner[4];
      const float su[4] = {-1, 1, 1, -1}, sv[4] = {-1, -1, 1, 1};
      for (int k = 0; k < 4; ++k) {
        corner[k][axis] = sign * h[axis];
        corner[k][u] = su[k] * h[u] * sign;
        corner[k][v] = sv[k] * h[v];
      }
      for (int k : {0, 1, 2, 0, 2, 3})
        append_vertex(&out, corner[k], n, 0.0f, 0.0f);
    }
  }
  return single_part(std::move(out));
}

Mesh make_cylinder(double radius, double length, int segments) {
  const float r = static_cast<float>(radius), hz = static_cast<float>(length / 2);
  std::vector<float> out;
  for (int i = 0; i < segments; ++i) {
    const double a0 = 2 * M_PI * i / segments, a1 = 2 * M_PI * (i + 1) / segments;
    const Vec3 n0(static_cast<float>(std::cos(a0)), static_cast<float>(std::sin(a0)), 0);
    const Vec3 n1(static_cast<float>(std::cos(a1)), static_cast<float>(std::sin(a1)), 0);
    const Vec3 b0 = r * n0 - Vec3(0, 0, hz), b1 = r * n1 - Vec3(0, 0, hz);
    const Vec3 t0 = r * n0 + Vec3(0, 0, hz), t1 = r * n1 + Vec3(0, 0, hz);
    // side
    append_vertex(&out, b0, n0, 0, 0);
    append_vertex(&out, b1, n1, 0, 0);
    append_vertex(&out, t1, n1, 0, 0);
    append_vertex(&out, b0, n0, 0, 0);
    append_vertex(&out, t1, n1, 0, 0);
    append_vertex(&out, t0, n0, 0, 0);
    // caps
    const Vec3 up(0, 0, 1);
    append_vertex(&out, Vec3(0, 0, hz), up, 0, 0);
    append_vertex(&out, t0, up, 0, 0);
    append_vertex(&out, t1, up, 0, 0);
    append_vertex(&out, Vec3(0, 0, -hz), -up, 0, 0);
    append_vertex(&out, b1, -up, 0, 0);
    append_vertex(&out, b0, -up, 0, 0);
  }
  return single_part(std::move(out));
}

Mesh make_sphere(double radius, int segments) {
  const int rings = std::max(segments / 2, 2);
  const auto point = [&](int ring, int seg) {
    const double theta = M_PI * ring / rings, phi = 2 * M_PI * seg / segments;
    return Vec3(static_cast<float>(std::sin(theta) * std::cos(phi)),
                static_cast<float>(std::sin(theta) * std::sin(phi)),
                static_cast<float>(std::cos(theta)));
  };
  const float r = static_cast<float>(radius);
  std::vector<float> out;
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const Vec3 a = point(i, j), b = point(i + 1, j), c = point(i + 1, j + 1), d = point(i, j + 1);
      if (i > 0) {
        for (const Vec3* p : {&a, &b, &d})
          append_vertex(&out, r * *p, *p, 0, 0);
      }
      if (i + 1 < rings) {
        for (const Vec3* p : {&d, &b, &c})
          append_vertex(&out, r * *p, *p, 0, 0);
      }
    }
  }
  return single_part(std::move(out));
}

}  // namespace ropes::sim
