#include "ropes_nn/checkpoint.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>
#include <set>
#include <stdexcept>

#include "ropes_core/file_io.hpp"
#include "ropes_core/json_text.hpp"
#include "ropes_nn/safetensors.hpp"

namespace ropes::nn {

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using core::describe;

constexpr const char* kModelPrefix = "model.";
constexpr const char* kOptimizerPrefix = "optimizer.";
constexpr const char* kFirstMoment = "optimizer.exp_avg.";
constexpr const char* kSecondMoment = "optimizer.exp_avg_sq.";
constexpr const char* kStepCount = "optimizer.step.";

[[noreturn]] void checkpoint_fail(const std::string& name, const std::string& what) {
  throw core::FileFormatError(name + ": " + what);
}

bool starts_with(const std::string& text, const std::string& prefix) {
  return text.compare(0, prefix.size(), prefix) == 0;
}

std::string shape_text(const std::vector<std::int64_t>& shape) {
  std::string out = "[";
  for (std::size_t i = 0; i < shape.size(); ++i)
    out += (i ? ", " : "") + std::to_string(shape[i]);
  return out + "]";
}

core::NpyArray f32_array(const float* values, const std::vector<std::int64_t>& shape,
                         std::size_t count) {
  core::NpyArray a;
  a.dtype = core::DType::kF32;
  a.shape = shape;
  a.data.resize(count * sizeof(float));
  if (count > 0)
    std::memcpy(a.data.data(), values, a.data.size());
  return a;
}

core::NpyArray i64_scalar(std::int64_t value) {
  core::NpyArray a;
  a.dtype = core::DType::kI64;
  a.data.resize(sizeof(value));
  std::memcpy(a.data.data(), &value, sizeof(value));
  return a;
}

// the array `key` of the file, of `dtype` and `shape`; core::FileFormatError naming both otherwise
const core::NpyArray& expect_tensor(const Safetensors& file, const std::string& name,
                                    const std::string& key, core::DType dtype,
                                    const std::vector<std::int64_t>& shape,
                                    const std::string& owner) {
  const core::NpyArray* a = file.find(key);
  if (!a)
    checkpoint_fail(name, "has no tensor '" + key + "' for " + owner);
  if (a->dtype != dtype || a->shape != shape) {
    checkpoint_fail(name, "tensor '" + key + "' is " + core::dtype_name(a->dtype) + " " +
                              shape_text(a->shape) + "; " + owner + " is " +
                              core::dtype_name(dtype) + " " + shape_text(shape) +
                              " (a file of another architecture?)");
  }
  return *a;
}

// a tensor of the file named like `parameter` under some other prefix, to hint at it
std::string prefix_hint(const Safetensors& file, const std::string& parameter) {
  for (const auto& [key, array] : file.tensors) {
    if (key.size() > parameter.size() && key[key.size() - parameter.size() - 1] == '.' &&
        key.compare(key.size() - parameter.size(), parameter.size(), parameter) == 0) {
      const std::string prefix = key.substr(0, key.size() - parameter.size());
      return " (the file has '" + key + "': load with the prefix \"" + prefix + "\"?)";
    }
  }
  return "";
}

// module parameters matched with the file's arrays, every check done before any write
struct WeightPlan {
  std::vector<std::pair<std::string, Tensor>> targets;
  std::vector<const core::NpyArray*> sources;
  std::vector<std::string> missing, unexpected;
};

WeightPlan plan_weights(const Module& module, const Safetensors& file, const std::string& name,
                        const LoadOptions& options) {
  WeightPlan plan;
  std::set<std::string> known;
  for (const auto& [pname, t] : module.named_parameters()) {
    known.insert(pname);
    const std::string key = options.prefix + pname;
    if (!file.find(key)) {
      if (options.strict) {
        checkpoint_fail(name, "has no tensor '" + key + "' for parameter '" + pname + "'" +
                                  (options.prefix.empty() ? prefix_hint(file, pname) : ""));
      }
      plan.missing.push_back(pname);
      continue;
    }
    plan.sources.push_back(&expect_tensor(file, name, key, core::DType::kF32, t.shape().dims(),
                                          "parameter '" + pname + "'"));
    plan.targets.emplace_back(pname, t);
  }
  for (const auto& [key, array] : file.tensors) {
    if (!starts_with(key, options.prefix) || known.count(key.substr(options.prefix.size())))
      continue;
    if (options.strict) {
      checkpoint_fail(name, "holds tensor '" + key +
                                "', which the module does not have (no parameter '" +
                                key.substr(options.prefix.size()) + "')");
    }
    plan.unexpected.push_back(key.substr(options.prefix.size()));
  }
  return plan;
}

void apply_weights(Module& module, const WeightPlan& plan) {
  for (std::size_t i = 0; i < plan.targets.size(); ++i) {
    Tensor t = plan.targets[i].second;
    const core::NpyArray& a = *plan.sources[i];
    if (!a.data.empty())
      std::memcpy(t.mutable_data(), a.data.data(), a.data.size());
    module.mark_initialized(plan.targets[i].first);
  }
}

const Json& field(const Json& object, const char* key, const std::string& name,
                  const std::string& where) {
  const auto it = object.find(key);
  if (it == object.end())
    checkpoint_fail(name, where + " has no field '" + key + "'");
  return *it;
}

std::int64_t count_field(const Json& object, const char* key, const std::string& name,
                         const std::string& where) {
  const Json& v = field(object, key, name, where);
  if (!v.is_number_integer() || v.get<std::int64_t>() < 0 ||
      (v.is_number_unsigned() && v.get<std::uint64_t>() > INT64_MAX)) {
    checkpoint_fail(name, where + "." + key + " is " + describe(v) + "; expected an integer >= 0");
  }
  return v.get<std::int64_t>();
}

double number_field(const Json& object, const char* key, const std::string& name,
                    const std::string& where) {
  const Json& v = field(object, key, name, where);
  if (!v.is_number() || !std::isfinite(v.get<double>()))
    checkpoint_fail(name, where + "." + key + " is " + describe(v) + "; expected a finite number");
  return v.get<double>();
}

}  // namespace

void save_module(const Module& module, const fs::path& path,
                 const std::map<std::string, std::string>& metadata, const std::string& prefix) {
  Safetensors file;
  file.metadata = metadata;
  for (const auto& [name, t] : module.named_parameters()) {
    file.tensors.emplace_back(
        prefix + name, f32_array(t.data(), t.shape().dims(), static_cast<std::size_t>(t.numel())));
  }
  write_safetensors(path, file, /*sealed=*/true);
}

LoadResult load_module(Module& module, const fs::path& path, const LoadOptions& options) {
  const Safetensors file = read_safetensors(path);  // checks the seal, when there is one
  const WeightPlan plan = plan_weights(module, file, path.string(), options);
  apply_weights(module, plan);
  std::map<std::string, std::string> metadata = file.metadata;
  metadata.erase(kSafetensorsSealKey);
  return {metadata, plan.missing, plan.unexpected};
}

void save_checkpoint(const fs::path& path, const Module& module, const Adam& adam,
                     const LrSchedule& schedule, const TrainingProgress& progress,
                     const std::map<std::string, std::string>& metadata) {
  for (const char* reserved : {kCheckpointMetadataKey, kSafetensorsSealKey}) {
    if (metadata.count(reserved)) {
      throw std::invalid_argument(std::string("save_checkpoint: metadata key '") + reserved +
                                  "' is reserved for the training state; use another key");
    }
  }
  if (progress.epoch < 0 || progress.position < 0) {
    throw std::invalid_argument("save_checkpoint: data cursor epoch " +
                                std::to_string(progress.epoch) + ", position " +
                                std::to_string(progress.position) + "; expected both >= 0");
  }
  const AdamOptions& o = adam.options();
  const Json state = {
      {"format", kCheckpointFormat},
      {"format_version", kCheckpointFormatVersion},
      {"step", adam.steps()},
      {"lr", o.lr},
      {"adam",
       {{"beta1", o.beta1}, {"beta2", o.beta2}, {"eps", o.eps}, {"weight_decay", o.weight_decay}}},
      {"schedule", Json::parse(schedule.to_json())},
      {"seed", progress.seed},
      {"epoch", progress.epoch},
      {"position", progress.position}};
  Safetensors file;
  file.metadata = metadata;
  file.metadata[kCheckpointMetadataKey] = state.dump();
  for (const auto& [name, t] : module.named_parameters()) {
    file.tensors.emplace_back(kModelPrefix + name, f32_array(t.data(), t.shape().dims(),
                                                             static_cast<std::size_t>(t.numel())));
  }
  for (std::size_t i = 0; i < adam.params().size(); ++i) {
    const std::string& name = adam.names()[i];
    const std::vector<std::int64_t> shape = adam.params()[i].shape().dims();
    file.tensors.emplace_back(kFirstMoment + name, f32_array(adam.first_moment(i).data(), shape,
                                                             adam.first_moment(i).size()));
    file.tensors.emplace_back(kSecondMoment + name, f32_array(adam.second_moment(i).data(), shape,
                                                              adam.second_moment(i).size()));
    file.tensors.emplace_back(kStepCount + name, i64_scalar(adam.param_steps(i)));
  }
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  core::remove_stale_temporaries(dir, path.filename().string());
  write_safetensors(path, file, /*sealed=*/true);
}

LoadedCheckpoint load_checkpoint(const fs::path& path, Module& module, Adam& adam) {
  const std::string name = path.string();
  const Safetensors file = read_safetensors(path);  // checks the seal, when there is one

  // the training state in the metadata
  const auto meta = file.metadata.find(kCheckpointMetadataKey);
  if (meta == file.metadata.end()) {
    checkpoint_fail(name, std::string("is not a training checkpoint (no \"") +
                              kCheckpointMetadataKey +
                              "\" metadata); a weights file loads with load_module");
  }
  const std::string where = std::string("metadata[\"") + kCheckpointMetadataKey + "\"]";
  Json state;
  const std::string problem = core::parse_json(meta->second, &state);
  if (!problem.empty())
    checkpoint_fail(name, where + " " + problem);
  if (!state.is_object())
    checkpoint_fail(name, where + " is " + describe(state) + "; expected a JSON object");
  const Json& format = field(state, "format", name, where);
  if (format != kCheckpointFormat) {
    checkpoint_fail(name, where + ".format is " + describe(format) + "; expected \"" +
                              kCheckpointFormat + "\"");
  }
  const Json& version = field(state, "format_version", name, where);
  if (version != kCheckpointFormatVersion && version != 1) {
    checkpoint_fail(name, where + ".format_version is " + describe(version) + "; expected 1 or " +
                              std::to_string(kCheckpointFormatVersion) +
                              " (the versions this reader knows)");
  }
  if (version != 1 && !is_sealed(file)) {
    checkpoint_fail(name, std::string("has no seal (metadata '") + kSafetensorsSealKey +
                              "'), which every checkpoint of format_version " + version.dump() +
                              " has");
  }
  const std::int64_t step = count_field(state, "step", name, where);
  const double lr = number_field(state, "lr", name, where);
  if (lr < 0)
    checkpoint_fail(name, where + ".lr is " + describe(state["lr"]) + "; expected a rate >= 0");
  const Json& adam_json = field(state, "adam", name, where);
  if (!adam_json.is_object())
    checkpoint_fail(name, where + ".adam is " + describe(adam_json) + "; expected an object");
  AdamOptions options = adam.options();
  options.lr = 1.0;  // checked apart: the saved rate may be 0 at the end of a schedule
  options.beta1 = number_field(adam_json, "beta1", name, where + ".adam");
  options.beta2 = number_field(adam_json, "beta2", name, where + ".adam");
  options.eps = number_field(adam_json, "eps", name, where + ".adam");
  options.weight_decay = number_field(adam_json, "weight_decay", name, where + ".adam");
  if (!options.problem().empty())
    checkpoint_fail(name, where + ".adam: " + options.problem());
  const Json& schedule_json = field(state, "schedule", name, where);
  if (!schedule_json.is_object())
    checkpoint_fail(name,
                    where + ".schedule is " + describe(schedule_json) + "; expected an object");
  LrSchedule schedule = LrSchedule::constant(1.0);
  try {
    schedule = LrSchedule::from_json(schedule_json.dump(), where + ".schedule");
  } catch (const std::invalid_argument& e) {
    checkpoint_fail(name, e.what());
  }
  TrainingProgress progress;
  const Json& seed = field(state, "seed", name, where);
  if (!seed.is_number_unsigned())
    checkpoint_fail(name, where + ".seed is " + describe(seed) + "; expected an integer >= 0");
  progress.seed = seed.get<std::uint64_t>();
  progress.epoch = count_field(state, "epoch", name, where);
  progress.position = count_field(state, "position", name, where);

  // every tensor: the module's weights, the optimiser's state, nothing else
  const WeightPlan weights = plan_weights(module, file, name, LoadOptions{kModelPrefix, true});
  std::set<std::string> expected;
  std::vector<const core::NpyArray*> first, second;
  std::vector<std::int64_t> counts;
  for (std::size_t i = 0; i < adam.params().size(); ++i) {
    const std::string& pname = adam.names()[i];
    const std::vector<std::int64_t> shape = adam.params()[i].shape().dims();
    const std::string owner = "the optimiser's parameter '" + pname + "'";
    first.push_back(
        &expect_tensor(file, name, kFirstMoment + pname, core::DType::kF32, shape, owner));
    second.push_back(
        &expect_tensor(file, name, kSecondMoment + pname, core::DType::kF32, shape, owner));
    const core::NpyArray& t =
        expect_tensor(file, name, kStepCount + pname, core::DType::kI64, {}, owner);
    std::int64_t count = 0;
    std::memcpy(&count, t.data.data(), sizeof(count));
    if (count < 0 || count > step) {
      checkpoint_fail(name, "tensor '" + std::string(kStepCount) + pname + "' is " +
                                std::to_string(count) + "; expected 0.." + std::to_string(step) +
                                " (the checkpoint's step)");
    }
    counts.push_back(count);
    for (const char* prefix : {kFirstMoment, kSecondMoment, kStepCount})
      expected.insert(prefix + pname);
  }
  for (const auto& [key, array] : file.tensors) {
    if (starts_with(key, kModelPrefix) || expected.count(key))
      continue;
    if (starts_with(key, kOptimizerPrefix)) {
      checkpoint_fail(name,
                      "holds optimiser state '" + key +
                          "' for a parameter the optimiser does not have (a checkpoint of another "
                          "architecture?)");
    }
    checkpoint_fail(name, "holds tensor '" + key + "', which is neither model.* nor optimizer.*");
  }

  // every check passed: write
  apply_weights(module, weights);
  adam.set_options(options);
  adam.set_lr(lr);
  adam.set_steps(step);
  for (std::size_t i = 0; i < adam.params().size(); ++i) {
    std::memcpy(adam.first_moment(i).data(), first[i]->data.data(), first[i]->data.size());
    std::memcpy(adam.second_moment(i).data(), second[i]->data.data(), second[i]->data.size());
    adam.set_param_steps(i, counts[i]);
  }
  std::map<std::string, std::string> user = file.metadata;
  user.erase(kCheckpointMetadataKey);
  user.erase(kSafetensorsSealKey);
  return {schedule, step, progress, user};
}

}  // namespace ropes::nn
