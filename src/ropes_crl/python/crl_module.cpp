// ropes._crl: the learner (ropes_crl) for Python: experiment configs, training a run with a
// progress callback that can stop it, and the Estimator on numpy images. The pure-Python
// module ropes.crl (python/ropes/crl.py) is what users import.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "ropes_core/python.hpp"
#include "ropes_crl/calibration.hpp"
#include "ropes_crl/estimator.hpp"
#include "ropes_crl/experiment_config.hpp"
#include "ropes_crl/run_directory.hpp"
#include "ropes_crl/trainer.hpp"
#include "ropes_nn/parallel.hpp"

namespace py = pybind11;
namespace crl = ropes::crl;
namespace nn = ropes::nn;
namespace rp = ropes::python;

namespace {

crl::ExperimentConfig load_config(const py::handle& name_or_path) {
  return crl::load_experiment_config(rp::fspath(name_or_path));
}

// trains (or resumes) the run; {"complete", "stopped"}
py::dict train(const crl::ExperimentConfig& config, const py::handle& data, const py::handle& out,
               std::uint64_t seed, int threads, int last_stage, const py::object& progress) {
  rp::Callback callback(progress);
  crl::TrainOptions options;
  options.seed = seed;
  options.threads = threads;
  options.last_stage = last_stage;
  options.on_metrics = [&callback](const nlohmann::json& record) {
    callback.stop_unless_going([&] { return py::make_tuple(rp::to_python(record)); });
  };
  const std::string data_dir = rp::fspath(data), run_dir = rp::fspath(out);
  bool stopped = false;
  try {
    py::gil_scoped_release release;
    crl::train(config, data_dir, run_dir, options);
  } catch (const rp::CallbackStop&) {
    stopped = true;
  }
  callback.finish();  // re-raises what the callback raised, KeyboardInterrupt included
  py::dict d;
  d["stopped"] = stopped;
  d["complete"] = !stopped && last_stage == 3;
  return d;
}

// an Estimator is not thread-safe and estimate() releases the GIL: Python threads sharing
// one take turns
struct SharedEstimator {
  explicit SharedEstimator(crl::Estimator e) : estimator(std::move(e)) {}
  crl::Estimator estimator;
  std::mutex mutex;
};

// images u8 [n, cameras, S, S] -> (latents f32 [n, J], angles f32 [n, J] or None), in batches
py::tuple estimate(SharedEstimator& shared, const py::handle& images_obj, std::int64_t batch) {
  crl::Estimator& e = shared.estimator;
  if (batch < 1)
    throw std::invalid_argument("batch is " + std::to_string(batch) + "; expected >= 1");
  const std::int64_t cams = e.cameras(), side = e.image_size();
  const auto images = rp::require_array<std::uint8_t>(images_obj, "images", {-1, cams, side, side},
                                                      {"n", "cameras", "S", "S"});
  const std::int64_t n = images.shape(0);
  const auto joints = static_cast<std::int64_t>(e.joints().size());
  const std::int64_t per = cams * side * side;
  std::vector<float> latents(static_cast<std::size_t>(n * joints));
  std::vector<float> angles;
  bool calibrated = false;
  const std::uint8_t* pixels = images.data();
  {
    py::gil_scoped_release release;  // then the lock: a thread waiting for it holds no GIL
    const std::lock_guard<std::mutex> lock(shared.mutex);
    calibrated = e.calibrated();
    angles.resize(calibrated ? latents.size() : 0);
    for (std::int64_t b = 0; b < n; b += batch) {
      const std::int64_t m = std::min(batch, n - b);
      nn::Buffer x(static_cast<std::size_t>(m * per));
      const std::uint8_t* from = pixels + b * per;
      for (std::size_t i = 0; i < x.size(); ++i)
        x[i] = static_cast<float>(from[i]) / 255.0f;  // as ropes-eval reads a dataset's images
      const nn::Tensor l = e.latents(nn::Tensor(nn::Shape{m, cams, side, side}, std::move(x)));
      std::copy(l.data(), l.data() + m * joints, latents.begin() + b * joints);
      if (calibrated) {
        const nn::Tensor a = e.angles_from_latents(l);
        std::copy(a.data(), a.data() + m * joints, angles.begin() + b * joints);
      }
    }
  }
  py::object a = py::none();
  if (calibrated)
    a = rp::to_numpy(std::move(angles), {n, joints});
  return py::make_tuple(rp::to_numpy(std::move(latents), {n, joints}), a);
}

}  // namespace

PYBIND11_MODULE(_crl, m) {
  m.doc() = "ropes._crl: the learner (use ropes.crl)";
  rp::translate_core_exceptions();

  py::class_<crl::ExperimentConfig>(m, "ExperimentConfig")
      .def_static("load", &load_config, py::arg("name_or_path"))
      .def_readonly("name", &crl::ExperimentConfig::name)
      .def_readonly("preset", &crl::ExperimentConfig::preset)
      .def_readonly("dataset_config", &crl::ExperimentConfig::dataset_config)
      .def_readonly("cameras", &crl::ExperimentConfig::cameras)
      .def_readonly("image_size", &crl::ExperimentConfig::image_size)
      .def_readonly("joints", &crl::ExperimentConfig::joints)
      .def("to_dict", [](const crl::ExperimentConfig& c) { return rp::to_python(c.raw); });

  m.def("train", &train, py::arg("config"), py::arg("data"), py::arg("out"), py::arg("seed"),
        py::arg("threads"), py::arg("last_stage"), py::arg("progress"));

  py::class_<SharedEstimator>(m, "Estimator")
      .def_static(
          "load",
          [](const py::handle& run) {
            return std::make_unique<SharedEstimator>(crl::Estimator::load(rp::fspath(run)));
          },
          py::arg("run"))
      .def_property_readonly("joints",
                             [](const SharedEstimator& s) { return s.estimator.joints(); })
      .def_property_readonly("cameras",
                             [](const SharedEstimator& s) { return s.estimator.cameras(); })
      .def_property_readonly("image_size",
                             [](const SharedEstimator& s) { return s.estimator.image_size(); })
      .def_property_readonly("calibrated",
                             [](const SharedEstimator& s) { return s.estimator.calibrated(); })
      .def("estimate", &estimate, py::arg("images"), py::arg("batch"))
      .def(
          "use_calibration",
          [](SharedEstimator& s, const py::handle& run, const py::handle& file) {
            const crl::Calibration c = crl::Calibration::read(rp::fspath(file));
            c.check_fits(crl::RunDirectory::open(rp::fspath(run)));
            py::gil_scoped_release release;
            const std::lock_guard<std::mutex> lock(s.mutex);
            s.estimator.set_calibration(c);
          },
          py::arg("run"), py::arg("file"));

  m.def(
      "latest_calibration",
      [](const py::handle& run) -> py::object {
        const std::optional<std::filesystem::path> p =
            crl::latest_calibration(crl::RunDirectory::open(rp::fspath(run)));
        if (!p)
          return py::none();
        return py::str(p->string());
      },
      py::arg("run"));
  m.def(
      "run_info",
      [](const py::handle& run) {
        const crl::RunDirectory r = crl::RunDirectory::open(rp::fspath(run));
        py::dict d;
        d["dir"] = r.dir().string();
        d["config"] = r.config().name;
        d["joints"] = r.joints();
        d["data_dir"] = r.data_dir().string();
        d["dataset_id"] = r.dataset_id();
        d["provenance"] = rp::to_python(r.provenance());
        return d;
      },
      py::arg("run"));
  m.def("set_num_threads", &nn::set_num_threads, py::arg("threads"));
}
