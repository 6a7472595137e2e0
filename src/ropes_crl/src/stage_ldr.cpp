// The trainer's stage 2: one LDR classifier a joint, early-stopped on held-out anchors.
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

// held-out loss and accuracy of `net` on `rows`
std::pair<double, double> ldr_evaluate(Ldr& net, const TrainingData& data,
                                       const std::vector<std::int64_t>& rows,
                                       std::int32_t positive) {
  nn::GradModeGuard no_grad(false);
  double loss = 0, correct = 0;
  for (std::size_t b = 0; b < rows.size(); b += 512) {
    const std::vector<std::int64_t> part(
        rows.begin() + static_cast<std::ptrdiff_t>(b),
        rows.begin() + static_cast<std::ptrdiff_t>(std::min(rows.size(), b + 512)));
    const Tensor logits = net(data.codes_of(part));
    const Tensor labels = data.labels_of(part, positive);
    loss += nn::sum(nn::bce_with_logits_elementwise(logits, labels)).item();
    for (std::size_t i = 0; i < part.size(); ++i)
      correct += (logits.data()[i] > 0) == (labels.data()[i] > 0.5f) ? 1 : 0;
  }
  return {loss / static_cast<double>(rows.size()), correct / static_cast<double>(rows.size())};
}

// ldr.weight_average: the running average of a network's trained weights (LdrWeightAverage)
class WeightAverage {
 public:
  WeightAverage(std::vector<Tensor> weights, double decay)
      : weights_(std::move(weights)), decay_(decay) {
    for (const Tensor& w : weights_)
      average_.push_back(w.to_vector());
  }
  // after each optimiser step
  void update() {
    const auto d = static_cast<float>(
        std::min(decay_, static_cast<double>(1 + step_) / static_cast<double>(10 + step_)));
    ++step_;
    for (std::size_t i = 0; i < weights_.size(); ++i) {
      float* e = average_[i].data();
      const float* w = weights_[i].data();
      for (std::size_t j = 0; j < average_[i].size(); ++j)
        e[j] = d * e[j] + (1.0f - d) * w[j];
    }
  }
  // exchanges the averaged and the trained values in the network's weights (between steps)
  void swap() {
    for (std::size_t i = 0; i < weights_.size(); ++i)
      std::swap_ranges(average_[i].begin(), average_[i].end(), weights_[i].mutable_data());
  }

 private:
  std::vector<Tensor> weights_;
  std::vector<std::vector<float>> average_;
  double decay_;
  std::int64_t step_ = 0;
};

}  // namespace

LdrOutcome train_ldr(const ExperimentConfig& config, const TrainingData& data,
                     const CodeStandardization* codes_map, const JointRegimes& joint,
                     const TrainOptions& options, const MetricsLog& metrics,
                     const fs::path& weights, bool bar) {
  const LdrTraining& t = config.ldr_training;
  Ldr net(config.ldr);
  net.initialize(derive_seed(options.seed, "ldr.init." + joint.name));
  std::vector<std::int64_t> train_rows, held_rows;
  for (std::int64_t r : joint.rows)
    (data.held_out_anchor(r) ? held_rows : train_rows).push_back(r);
  if (train_rows.empty() || held_rows.empty())
    throw std::invalid_argument("joint " + joint.name + ": the held-out split of " +
                                std::to_string(joint.rows.size()) +
                                " interventional samples leaves one side empty; the dataset "
                                "needs more anchors");
  if (config.ldr.input_normalization == "standardize")
    net.set_input_map(*codes_map);
  // the pair loss (an extension): each training row's partner, the row of the joint's other
  // intervention at the same anchor
  const double pair_weight = t.pair_loss.weight;
  std::map<std::int64_t, std::int64_t> partner;
  if (pair_weight > 0)
    for (const auto& [r1, r2] : data.training_pairs(joint)) {
      partner[r1] = r2;
      partner[r2] = r1;
    }
  nn::Adam adam(net.trained_parameters(), nn::AdamOptions{t.optimizer.lr});
  // the weight average (an extension): evaluated, early-stopped and saved in place of the
  // trained weights
  std::unique_ptr<WeightAverage> average;
  if (t.weight_average.decay > 0) {
    std::vector<Tensor> trained;
    for (const auto& [name, w] : net.trained_parameters())
      trained.push_back(w);
    average = std::make_unique<WeightAverage>(std::move(trained), t.weight_average.decay);
  }
  const std::int64_t batches =
      (static_cast<std::int64_t>(train_rows.size()) + t.batch_size - 1) / t.batch_size;
  nn::LrSchedule schedule = t.optimizer.make_schedule(batches * t.max_epochs);
  std::vector<std::vector<float>> best;
  double best_loss = INFINITY, best_accuracy = 0;
  std::int64_t since_best = 0, epoch = 0;
  Progress progress("ldr " + joint.name, t.max_epochs, 0, bar, 1);
  for (; epoch < t.max_epochs && since_best < t.patience; ++epoch) {
    const std::vector<std::int64_t> order = core::shuffled_indices(
        static_cast<std::int64_t>(train_rows.size()),
        derive_seed(options.seed, "ldr.data." + joint.name), static_cast<std::uint64_t>(epoch));
    double train_loss = 0;
    for (std::int64_t b = 0; b < batches; ++b) {
      std::vector<std::int64_t> rows;
      for (std::int64_t k = b * t.batch_size;
           k < std::min<std::int64_t>((b + 1) * t.batch_size, train_rows.size()); ++k)
        rows.push_back(train_rows[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])]);
      const Tensor y = data.codes_of(rows);
      const Tensor labels = data.labels_of(rows, joint.regime2);
      nn::StepOptions so;
      so.schedule = &schedule;
      so.clip_norm = t.optimizer.clip_norm;
      // with the pair loss: each row with its partner, (intervention 1, intervention 2)
      std::vector<std::int64_t> firsts, seconds;
      if (pair_weight > 0)
        for (std::int64_t r : rows)
          if (const auto it = partner.find(r); it != partner.end()) {
            const bool first = data.regime[static_cast<std::size_t>(r)] == joint.regime1;
            firsts.push_back(first ? r : it->second);
            seconds.push_back(first ? it->second : r);
          }
      Tensor pair_codes;  // outlives the loss, which reads it
      if (!firsts.empty()) {
        std::vector<std::int64_t> both = firsts;
        both.insert(both.end(), seconds.begin(), seconds.end());
        pair_codes = data.codes_of(both);
      }
      const auto n = static_cast<std::int64_t>(rows.size());
      const auto p = static_cast<std::int64_t>(firsts.size());
      // one member's per-sample terms: the BCE's, then with the pair loss the pairs', scaled so
      // that their mean is the BCE's mean + weight x the pairs' mean
      // (pair_logits_of is called after the BCE, the order of the single classifier's graph)
      const auto member_terms = [&](const Tensor& logits,
                                    const std::function<Tensor()>& pair_logits_of) {
        const Tensor bce = nn::bce_with_logits_elementwise(logits, labels);
        if (p == 0)
          return bce;
        const float total = static_cast<float>(n + p);
        const Tensor pair_logits = pair_logits_of();  // [2p]: firsts, then seconds
        const Tensor d =
            nn::sub(nn::slice(pair_logits, 0, p, 2 * p), nn::slice(pair_logits, 0, 0, p));
        const Tensor pair = nn::bce_with_logits_elementwise(
            d, Tensor(Shape{p}, nn::Buffer(static_cast<std::size_t>(p), 1.0f)));
        return nn::concat(
            {nn::mul_scalar(bce, total / static_cast<float>(n)),
             nn::mul_scalar(pair, static_cast<float>(pair_weight) * total / static_cast<float>(p))},
            0);
      };
      nn::BatchLoss loss = nn::mean_loss([&](std::size_t) {
        if (config.ldr.members == 1)  // one classifier: its loss as before the option
          return member_terms(net(y), [&] { return net(pair_codes); });
        // an ensemble: each member's own loss, summed (the members share no parameter, so each
        // gets the gradient it would alone); the mean over K x terms, times K, is that sum
        const std::vector<Tensor> logits = net.member_logits(y);
        std::vector<Tensor> pair_logits;
        if (p > 0)
          pair_logits = net.member_logits(pair_codes);
        std::vector<Tensor> terms;
        for (std::size_t k = 0; k < logits.size(); ++k)
          terms.push_back(member_terms(logits[k], [&] { return pair_logits[k]; }));
        return nn::mul_scalar(nn::concat(terms, 0), static_cast<float>(logits.size()));
      });
      train_loss += checked_step(adam, loss, so, "ldr " + joint.name, weights).loss;
      if (average)
        average->update();
    }
    if (average)  // the averaged weights in place until the epoch's end
      average->swap();
    const auto [loss, accuracy] = ldr_evaluate(net, data, held_rows, joint.regime2);
    metrics.append({{"stage", "ldr"},
                    {"joint", joint.name},
                    {"epoch", epoch + 1},
                    {"train_loss", train_loss / static_cast<double>(batches)},
                    {"held_out_loss", loss},
                    {"held_out_accuracy", accuracy},
                    {"bayes_accuracy", joint.bayes_accuracy}});
    progress.update(epoch + 1, loss,
                    "acc " + std::to_string(accuracy).substr(0, 5) + " (Bayes " +
                        std::to_string(joint.bayes_accuracy).substr(0, 5) + ")");
    if (loss < best_loss) {
      best_loss = loss;
      best_accuracy = accuracy;
      since_best = 0;
      best.clear();
      for (const Tensor& p : net.parameters())
        best.push_back(p.to_vector());
    } else {
      ++since_best;
    }
    if (average)
      average->swap();
  }
  // the early-stopped weights
  std::vector<Tensor> params = net.parameters();
  for (std::size_t i = 0; i < params.size(); ++i)
    std::copy(best[i].begin(), best[i].end(), params[i].mutable_data());
  LdrOutcome out{best_loss, best_accuracy, epoch};
  nn::save_module(net, weights,
                  network_metadata("ldr", config.ldr.to_json(), config,
                                   {{"joint", joint.name},
                                    {"held_out_loss", best_loss},
                                    {"held_out_accuracy", best_accuracy},
                                    {"bayes_accuracy", joint.bayes_accuracy},
                                    {"epochs", epoch}}));
  progress.finish("held-out accuracy " + std::to_string(best_accuracy) + " (Bayes " +
                  std::to_string(joint.bayes_accuracy) + ") after " + std::to_string(epoch) +
                  " epochs");
  return out;
}

}  // namespace ropes::crl::detail
