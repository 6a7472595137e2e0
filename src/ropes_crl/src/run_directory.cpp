#include "ropes_crl/run_directory.hpp"

#include <cmath>
#include <stdexcept>
#include <system_error>

#include "ropes_core/file_format_error.hpp"
#include "ropes_core/json_text.hpp"
#include "run_files.hpp"

namespace ropes::crl {

namespace fs = std::filesystem;

namespace {

[[noreturn]] void fail(const fs::path& run_file, const std::string& what) {
  throw core::FileFormatError(run_file.string() + ": " + what);
}

const nlohmann::json& required(const nlohmann::json& run, const fs::path& file, const char* key,
                               bool (nlohmann::json::*is)() const noexcept, const char* expected) {
  const auto it = run.find(key);
  if (it == run.end())
    fail(file, std::string(key) + " is missing; expected " + expected);
  if (!((*it).*is)())
    fail(file, std::string(key) + " is " + core::describe(*it) + "; expected " + expected);
  return *it;
}

double number_or_nan(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<double>() : std::nan("");
}

}  // namespace

RunDirectory RunDirectory::open(const fs::path& dir) {
  RunDirectory r;
  r.dir_ = dir;
  const fs::path file = r.run_file();
  if (!core::is_regular_file(file))
    fail(file, "missing; is '" + dir.string() + "' a run directory of ropes-train?");
  const nlohmann::json run = core::read_json_file(file);
  if (!run.is_object())
    fail(file, "holds " + core::describe(run) + "; expected a ropes run (a JSON object)");
  const auto format = run.find("format");
  if (format == run.end() || *format != detail::kRunFormat)
    fail(file, "not a ropes run (format " +
                   (format == run.end() ? std::string("missing") : core::describe(*format)) +
                   ", expected \"" + detail::kRunFormat + "\")");
  r.config_ = ExperimentConfig::from_json(  // a core::ConfigError naming run.json
      required(run, file, "config", &nlohmann::json::is_object, "a JSON object"), file.string());
  for (const nlohmann::json& j :
       required(run, file, "joints", &nlohmann::json::is_array, "an array of joint names")) {
    if (!j.is_string())
      fail(file, "joints holds " + core::describe(j) + "; expected joint names");
    r.joints_.push_back(j.get<std::string>());
  }
  r.data_dir_ =
      required(run, file, "data_dir", &nlohmann::json::is_string, "the training set's directory")
          .get<std::string>();
  r.dataset_id_ =
      required(run, file, "dataset", &nlohmann::json::is_string, "a dataset id").get<std::string>();
  r.seed_ =
      required(run, file, "seed", &nlohmann::json::is_number_unsigned, "a non-negative integer")
          .get<std::uint64_t>();
  r.complete_ = run.value("complete", nlohmann::json(false)) == true;
  r.provenance_ = run.value("provenance", nlohmann::json());
  if (!r.provenance_.is_object() && !r.provenance_.is_null())
    fail(file, "provenance is " + core::describe(r.provenance_) + "; expected an object");
  r.ldr_ = run.value("ldr", nlohmann::json::object());
  if (!r.ldr_.is_object())
    fail(file, "ldr is " + core::describe(r.ldr_) + "; expected an object of joints");
  const nlohmann::json sparsity = run.value("sparsity_matrix", nlohmann::json::object());
  if (!sparsity.is_object())
    fail(file, "sparsity_matrix is " + core::describe(sparsity) + "; expected an object");
  for (auto it = sparsity.begin(); it != sparsity.end(); ++it) {
    SparsityMatrix m{it.key(), {}};
    if (!it->is_array())
      fail(file, "sparsity_matrix." + it.key() + " is " + core::describe(*it) +
                     "; expected an array of rows");
    for (const nlohmann::json& row : *it) {
      if (!row.is_array())
        fail(file, "sparsity_matrix." + it.key() + " holds " + core::describe(row) +
                       "; expected rows of numbers");
      std::vector<double> values;
      for (const nlohmann::json& v : row)
        values.push_back(v.is_number() ? v.get<double>() : std::nan(""));
      m.rows.push_back(std::move(values));
    }
    r.sparsity_.push_back(std::move(m));
  }
  return r;
}

std::optional<LdrRecord> RunDirectory::ldr(const std::string& joint) const {
  const auto it = ldr_.find(joint);
  if (it == ldr_.end() || !it->is_object())
    return std::nullopt;
  LdrRecord r;
  r.held_out_loss = number_or_nan(*it, "held_out_loss");
  r.held_out_accuracy = number_or_nan(*it, "held_out_accuracy");
  r.bayes_accuracy = number_or_nan(*it, "bayes_accuracy");
  const auto epochs = it->find("epochs");
  r.epochs = epochs != it->end() && epochs->is_number_integer() ? epochs->get<std::int64_t>() : 0;
  return r;
}

}  // namespace ropes::crl
