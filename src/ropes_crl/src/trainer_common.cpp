// What the trainer's stages share: resuming from a checkpoint, a checked step, the
// networks' metadata, and the run directory's record (run.json).
#include "stages.hpp"

#include <ropes_core/file_io.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_core/npy.hpp>
#include <ropes_core/philox.hpp>
#include <ropes_nn/adam.hpp>
#include <ropes_nn/batch_loader.hpp>
#include <ropes_nn/build_info.hpp>
#include <ropes_nn/checkpoint.hpp>
#include <ropes_nn/ops.hpp>
#include <ropes_nn/parallel.hpp>
#include <ropes_nn/train_step.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>

#include "ropes_crl/bayes_accuracy.hpp"
#include "ropes_crl/sparsity_objective.hpp"
#include "run_files.hpp"
#include "training_data.hpp"

namespace ropes::crl::detail {

using nn::Shape;

nn::LoadedCheckpoint resume_from(const fs::path& checkpoint, nn::Module& net, nn::Adam& adam) {
  try {
    return nn::load_checkpoint(checkpoint, net, adam);
  } catch (const core::FileFormatError& e) {
    throw core::FileFormatError(std::string(e.what()) + "; remove " + checkpoint.string() +
                                " to train this model again from its first step");
  }
}

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

std::map<std::string, std::string> network_metadata(const std::string& kind,
                                                    const nlohmann::json& spec,
                                                    const ExperimentConfig& config,
                                                    const nlohmann::json& extra) {
  nlohmann::json net = {{"kind", kind}, {"spec", spec}};
  if (!extra.is_null())
    net["info"] = extra;
  return {{kNetworkKey, net.dump()}, {kConfigKey, config.to_json().dump()}};
}

nn::StepResult checked_step(nn::Adam& adam, const nn::BatchLoss& loss, const nn::StepOptions& so,
                            const std::string& stage, const fs::path& checkpoint) {
  try {
    return nn::train_step(adam, loss, so);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(
        "stage " + stage + ", step " + std::to_string(adam.steps() + 1) + ": " + e.what() +
        (fs::exists(checkpoint) ? "; the last checkpoint " + checkpoint.string() + " is kept"
                                : "; no checkpoint was written yet"));
  }
}

void note_checkpoint(const TrainOptions& options, const std::string& stage, std::int64_t step) {
  if (!options.progress_bar) {
    std::fprintf(stderr, "ropes-train: checkpoint %s step %lld\n", stage.c_str(),
                 static_cast<long long>(step));
    std::fflush(stderr);
  }
  if (options.on_checkpoint)
    options.on_checkpoint(stage, step);
}

nlohmann::json open_run(const ExperimentConfig& config, const TrainingData& data,
                        const fs::path& run_dir, const TrainOptions& options) {
  const fs::path run_json = run_dir / "run.json";
  // not the thread count: every count gives the same bytes (ropes_nn/parallel.hpp), so a
  // run may resume at another
  const nlohmann::json identity = {
      {"config", config.to_json()}, {"dataset", data.dataset_id}, {"seed", options.seed}};
  const nlohmann::json provenance = nn::provenance(options.threads);
  if (fs::exists(run_json)) {
    nlohmann::json run = core::read_json_file(run_json);
    if (!run.is_object() || !run.contains("format") || run["format"] != kRunFormat)
      throw std::invalid_argument(
          run_json.string() + ": not a ropes run (format " +
          (run.is_object() && run.contains("format") ? core::describe(run["format"]) : "missing") +
          ", expected \"" + kRunFormat + "\")");
    for (const auto& [key, value] : identity.items())
      if (run[key] != value)
        throw std::invalid_argument(
            run_dir.string() + " holds a run with another " + key + " (" +
            (key == "config" && run[key].is_object() && run[key]["name"].is_string()
                 ? run[key]["name"].get<std::string>()
                 : core::describe(run[key])) +
            ", this one: " + (key == "config" ? config.name : core::describe(value)) +
            "); choose another --out or remove it");
    // resumed by another build: its weights may differ in the last bits from what the first
    // build would have written; recorded beside the first, once per build (not per resume, and
    // not for another thread count or revision, which change no bit)
    bool known =
        nn::provenance_differences(run.value("provenance", nlohmann::json()), provenance).empty();
    if (run.contains("resumed_under") && run["resumed_under"].is_array())
      for (const nlohmann::json& earlier : run["resumed_under"])
        known = known || nn::provenance_differences(earlier, provenance).empty();
    if (!known) {
      run["resumed_under"].push_back(provenance);
      write_json_file(run_json, run);
    }
    return run;
  }
  if (fs::exists(run_dir) && !fs::is_empty(run_dir))
    throw std::invalid_argument(run_dir.string() +
                                " is not empty and holds no run.json; choose an empty or new "
                                "directory for --out");
  fs::create_directories(run_dir);
  nlohmann::json run = identity;
  run["format"] = kRunFormat;
  run["format_version"] = kRunFormatVersion;
  run["threads"] = options.threads;
  run["provenance"] = provenance;
  run["data_dir"] = fs::absolute(data.dir).string();
  run["versions"] = {{"ropes_crl", ROPES_CRL_VERSION_STRING},
                     {"ropes_nn", ROPES_NN_VERSION_STRING}};
  run["joints"] = config.joints;
  run["stages"] = nlohmann::json::object();
  write_json_file(run_json, run);
  return run;
}

void add_stage_time(nlohmann::json& run, const std::string& stage, double seconds) {
  nlohmann::json& s = run["stages"][stage];
  if (!s.is_object())
    s = nlohmann::json::object();
  s["wall_s"] = s.value("wall_s", 0.0) + seconds;
}

}  // namespace ropes::crl::detail
