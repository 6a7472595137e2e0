// The trainer's stage 3: the AE2s (one a joint, or one for all, and the lambda = 0
// baseline), several at once on a fixed thread plan, and their sparsity matrices.
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

namespace {

// Trains (or resumes) one AE2. Returns false, with a checkpoint of the current step written,
// when `stop` was raised before the last step (another model of the stage failed); true when
// the weights are saved.
bool train_ae2(const ExperimentConfig& config, const TrainingData& data, const ScoreTable& scores,
               const CodeStandardization* codes_map, const Ae2Model& model, const fs::path& run_dir,
               const TrainOptions& options, const MetricsLog& metrics, ProgressBoard* board,
               const std::atomic<bool>& stop) {
  const Ae2Training& t = config.ae2_training;
  Ae2 net(config.ae2);
  net.initialize(derive_seed(options.seed, "ae2.init." + model.name));
  if (config.ae2.input_normalization == "standardize")
    net.set_input_map(*codes_map);
  nn::Adam adam(net.trained_parameters(), nn::AdamOptions{t.optimizer.lr});
  nn::LrSchedule schedule = t.optimizer.make_schedule(t.steps);
  const fs::path weights = ae2_file(run_dir, model.name), checkpoint = checkpoint_of(weights);
  if (fs::exists(checkpoint))
    schedule = resume_from(checkpoint, net, adam).schedule;
  const std::int64_t first = adam.steps();
  const std::string stage = "ae2 " + model.name;
  metrics.truncate([&](const nlohmann::json& r) {
    return r.value("stage", "") != "ae2" || r.value("model", "") != model.name ||
           r.value("step", 0) <= first;
  });

  // the batches of step s: a pure function of s (resume needs only the step count)
  StepSampler recon(data.rows, t.batch_size, derive_seed(options.seed, "ae2.recon." + model.name));
  std::vector<StepSampler> term_samplers;
  for (std::size_t k : model.terms)
    term_samplers.emplace_back(
        static_cast<std::int64_t>(scores.rows[k].size()), t.sparsity_batch_size,
        derive_seed(options.seed, "ae2.scores." + model.name + "." + config.joints[k]));
  // ae2.logit_loss (an extension) on the models with sparsity terms, never the lambda = 0 one
  const bool logit_term = t.logit_loss.weight > 0 && !model.terms.empty();
  Progress progress(stage, t.steps, first, options.progress_bar, config.log_every, board);
  Clock::time_point window = Clock::now();
  std::int64_t window_samples = 0;
  while (adam.steps() < t.steps) {
    const std::int64_t s = adam.steps();
    if (stop.load()) {
      // the batches are a function of the step alone: any step is a valid resume point
      if (s > first)
        nn::save_checkpoint(checkpoint, net, adam, schedule, {options.seed, 0, s},
                            network_metadata("ae2", config.ae2.to_json(), config));
      return false;
    }
    Ae2Batch batch;
    const std::vector<std::int64_t> recon_rows = recon.rows(s);
    batch.reconstruction = data.codes_of(recon_rows);
    for (std::size_t i = 0; i < model.terms.size(); ++i) {
      const std::size_t k = model.terms[i];
      const std::vector<std::int64_t> picked = term_samplers[i].rows(s);
      batch.term_codes.push_back(data.codes_of(scores.dataset_rows(k, picked)));
      batch.term_scores.push_back(scores.scores_of(k, picked));
      batch.targets.push_back(static_cast<std::int64_t>(k));
      if (logit_term)
        batch.term_logits.push_back(scores.logits_of(k, recon_rows));
    }
    batch.logit_weight = logit_term ? t.logit_loss.weight : 0.0;
    std::size_t parts = 1;
    const nn::BatchLoss loss =
        ae2_batch_loss(net, batch, model.lambda, t.norm, t.micro_batch, &parts, t.diagonal);
    nn::StepOptions so;
    so.micro_batches = parts;
    so.schedule = &schedule;
    so.clip_norm = t.optimizer.clip_norm;
    const nn::StepResult r = checked_step(adam, loss, so, stage, checkpoint);
    window_samples += r.samples;
    const std::int64_t step = adam.steps();
    std::string extra;
    if (step % config.log_every == 0 || step == t.steps) {
      nlohmann::json rec = {
          {"stage", "ae2"},
          {"model", model.name},
          {"step", step},
          {"loss", r.loss},
          {"reconstruction", r.means[0][0]},
          {"lr", r.lr},
          {"grad_norm", r.grad_norm},
          {"samples_per_s", static_cast<double>(window_samples) / seconds_since(window)}};
      nlohmann::json rows = nlohmann::json::object();
      if (model.lambda > 0)
        for (std::size_t i = 0; i < model.terms.size(); ++i)
          rows[config.joints[model.terms[i]]] = r.means[1 + i];
      rec["sparsity_rows"] = rows;
      if (logit_term) {  // the batch correlation of each latent with its LDR's logit
        nlohmann::json corr = nlohmann::json::object();
        const std::size_t first_logit = r.means.size() - model.terms.size();
        for (std::size_t i = 0; i < model.terms.size(); ++i) {
          const Tensor m(Shape{5}, r.means[first_logit + i]);
          corr[config.joints[model.terms[i]]] = 1.0 - logit_correlation_loss(m).item();
        }
        rec["logit_correlation"] = corr;
      }
      metrics.append(rec);
      window = Clock::now();
      window_samples = 0;
    }
    progress.update(step, r.loss);
    if (step % config.checkpoint_every == 0 && step < t.steps) {
      nn::save_checkpoint(checkpoint, net, adam, schedule, {options.seed, 0, step},
                          network_metadata("ae2", config.ae2.to_json(), config));
      note_checkpoint(options, stage, step);
    }
  }
  nn::save_module(net, weights,
                  network_metadata("ae2", config.ae2.to_json(), config,
                                   {{"model", model.name}, {"lambda", model.lambda}}));
  fs::remove(checkpoint);
  progress.finish(std::to_string(t.steps) + " steps");
  return true;
}

// sets the kernels' thread count for a scope and restores it
class ThreadCountScope {
 public:
  explicit ThreadCountScope(int n) : saved_(nn::num_threads()) { nn::set_num_threads(n); }
  ~ThreadCountScope() { nn::set_num_threads(saved_); }
  ThreadCountScope(const ThreadCountScope&) = delete;
  ThreadCountScope& operator=(const ThreadCountScope&) = delete;

 private:
  int saved_;
};

}  // namespace

std::vector<Ae2Model> ae2_models(const ExperimentConfig& config) {
  const Ae2Training& t = config.ae2_training;
  std::vector<Ae2Model> models;
  if (t.mode == "per_joint") {
    for (std::size_t k = 0; k < config.joints.size(); ++k)
      models.push_back({config.joints[k], {k}, t.lambda});
  } else {
    std::vector<std::size_t> all(config.joints.size());
    for (std::size_t k = 0; k < all.size(); ++k)
      all[k] = k;
    models.push_back({"joint", all, t.lambda});
  }
  if (t.lambda0_baseline)
    models.push_back({"lambda0", {}, 0.0});
  return models;
}

Ae2Plan ae2_plan(int threads, std::size_t models) {
  Ae2Plan p;
  p.workers = static_cast<int>(
      std::max<std::size_t>(1, std::min(static_cast<std::size_t>(std::max(threads, 1)), models)));
  p.threads_each = std::max(1, threads / p.workers);
  return p;
}

void train_ae2_models(const ExperimentConfig& config, const TrainingData& data,
                      const ScoreTable& scores, const CodeStandardization* codes_map,
                      const std::vector<const Ae2Model*>& todo, const Ae2Plan& plan,
                      const fs::path& run_dir, const TrainOptions& options,
                      const MetricsLog& metrics,
                      const std::function<void(const Ae2Model&, double)>& finished) {
  const ThreadCountScope kernels(plan.threads_each);
  const int workers = std::min<int>(plan.workers, static_cast<int>(todo.size()));
  ProgressBoard board("ae2");
  ProgressBoard* shared = workers > 1 ? &board : nullptr;
  std::atomic<std::size_t> next{0};
  std::atomic<bool> stop{false};
  std::mutex lock;
  std::exception_ptr failure;
  auto work = [&] {
    while (!stop.load()) {
      const std::size_t i = next.fetch_add(1);
      if (i >= todo.size())
        return;
      try {
        const Clock::time_point t0 = Clock::now();
        if (train_ae2(config, data, scores, codes_map, *todo[i], run_dir, options, metrics, shared,
                      stop)) {
          const std::lock_guard<std::mutex> guard(lock);
          finished(*todo[i], seconds_since(t0));
        }
      } catch (...) {
        const std::lock_guard<std::mutex> guard(lock);
        if (!failure)
          failure = std::current_exception();
        stop.store(true);
      }
    }
  };
  if (workers <= 1) {
    work();
  } else {
    std::vector<std::thread> pool;
    for (int w = 0; w < workers; ++w)
      pool.emplace_back(work);
    for (std::thread& t : pool)
      t.join();
  }
  if (failure)
    std::rethrow_exception(failure);
}

nlohmann::json sparsity_matrix(const ExperimentConfig& config, const TrainingData& data,
                               const ScoreTable& scores, const fs::path& weights) {
  Ae2 net(config.ae2);
  nn::load_module(net, weights);
  nlohmann::json m = nlohmann::json::array();
  for (std::size_t k = 0; k < config.joints.size(); ++k) {
    std::vector<double> sum(static_cast<std::size_t>(config.ae2.latent_dim), 0.0);
    const std::int64_t n = static_cast<std::int64_t>(scores.rows[k].size());
    for (std::int64_t b = 0; b < n; b += 256) {
      std::vector<std::int64_t> picked;
      for (std::int64_t j = b; j < std::min<std::int64_t>(n, b + 256); ++j)
        picked.push_back(j);
      const Tensor jtv = latent_score_differences(
          net, data.codes_of(scores.dataset_rows(k, picked)), scores.scores_of(k, picked), false);
      for (std::int64_t i = 0; i < jtv.numel(); ++i)
        sum[static_cast<std::size_t>(i % config.ae2.latent_dim)] += std::fabs(jtv.data()[i]);
    }
    for (double& v : sum)
      v /= static_cast<double>(n);
    m.push_back(sum);
  }
  return m;
}

}  // namespace ropes::crl::detail
