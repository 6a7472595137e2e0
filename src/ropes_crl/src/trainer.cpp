#include "ropes_crl/trainer.hpp"

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
#include "stages.hpp"
#include "training_data.hpp"

namespace ropes::crl {

using namespace detail;
using nn::Shape;

const char* ropes_crl_version() {
  return ROPES_CRL_VERSION_STRING;
}

void train(const ExperimentConfig& config_in, const fs::path& data_dir, const fs::path& run_dir,
           const TrainOptions& options) {
  if (options.last_stage < 1 || options.last_stage > 3)
    throw std::invalid_argument("train: last_stage is " + std::to_string(options.last_stage) +
                                "; expected 1 (AE1), 2 (the LDRs) or 3 (AE2)");
  nn::set_num_threads(options.threads);
  ExperimentConfig config = config_in;
  TrainingData data = TrainingData::open(config, data_dir, options.seed);
  config.resolve_epochs(data.rows * config.cameras);
  nlohmann::json run = open_run(config_in, data, run_dir, options);
  const fs::path run_json = run_dir / "run.json";
  core::remove_stale_temporaries(run_dir);
  const MetricsLog metrics(run_dir / "metrics.jsonl", options.on_metrics);
  // a kill between a network's final weights and the removal of its checkpoint leaves the
  // checkpoint of a finished network behind (found by ropes_eval's fault-injection test): it
  // goes now, so that a resumed run ends with the files of an uninterrupted one
  std::vector<fs::path> networks = {ae1_file(run_dir)};
  for (const Ae2Model& model : ae2_models(config))
    networks.push_back(ae2_file(run_dir, model.name));
  for (const fs::path& weights : networks)
    if (fs::exists(weights))
      fs::remove(checkpoint_of(weights));

  // stage 1: AE1, then the codes
  if (!fs::exists(codes_file(run_dir))) {
    const Clock::time_point t0 = Clock::now();
    if (!fs::exists(ae1_file(run_dir)))
      train_ae1(config, data, run_dir, options, metrics);
    encode_codes(config, data, run_dir);
    add_stage_time(run, "ae1", seconds_since(t0));
    run["stages"]["ae1"]["steps"] = config.ae1_training.steps;
    write_json_file(run_json, run);
  }
  if (options.last_stage == 1)
    return;
  data.load_codes(codes_file(run_dir));
  // the map of standardised codes, for the networks that read them: fitted once on every
  // code of the training anchors (all regimes), never on the held-out anchors that the LDRs'
  // early stopping reads
  std::unique_ptr<CodeStandardization> codes_map;
  if (config.ldr.input_normalization == "standardize" ||
      config.ae2.input_normalization == "standardize") {
    codes_map =
        std::make_unique<CodeStandardization>(config.ae2.in_channels, config.ae2.input_size);
    codes_map->fit(data.training_anchor_codes(),
                   "the standardised codes of " + codes_file(run_dir).string());
  }

  // stage 2: one LDR per joint; with ldr.all_regimes one classifier for all, trained again
  // unless every joint's LDR is there (each file is written whole, the last one last)
  bool all_ldrs = true;
  for (const JointRegimes& joint : data.joints)
    all_ldrs = all_ldrs && fs::exists(ldr_file(run_dir, joint.name));
  if (config.ldr_training.all_regimes.on && !all_ldrs) {
    metrics.truncate([](const nlohmann::json& r) { return r.value("stage", "") != "ldr"; });
    const Clock::time_point t0 = Clock::now();
    const std::vector<LdrOutcome> outcomes = train_ldrs_all_regimes(
        config, data, codes_map.get(), options, metrics, run_dir, options.progress_bar);
    add_stage_time(run, "ldr", seconds_since(t0));
    for (std::size_t j = 0; j < data.joints.size(); ++j)
      run["ldr"][data.joints[j].name] = {{"held_out_loss", outcomes[j].loss},
                                         {"held_out_accuracy", outcomes[j].accuracy},
                                         {"bayes_accuracy", data.joints[j].bayes_accuracy},
                                         {"epochs", outcomes[j].epochs}};
    write_json_file(run_json, run);
  }
  for (const JointRegimes& joint : data.joints) {
    const fs::path weights = ldr_file(run_dir, joint.name);
    if (fs::exists(weights))
      continue;
    metrics.truncate([&](const nlohmann::json& r) {
      return r.value("stage", "") != "ldr" || r.value("joint", "") != joint.name;
    });
    const Clock::time_point t0 = Clock::now();
    const LdrOutcome o = train_ldr(config, data, codes_map.get(), joint, options, metrics, weights,
                                   options.progress_bar);
    add_stage_time(run, "ldr", seconds_since(t0));
    run["ldr"][joint.name] = {{"held_out_loss", o.loss},
                              {"held_out_accuracy", o.accuracy},
                              {"bayes_accuracy", joint.bayes_accuracy},
                              {"epochs", o.epochs}};
    write_json_file(run_json, run);
  }

  if (options.last_stage == 2)
    return;

  // score differences v_k(y) = grad_y LDR_k(y), from the frozen classifiers, in AE2's
  // coordinates
  const ScoreTable scores = ScoreTable::compute(
      config, data, run_dir,
      config.ae2.input_normalization == "standardize" ? codes_map.get() : nullptr);

  // stage 3: AE2 (one a joint, or one for all) and the lambda = 0 baseline, several at once
  // (see ae2_plan)
  const std::vector<Ae2Model> models = ae2_models(config);
  const Ae2Plan plan = ae2_plan(options.threads, models.size());
  std::vector<const Ae2Model*> todo;
  for (const Ae2Model& model : models)
    if (!fs::exists(ae2_file(run_dir, model.name)))
      todo.push_back(&model);
  if (!todo.empty()) {
    const Clock::time_point t0 = Clock::now();
    nlohmann::json& stage = run["stages"]["ae2"];
    stage["models_at_once"] = plan.workers;
    stage["threads_each"] = plan.threads_each;
    train_ae2_models(config, data, scores, codes_map.get(), todo, plan, run_dir, options, metrics,
                     [&](const Ae2Model& model, double seconds) {
                       stage["models"][model.name]["wall_s"] = seconds;
                       write_json_file(run_json, run);
                     });
    add_stage_time(run, "ae2", seconds_since(t0));
  }
  for (const Ae2Model& model : models)
    run["sparsity_matrix"][model.name] =
        sparsity_matrix(config, data, scores, ae2_file(run_dir, model.name));
  write_json_file(run_json, run);
  run["complete"] = true;
  write_json_file(run_json, run);
}

}  // namespace ropes::crl
