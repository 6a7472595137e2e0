// ropes._sim: the simulator (ropes_sim) for Python: URDF, forward kinematics, rendering a
// dataset config's rig, generating datasets. The pure-Python module ropes.sim
// (python/ropes/sim.py) is what users import.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ropes_core/python.hpp"
#include "ropes_sim/dataset_config.hpp"
#include "ropes_sim/dataset_generator.hpp"
#include "ropes_sim/kinematics.hpp"
#include "ropes_sim/mesh.hpp"
#include "ropes_sim/renderer.hpp"
#include "ropes_sim/rig_renderer.hpp"
#include "ropes_sim/robot_model.hpp"

namespace py = pybind11;
namespace sim = ropes::sim;
namespace rp = ropes::python;

namespace {

// a URDF's model and its Simbody kinematics
struct Robot {
  explicit Robot(const std::string& urdf)
      : model(sim::RobotModel::load(urdf)), kinematics(std::make_unique<sim::Kinematics>(model)) {}
  sim::RobotModel model;
  std::unique_ptr<sim::Kinematics> kinematics;

  std::vector<std::string> joint_names() const {
    std::vector<std::string> out;
    for (int j : model.movable_joints())
      out.push_back(model.joints()[static_cast<std::size_t>(j)].name);
    return out;
  }

  // X_WL of every link for coordinates q: [links, 4, 4]
  py::array forward_kinematics(const py::handle& q_obj) {
    const std::int64_t n = static_cast<std::int64_t>(model.movable_joints().size());
    const auto q = rp::require_array<double>(q_obj, "q", {n}, {"joints"});
    kinematics->set_positions(std::vector<double>(q.data(), q.data() + q.size()));
    const std::vector<Eigen::Isometry3d> poses = kinematics->link_poses();
    std::vector<double> out;
    out.reserve(poses.size() * 16);
    for (const Eigen::Isometry3d& X : poses) {
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c)
          out.push_back(X.matrix()(r, c));
    }
    return rp::to_numpy(std::move(out), {static_cast<py::ssize_t>(poses.size()), 4, 4});
  }
};

sim::DatasetConfig load_config(const py::handle& name_or_path_obj) {
  const std::string name_or_path = rp::fspath(name_or_path_obj);
  const std::filesystem::path file = sim::find_dataset_config(name_or_path);
  if (file.empty()) {
    throw ropes::core::ConfigError("dataset config '" + name_or_path +
                                   "' is neither a file nor an installed config name (in " +
                                   sim::installed_dataset_configs_dir().string() + ")");
  }
  return sim::DatasetConfig::load(file);
}

// every camera of the rig for each row of q [n, joints]: [n, cameras, height, width]
py::array render_batch(sim::RigRenderer& r, const py::handle& q_obj, bool masks) {
  const auto joints = static_cast<std::int64_t>(r.joint_names().size());
  const auto q = rp::require_array<double>(q_obj, "q", {-1, joints}, {"n", "joints"});
  const py::ssize_t n = q.shape(0);
  py::array_t<std::uint8_t> out({n, static_cast<py::ssize_t>(r.cameras()),
                                 static_cast<py::ssize_t>(r.height()),
                                 static_cast<py::ssize_t>(r.width())});
  std::uint8_t* pixels = out.mutable_data();
  const double* angles = q.data();
  {
    py::gil_scoped_release release;  // the OSMesa context stays on this thread
    for (py::ssize_t i = 0; i < n; ++i) {
      const std::vector<double> row(angles + i * joints, angles + (i + 1) * joints);
      std::uint8_t* frame = pixels + static_cast<std::size_t>(i) * r.frame_bytes();
      if (masks)
        r.robot_masks(row, frame);
      else
        r.render(row, frame);
    }
  }
  return out;
}

py::dict generate(const sim::DatasetConfig& config, const std::string& out, std::uint64_t seed,
                  int threads, int shard_index, int shard_count, const py::object& progress) {
  rp::Callback callback(progress);
  sim::GenerateOptions options;
  options.out = out;
  options.seed = seed;
  options.threads = threads;
  options.shard_index = shard_index;
  options.shard_count = shard_count;
  bool go_on = true;
  options.progress = [&](int done, int total, const std::string& message) {
    go_on = callback([&] { return py::make_tuple(done, total, message); });
  };
  options.keep_going = [&] { return go_on; };
  sim::GenerateResult result;
  {
    py::gil_scoped_release release;
    result = sim::generate_dataset(config, options);
  }
  const bool stopped = callback.finish();  // re-raises what the callback raised
  py::dict d;
  d["shards_written"] = result.shards_written;
  d["shards_skipped"] = result.shards_skipped;
  d["complete"] = result.complete;
  d["images"] = result.images;
  d["warnings"] = result.warnings;
  d["stopped"] = stopped;
  return d;
}

}  // namespace

PYBIND11_MODULE(_sim, m) {
  m.doc() = "ropes._sim: the simulator (use ropes.sim)";
  rp::translate_core_exceptions();
  rp::translate_exception<sim::ModelError>("ModelError");
  rp::translate_exception<sim::MeshError>("MeshError");
  rp::translate_exception<sim::RenderError>("RenderError");

  py::class_<Robot>(m, "Robot")
      .def(py::init<const std::string&>(), py::arg("urdf"))
      .def_property_readonly("name", [](const Robot& r) { return r.model.name(); })
      .def_property_readonly("source", [](const Robot& r) { return r.model.source(); })
      .def_property_readonly("links",
                             [](const Robot& r) {
                               std::vector<std::string> out;
                               for (const sim::Link& l : r.model.links())
                                 out.push_back(l.name);
                               return out;
                             })
      .def_property_readonly("joints", &Robot::joint_names)
      .def_property_readonly("limits",
                             [](const Robot& r) {
                               std::vector<double> out;
                               for (int j : r.model.movable_joints()) {
                                 const sim::Joint& joint =
                                     r.model.joints()[static_cast<std::size_t>(j)];
                                 out.push_back(joint.lower);
                                 out.push_back(joint.upper);
                               }
                               const auto n = static_cast<py::ssize_t>(out.size() / 2);
                               return rp::to_numpy(std::move(out), {n, 2});
                             })
      .def("forward_kinematics", &Robot::forward_kinematics, py::arg("q"));

  py::class_<sim::DatasetConfig>(m, "DatasetConfig")
      .def_static("load", &load_config, py::arg("name_or_path"))
      .def_readonly("name", &sim::DatasetConfig::name)
      .def_property_readonly("file", [](const sim::DatasetConfig& c) { return c.file.string(); })
      .def_property_readonly("robot", [](const sim::DatasetConfig& c) { return c.robot.string(); })
      .def_property_readonly("distribution",
                             [](const sim::DatasetConfig& c) { return c.distribution.string(); })
      .def_readonly("anchors", &sim::DatasetConfig::anchors)
      .def_readonly("anchors_per_shard", &sim::DatasetConfig::anchors_per_shard)
      .def_readonly("test_sets", &sim::DatasetConfig::test_sets)
      .def_property_readonly("shard_count", &sim::DatasetConfig::shard_count)
      .def("to_dict", [](const sim::DatasetConfig& c) {
        return rp::to_python(nlohmann::json::parse(c.to_json()));
      });

  py::class_<sim::RigRenderer>(m, "RigRenderer")
      .def(py::init<const sim::DatasetConfig&>(), py::arg("config"))
      .def_property_readonly("joint_names", &sim::RigRenderer::joint_names)
      .def_property_readonly("camera_names", &sim::RigRenderer::camera_names)
      .def_property_readonly("cameras", &sim::RigRenderer::cameras)
      .def_property_readonly("width", &sim::RigRenderer::width)
      .def_property_readonly("height", &sim::RigRenderer::height)
      .def(
          "render",
          [](sim::RigRenderer& r, const py::handle& q) { return render_batch(r, q, false); },
          py::arg("q"))
      .def(
          "robot_masks",
          [](sim::RigRenderer& r, const py::handle& q) { return render_batch(r, q, true); },
          py::arg("q"));

  m.def("generate_dataset", &generate, py::arg("config"), py::arg("out"), py::arg("seed"),
        py::arg("threads"), py::arg("shard_index"), py::arg("shard_count"), py::arg("progress"));
  m.def(
      "write_extremes_preview",
      [](const sim::DatasetConfig& c, std::uint64_t seed, const std::string& png, int scale) {
        py::gil_scoped_release release;
        sim::write_extremes_preview(c, seed, png, scale);
      },
      py::arg("config"), py::arg("seed"), py::arg("png"), py::arg("scale"));
  m.def(
      "framing_reach",
      [](const sim::DatasetConfig& c, std::uint64_t seed) {
        std::vector<sim::FramingReach> reach;
        {
          py::gil_scoped_release release;
          reach = sim::framing_reach(c, seed);
        }
        py::list out;
        for (const sim::FramingReach& f : reach) {
          py::dict d;
          d["camera"] = f.camera;
          d["link"] = f.link;
          d["anchor"] = f.anchor;
          d["regime"] = f.regime;
          d["angles"] = f.angles;
          d["x"] = f.x;
          d["y"] = f.y;
          d["reach"] = f.reach;
          d["beyond_pixels"] = f.beyond_pixels;
          out.append(d);
        }
        return out;
      },
      py::arg("config"), py::arg("seed"));
  m.def(
      "check_framing",
      [](const sim::DatasetConfig& c, std::uint64_t seed) {
        py::gil_scoped_release release;
        sim::check_framing(c, seed);
      },
      py::arg("config"), py::arg("seed"));
  m.def("tune_malloc_for_rendering", &sim::tune_malloc_for_rendering);
}
