#include "ropes_sim/dataset_config.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>
#include <set>
#include <system_error>
#include <vector>

#include "json_config.hpp"
#include "ropes_core/file_io.hpp"
#include "ropes_core/json_text.hpp"
#include "ropes_core/package_share.hpp"
#include "ropes_core/plain_name.hpp"
#include "ropes_sim/intervention_sampler.hpp"

namespace ropes::sim {

namespace {

using Json = nlohmann::json;

using detail::fail;
using detail::number;

void only_fields(const Json& object, const std::set<std::string>& allowed, const std::string& file,
                 const std::string& where) {
  for (const auto& [key, value] : object.items()) {
    if (!allowed.count(key)) {
      std::string list;
      for (const auto& a : allowed)
        list += (list.empty() ? "" : ", ") + a;
      fail(file, where + "has an unknown field '" + key + "' (expected one of: " + list + ")");
    }
  }
}

const Json& required(const Json& object, const char* key, const std::string& file,
                     const std::string& where) {
  if (!object.contains(key))
    fail(file, where + "lacks the field '" + key + "'");
  return object[key];
}

std::int64_t integer(const Json& v, const std::string& file, const std::string& field,
                     std::int64_t lo, std::int64_t hi) {
  if (!v.is_number_integer() || v.get<std::int64_t>() < lo || v.get<std::int64_t>() > hi)
    fail(file, field + " is " + core::describe(v) + "; expected an integer in [" +
                   std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return v.get<std::int64_t>();
}

std::string text(const Json& v, const std::string& file, const std::string& field) {
  if (!v.is_string() || v.get<std::string>().empty())
    fail(file, field + " is " + core::describe(v) + "; expected a non-empty string");
  return v.get<std::string>();
}

Camera camera(const Json& v, const std::string& file, const std::string& field) {
  if (!v.is_object())
    fail(file, field + " is not an object");
  only_fields(v, {"name", "target", "distance", "yaw_deg", "pitch_deg", "fov_y_deg", "near", "far"},
              file, field + " ");
  Camera c;
  c.name = text(required(v, "name", file, field + " "), file, field + ".name");
  if (v.contains("target")) {
    const Json& t = v["target"];
    if (!t.is_array() || t.size() != 3)
      fail(file, field + ".target is " + core::describe(t) + "; expected [x, y, z]");
    for (int i = 0; i < 3; ++i)
      c.target[i] = number(t[static_cast<std::size_t>(i)], file, field + ".target");
  }
  const auto opt = [&](const char* key, double* out) {
    if (v.contains(key))
      *out = number(v[key], file, field + "." + key);
  };
  opt("distance", &c.distance);
  opt("yaw_deg", &c.yaw_deg);
  opt("pitch_deg", &c.pitch_deg);
  opt("fov_y_deg", &c.fov_y_deg);
  opt("near", &c.near);
  opt("far", &c.far);
  const std::string why = c.problem();
  if (!why.empty())
    fail(file, field + ": " + why);
  return c;
}

// a rig object: {name, cameras: [...]} and the other `allowed` fields
CameraRig rig_of(const Json& rig, const std::string& file, const std::string& field,
                 const std::set<std::string>& allowed) {
  only_fields(rig, allowed, file, field.empty() ? "" : field + " ");
  const std::string prefix = field.empty() ? "" : field + ".";
  CameraRig out;
  out.name =
      text(required(rig, "name", file, field.empty() ? "" : field + " "), file, prefix + "name");
  const Json& cameras = required(rig, "cameras", file, field.empty() ? "" : field + " ");
  if (!cameras.is_array() || cameras.empty())
    fail(file, prefix + "cameras is " + core::describe(cameras) + "; expected a non-empty array");
  for (std::size_t i = 0; i < cameras.size(); ++i)
    out.cameras.push_back(camera(cameras[i], file, prefix + "cameras[" + std::to_string(i) + "]"));
  return out;
}

std::string installed_rig_names() {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(installed_rigs_dir(), ec))
    if (e.path().extension() == ".json")
      names.push_back(e.path().stem().string());
  std::sort(names.begin(), names.end());
  std::string out;
  for (const std::string& n : names)
    out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? "none" : out;
}

std::filesystem::path relative_to(const std::filesystem::path& file, const std::string& value) {
  const std::filesystem::path p(value);
  return p.is_absolute() ? p : file.parent_path() / p;
}

Json camera_json(const Camera& c) {
  return Json{{"name", c.name},           {"target", {c.target.x(), c.target.y(), c.target.z()}},
              {"distance", c.distance},   {"yaw_deg", c.yaw_deg},
              {"pitch_deg", c.pitch_deg}, {"fov_y_deg", c.fov_y_deg},
              {"near", c.near},           {"far", c.far}};
}

}  // namespace

DatasetConfig DatasetConfig::load(const std::filesystem::path& path) {
  const std::string file = path.string();
  const Json config = detail::read_config_object(path, "dataset config");
  only_fields(config,
              {"name", "source", "notes", "distribution", "robot", "rig", "image", "anchors",
               "anchors_per_shard", "test_sets"},
              file, "");

  DatasetConfig c;
  c.file = path;
  c.name = text(required(config, "name", file, ""), file, "name");
  if (!core::is_plain_name(c.name)) {
    fail(file, "name is '" + c.name.substr(0, 64) +
                   "'; expected a plain name (letters, digits, '_', '-', '.', not starting "
                   "with '.'; at most 128 characters): tools name directories after it");
  }
  c.distribution =
      relative_to(path, text(required(config, "distribution", file, ""), file, "distribution"));
  if (!core::is_regular_file(c.distribution))
    fail(file, "distribution is '" + config["distribution"].get<std::string>() +
                   "': " + c.distribution.string() + " does not exist");
  c.robot = relative_to(path, text(required(config, "robot", file, ""), file, "robot"));
  if (!core::is_regular_file(c.robot))
    fail(file, "robot is '" + config["robot"].get<std::string>() + "': " + c.robot.string() +
                   " does not exist");

  const Json& rig = required(config, "rig", file, "");
  if (rig.is_string()) {
    const std::string value = rig.get<std::string>();
    const std::filesystem::path rig_file = find_rig(value, path);
    if (rig_file.empty())
      fail(file, "rig is \"" + value.substr(0, 128) +
                     "\"; expected the name of an installed rig (" + installed_rig_names() +
                     " in " + installed_rigs_dir().string() +
                     "), the path of a rig file relative to this config, or a rig object");
    c.rig = load_rig(rig_file);
  } else if (rig.is_object()) {
    c.rig = rig_of(rig, file, "rig", {"name", "cameras"});
  } else {
    fail(file, "rig is " + core::describe(rig) + "; expected a rig name, file or object");
  }
  const Json& image = required(config, "image", file, "");
  if (!image.is_object())
    fail(file, "image is " + core::describe(image) + "; expected {width, height}");
  only_fields(image, {"width", "height"}, file, "image ");
  c.rig.width = static_cast<int>(
      integer(required(image, "width", file, "image "), file, "image.width", 8, 4096));
  c.rig.height = static_cast<int>(
      integer(required(image, "height", file, "image "), file, "image.height", 8, 4096));
  const std::string why = c.rig.problem();
  if (!why.empty())
    fail(file, "rig: " + why);
  c.anchors = integer(required(config, "anchors", file, ""), file, "anchors", 1, 1LL << 40);
  c.anchors_per_shard = integer(required(config, "anchors_per_shard", file, ""), file,
                                "anchors_per_shard", 1, 1LL << 20);
  if (config.contains("test_sets")) {
    const Json& sets = config["test_sets"];
    if (!sets.is_object())
      fail(file, std::string("test_sets is a JSON ") + sets.type_name() +
                     "; expected an object of suites and dataset config names, "
                     "{\"id\": NAME, \"ood\": NAME, \"causal\": NAME}");
    for (const auto& [suite, name] : sets.items()) {
      if (suite != "id" && suite != "ood" && suite != "causal")
        fail(file,
             "test_sets has the suite '" + suite.substr(0, 64) + "'; expected id, ood or causal");
      const std::string n = text(name, file, "test_sets." + suite);
      if (!core::is_plain_name(n))
        fail(file, "test_sets." + suite + " is '" + n.substr(0, 64) +
                       "'; expected the name of an installed dataset config");
      c.test_sets[suite] = n;
    }
  }
  return c;
}

std::string DatasetConfig::to_json() const {
  Json cameras = Json::array();
  for (const Camera& cam : rig.cameras)
    cameras.push_back(camera_json(cam));
  const Json j{{"name", name},
               {"rig", {{"name", rig.name}, {"cameras", cameras}}},
               {"image", {{"width", rig.width}, {"height", rig.height}}},
               {"anchors", anchors},
               {"anchors_per_shard", anchors_per_shard}};
  return j.dump();
}

CameraRig load_rig(const std::filesystem::path& path) {
  const std::string file = path.string();
  const Json rig = detail::read_config_object(path, "rig");
  CameraRig out = rig_of(rig, file, "", {"name", "source", "notes", "cameras"});
  if (out.cameras.empty())
    fail(file, "cameras is empty; expected at least one camera");
  return out;
}

std::filesystem::path installed_rigs_dir() {
  return core::find_package_share("ropes_sim", "rigs", ROPES_SIM_INSTALL_SHARE_DIR) / "rigs";
}

std::filesystem::path find_rig(const std::string& name_or_path,
                               const std::filesystem::path& config_file) {
  const bool is_path = name_or_path.find('/') != std::string::npos ||
                       std::filesystem::path(name_or_path).extension() == ".json";
  if (is_path) {
    const std::filesystem::path p = relative_to(config_file, name_or_path);
    return core::is_regular_file(p) ? p : std::filesystem::path();
  }
  if (!core::is_plain_name(name_or_path))
    return {};
  const std::filesystem::path p = installed_rigs_dir() / (name_or_path + ".json");
  return core::is_regular_file(p) ? p : std::filesystem::path();
}

std::filesystem::path installed_dataset_configs_dir() {
  return core::find_package_share("ropes_sim", "datasets", ROPES_SIM_INSTALL_SHARE_DIR) /
         "datasets";
}

std::filesystem::path find_dataset_config(const std::string& name_or_path) {
  if (core::is_regular_file(name_or_path))
    return name_or_path;
  // a name may come from a manifest someone else wrote: never a path out of the directory
  if (!core::is_plain_name(name_or_path))
    return {};
  const std::filesystem::path p = installed_dataset_configs_dir() / (name_or_path + ".json");
  return core::is_regular_file(p) ? p : std::filesystem::path();
}

}  // namespace ropes::sim
