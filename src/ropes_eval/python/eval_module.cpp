// ropes._eval: the evaluation (ropes_eval) for Python: the paper's measures on numpy arrays,
// a run's evaluation by the paper's protocol, the suites and the main job. The pure-Python
// module ropes.eval (python/ropes/eval.py) is what users import.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Dense>
#include <cstdint>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "ropes_core/python.hpp"
#include "ropes_crl/calibration.hpp"
#include "ropes_eval/calibration.hpp"
#include "ropes_eval/correlation.hpp"
#include "ropes_eval/main_job.hpp"
#include "ropes_eval/run_evaluation.hpp"
#include "ropes_eval/suites.hpp"
#include "ropes_nn/parallel.hpp"
#include "ropes_sim/mesh.hpp"
#include "ropes_sim/renderer.hpp"
#include "ropes_sim/robot_model.hpp"

namespace py = pybind11;
namespace eval = ropes::eval;
namespace rp = ropes::python;

namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

Eigen::MatrixXd matrix(const py::handle& obj, const char* what, const char* cols) {
  const auto a = rp::require_array<double>(obj, what, {-1, -1}, {"n", cols});
  return Eigen::Map<const RowMatrix>(a.data(), a.shape(0), a.shape(1));
}
Eigen::VectorXd vector(const py::handle& obj, const char* what) {
  const auto a = rp::require_array<double>(obj, what, {-1});
  return Eigen::Map<const Eigen::VectorXd>(a.data(), a.shape(0));
}
py::array_t<double> to_numpy(const Eigen::VectorXd& v) {
  return rp::to_numpy(std::vector<double>(v.data(), v.data() + v.size()), {v.size()});
}

// value.cast<T>(), a mismatch a ValueError naming the field, the value and the type expected
template <class T>
T field_as(const py::handle& value, const std::string& key, const char* expected) {
  try {
    if (py::isinstance<py::bool_>(value) && !std::is_same<T, bool>::value)
      throw py::cast_error();
    return value.cast<T>();
  } catch (const py::cast_error&) {
    throw std::invalid_argument(key + " is " + std::string(py::repr(value)) + "; expected " +
                                expected);
  }
}

eval::Correlation correlation_kind(const std::string& kind) {
  if (kind == "pearson")
    return eval::Correlation::kPearson;
  if (kind == "spearman")
    return eval::Correlation::kSpearman;
  throw std::invalid_argument("kind is '" + kind + "'; expected 'pearson' or 'spearman'");
}

eval::RunEvaluationOptions protocol(const py::dict& p) {
  eval::RunEvaluationOptions o;
  for (const auto& [key_obj, value] : p) {
    const std::string key = py::str(key_obj);
    if (key == "repeats")
      o.repeats = field_as<std::int64_t>(value, key, "an int");
    else if (key == "calibration_samples")
      o.calibration_samples = field_as<std::int64_t>(value, key, "an int");
    else if (key == "test_samples")
      o.test_samples = field_as<std::int64_t>(value, key, "an int");
    else if (key == "seed")
      o.seed = field_as<std::uint64_t>(value, key, "an int >= 0");
    else if (key == "probe_steps")
      o.probe_steps = field_as<std::int64_t>(value, key, "an int");
    else if (key == "occlusion")
      o.occlusion = field_as<std::int64_t>(value, key, "an int");
    else if (key == "occlusion_seed")
      o.occlusion_seed = field_as<std::uint64_t>(value, key, "an int >= 0");
    else
      throw std::invalid_argument("protocol: unknown field '" + key + "'");
  }
  return o;
}

void set_threads(int threads) {
  if (threads < 1 || threads > 256)
    throw std::invalid_argument("threads is " + std::to_string(threads) + "; expected 1..256");
  ropes::nn::set_num_threads(threads);
}

py::dict evaluate(const py::handle& run, const py::handle& data, bool write, const py::object& out,
                  const py::dict& protocol_fields, int threads) {
  const eval::RunEvaluationOptions options = protocol(protocol_fields);
  set_threads(threads);
  const std::string run_dir = rp::fspath(run), data_dir = rp::fspath(data);
  std::optional<std::filesystem::path> results;
  if (write) {  // ropes-eval's place: `out`, else beside the run; never inside it
    results = ropes::crl::evaluation_output(run_dir, out.is_none() ? "" : rp::fspath(out),
                                            "results.json");
    eval::evaluation_files(*results);  // a bad name is refused before the evaluation
  }
  std::optional<eval::RunEvaluation> ev;
  std::optional<eval::EvaluationFiles> files;
  {
    py::gil_scoped_release release;
    ev = eval::evaluate_run(run_dir, data_dir, options);
    if (results)
      files = eval::write_evaluation(*ev, *results);
  }
  py::dict d;
  d["results"] = rp::to_python(ev->to_json());
  d["table"] = ev->table();
  d["markdown"] = ev->markdown();
  d["calibration"] = rp::to_python(ev->calibration.to_json());
  if (files) {
    py::dict f;
    f["results"] = files->results.string();
    f["markdown"] = files->markdown.string();
    f["calibration"] = files->calibration.string();
    d["files"] = f;
  } else {
    d["files"] = py::none();
  }
  return d;
}

eval::SuiteOptions suite_options(const py::dict& s) {
  eval::SuiteOptions o;
  for (const auto& [key_obj, value] : s) {
    const std::string key = py::str(key_obj);
    if (key == "suites")
      o.suites = field_as<std::vector<std::string>>(value, key, "a list of suite names");
    else if (key == "data")
      o.data = value.is_none() ? std::filesystem::path() : std::filesystem::path(rp::fspath(value));
    else if (key == "out")
      o.out = value.is_none() ? std::filesystem::path() : std::filesystem::path(rp::fspath(value));
    else if (key == "dataset_config")
      o.dataset_config =
          value.is_none() ? std::filesystem::path() : std::filesystem::path(rp::fspath(value));
    else if (key == "cache")
      o.cache =
          value.is_none() ? std::filesystem::path() : std::filesystem::path(rp::fspath(value));
    else if (key == "test_seed")
      o.test_seed =
          value.is_none()
              ? std::nullopt
              : std::optional<std::uint64_t>(field_as<std::uint64_t>(value, key, "an int >= 0"));
    else if (key == "occlusion_sizes")
      o.occlusion_sizes = field_as<std::vector<std::int64_t>>(value, key, "a list of ints");
    else if (key == "supervised")
      o.supervised = field_as<std::vector<double>>(value, key, "a list of fractions");
    else if (key == "supervised_max_steps")
      o.supervised_max_steps = field_as<std::int64_t>(value, key, "an int");
    else if (key == "threads")
      o.threads = field_as<int>(value, key, "an int");
    else if (key == "protocol")
      o.evaluation = protocol(field_as<py::dict>(value, key, "a dict"));
    else
      throw std::invalid_argument("suites: unknown field '" + key + "'");
  }
  return o;
}

py::dict suites(const py::handle& run, const py::dict& fields, const py::object& log) {
  const eval::SuiteOptions options = suite_options(fields);
  set_threads(options.threads);
  const std::string run_dir = rp::fspath(run);
  rp::Callback callback(log);
  std::optional<eval::SuiteOutcome> outcome;
  {
    py::gil_scoped_release release;
    try {
      outcome = eval::run_suites(run_dir, options, [&](const std::string& line) {
        callback.stop_unless_going([&] { return py::make_tuple(line); });
      });
    } catch (const rp::CallbackStop&) {
    }
  }
  const bool stopped = callback.finish();
  py::dict d;
  d["stopped"] = stopped;
  if (outcome) {
    d["report"] = rp::to_python(outcome->report.to_json());
    d["table"] = outcome->report.table();
    d["report_dir"] = outcome->report_dir.string();
  }
  return d;
}

py::dict main_job(const py::dict& fields, const py::object& log) {
  eval::MainJobOptions o;
  py::dict suite_fields;
  for (const auto& [key_obj, value] : fields) {
    const std::string key = py::str(key_obj);
    if (key == "config")
      o.config = rp::fspath(value);
    else if (key == "out")
      o.out = value.is_none() ? std::filesystem::path() : std::filesystem::path(rp::fspath(value));
    else if (key == "seed")
      o.seed = field_as<std::uint64_t>(value, key, "an int >= 0");
    else if (key == "data_seed")
      o.data_seed = field_as<std::uint64_t>(value, key, "an int >= 0");
    else if (key == "dataset_config")
      o.dataset_config = value.is_none() ? "" : rp::fspath(value);
    else if (key == "threads")
      o.threads = field_as<int>(value, key, "an int");
    else
      suite_fields[key_obj] = value;
  }
  if (!suite_fields.empty()) {
    const eval::SuiteOptions s = suite_options(suite_fields);
    if (suite_fields.contains("suites"))
      o.suites.suites = s.suites;
    if (suite_fields.contains("protocol"))
      o.suites.evaluation = s.evaluation;
    if (suite_fields.contains("occlusion_sizes"))
      o.suites.occlusion_sizes = s.occlusion_sizes;
    if (suite_fields.contains("supervised"))
      o.suites.supervised = s.supervised;
    if (suite_fields.contains("supervised_max_steps"))
      o.suites.supervised_max_steps = s.supervised_max_steps;
  }
  set_threads(o.threads);
  rp::Callback callback(log);
  o.on_training_record = [&callback] { callback.poll(); };
  std::optional<eval::MainJobResult> result;
  {
    py::gil_scoped_release release;
    try {
      result = eval::run_main_job(o, [&](int stage, const std::string& line) {
        callback.stop_unless_going([&] { return py::make_tuple(stage, line); });
      });
    } catch (const rp::CallbackStop&) {
    }
  }
  const bool stopped = callback.finish();
  py::dict d;
  d["stopped"] = stopped;
  if (result) {
    d["dir"] = result->dir.string();
    d["train_data"] = result->train_data.string();
    d["run_dir"] = result->run_dir.string();
    d["report_dir"] = result->report_dir.string();
    d["table"] = result->table;
    d["evaluated"] = result->evaluated;
  }
  return d;
}

}  // namespace

PYBIND11_MODULE(_eval, m) {
  m.doc() = "ropes._eval: the evaluation (use ropes.eval)";
  rp::translate_core_exceptions();
  rp::translate_exception<ropes::sim::ModelError>("ModelError");
  rp::translate_exception<ropes::sim::MeshError>("MeshError");
  rp::translate_exception<ropes::sim::RenderError>("RenderError");

  m.def(
      "per_joint_correlation",
      [](const py::handle& latents, const py::handle& angles, const std::string& kind) {
        return to_numpy(eval::per_joint_correlation(matrix(latents, "latents", "joints"),
                                                    matrix(angles, "angles", "joints"),
                                                    correlation_kind(kind)));
      },
      py::arg("latents"), py::arg("angles"), py::arg("kind"));
  m.def(
      "correlation_matrix",
      [](const py::handle& latents, const py::handle& angles, const std::string& kind) {
        const Eigen::MatrixXd c =
            eval::correlation_matrix(matrix(latents, "latents", "latents"),
                                     matrix(angles, "angles", "joints"), correlation_kind(kind));
        const RowMatrix r = c;
        return rp::to_numpy(std::vector<double>(r.data(), r.data() + r.size()),
                            {r.rows(), r.cols()});
      },
      py::arg("latents"), py::arg("angles"), py::arg("kind"));
  m.def(
      "best_assignment",
      [](const py::handle& latents, const py::handle& angles, const std::string& kind) {
        const eval::Assignment a = eval::best_assignment_correlation(
            matrix(latents, "latents", "latents"), matrix(angles, "angles", "joints"),
            correlation_kind(kind));
        py::dict d;
        d["latent_of_joint"] =
            std::vector<std::int64_t>(a.latent_of_joint.begin(), a.latent_of_joint.end());
        d["correlation"] = to_numpy(a.correlation);
        d["mean"] = a.mean;
        return d;
      },
      py::arg("latents"), py::arg("angles"), py::arg("kind"));
  m.def(
      "fit_affine",
      [](const py::handle& latent, const py::handle& joint) {
        const eval::AffineCalibration c =
            eval::fit_affine(vector(latent, "latent"), vector(joint, "joint"));
        return py::make_tuple(c.scale, c.offset);
      },
      py::arg("latent"), py::arg("joint"));
  m.def(
      "affine_mse",
      [](double scale, double offset, const py::handle& latent, const py::handle& joint) {
        return eval::calibration_mse(eval::AffineCalibration{scale, offset},
                                     vector(latent, "latent"), vector(joint, "joint"));
      },
      py::arg("scale"), py::arg("offset"), py::arg("latent"), py::arg("joint"));
  m.def(
      "fit_linear",
      [](const py::handle& latents, const py::handle& joint) {
        const eval::LinearCalibration c =
            eval::fit_linear(matrix(latents, "latents", "latents"), vector(joint, "joint"));
        return py::make_tuple(to_numpy(c.weights), c.offset);
      },
      py::arg("latents"), py::arg("joint"));
  m.def(
      "linear_mse",
      [](const py::handle& weights, double offset, const py::handle& latents,
         const py::handle& joint) {
        return eval::calibration_mse(eval::LinearCalibration{vector(weights, "weights"), offset},
                                     matrix(latents, "latents", "latents"), vector(joint, "joint"));
      },
      py::arg("weights"), py::arg("offset"), py::arg("latents"), py::arg("joint"));
  m.def("evaluate_run", &evaluate, py::arg("run"), py::arg("data"), py::arg("write"),
        py::arg("out"), py::arg("protocol"), py::arg("threads"));
  m.def("run_suites", &suites, py::arg("run"), py::arg("options"), py::arg("log"));
  m.def("run_main_job", &main_job, py::arg("options"), py::arg("log"));
}
