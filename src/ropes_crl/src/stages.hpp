#pragma once
// The trainer's stages and what they share (private to ropes_crl; trainer.hpp is the API):
// checkpoints, steps and the run directory's record (trainer_common.cpp),
// stage 1 AE1 and the codes (stage_ae1.cpp), stage 2 the LDRs (stage_ldr.cpp), stage 3 the
// AE2s and their thread plan (stage_ae2.cpp). train() in trainer.cpp runs them in order.
#include <ropes_nn/adam.hpp>
#include <ropes_nn/checkpoint.hpp>
#include <ropes_nn/module.hpp>
#include <ropes_nn/train_step.hpp>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "ropes_crl/experiment_config.hpp"
#include "ropes_crl/networks.hpp"
#include "ropes_crl/trainer.hpp"
#include "run_files.hpp"
#include "training_data.hpp"

namespace ropes::crl::detail {

using Clock = std::chrono::steady_clock;

// load_checkpoint; a refusal (a damaged or foreign file) says what to do about it
nn::LoadedCheckpoint resume_from(const fs::path& checkpoint, nn::Module& net, nn::Adam& adam);

double seconds_since(Clock::time_point t);

std::map<std::string, std::string> network_metadata(const std::string& kind,
                                                    const nlohmann::json& spec,
                                                    const ExperimentConfig& config,
                                                    const nlohmann::json& extra = {});

// one update; a loss or gradient that is not finite names the stage and the step and keeps
// the last checkpoint (train_step changes nothing when it refuses)
nn::StepResult checked_step(nn::Adam& adam, const nn::BatchLoss& loss, const nn::StepOptions& so,
                            const std::string& stage, const fs::path& checkpoint);

// a log line (plain logs only) and the test hook, after each checkpoint
void note_checkpoint(const TrainOptions& options, const std::string& stage, std::int64_t step);

nlohmann::json open_run(const ExperimentConfig& config, const TrainingData& data,
                        const fs::path& run_dir, const TrainOptions& options);

void add_stage_time(nlohmann::json& run, const std::string& stage, double seconds);

void train_ae1(const ExperimentConfig& config, const TrainingData& data, const fs::path& run_dir,
               const TrainOptions& options, const MetricsLog& metrics);

// Y = E1(x) of every row, cams' codes concatenated along channels: [rows, C, 8, 8]
void encode_codes(const ExperimentConfig& config, const TrainingData& data,
                  const fs::path& run_dir);

struct LdrOutcome {
  double loss = 0, accuracy = 0;
  std::int64_t epochs = 0;
};

LdrOutcome train_ldr(const ExperimentConfig& config, const TrainingData& data,
                     const CodeStandardization* codes_map, const JointRegimes& joint,
                     const TrainOptions& options, const MetricsLog& metrics,
                     const fs::path& weights, bool bar);

// ldr.all_regimes: one classifier over every regime, trained once; each joint's LDR saved to
// ldr_file(run_dir, joint) as a plain classifier. The outcomes in data.joints order.
std::vector<LdrOutcome> train_ldrs_all_regimes(
    const ExperimentConfig& config, const TrainingData& data, const CodeStandardization* codes_map,
    const TrainOptions& options, const MetricsLog& metrics, const fs::path& run_dir, bool bar);

struct Ae2Model {
  std::string name;                ///< file stem: a joint's name, "joint" or "lambda0"
  std::vector<std::size_t> terms;  ///< indices into config.joints (= target latents)
  double lambda = 0;
};

std::vector<Ae2Model> ae2_models(const ExperimentConfig& config);

// How stage 3 uses the threads: an AE2 step is too small to share between threads (a
// 2-thread step takes as long as a 1-thread one, the second thread waiting), so up to
// `threads` AE2s train at once, each on threads / workers threads. A function of the thread
// count and the number of models of the config alone, never of what is left to train, so a
// resumed stage computes with the same thread count as an uninterrupted one.
struct Ae2Plan {
  int workers = 1, threads_each = 1;
};

Ae2Plan ae2_plan(int threads, std::size_t models);

// Trains the models of `todo` on plan.workers threads, each model on plan.threads_each
// kernel threads; `finished(model, seconds)` is called (under a lock) as each one finishes.
// The first failure stops the others at their next step, each with a checkpoint of the step
// it reached, and is rethrown once every worker has stopped.
void train_ae2_models(const ExperimentConfig& config, const TrainingData& data,
                      const ScoreTable& scores, const CodeStandardization* codes_map,
                      const std::vector<const Ae2Model*>& todo, const Ae2Plan& plan,
                      const fs::path& run_dir, const TrainOptions& options,
                      const MetricsLog& metrics,
                      const std::function<void(const Ae2Model&, double)>& finished);

// row k of model m's sparsity matrix: E|J_g^T v_k| over joint k's score rows
nlohmann::json sparsity_matrix(const ExperimentConfig& config, const TrainingData& data,
                               const ScoreTable& scores, const fs::path& weights);

}  // namespace ropes::crl::detail
