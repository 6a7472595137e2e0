// The trainer's stage 2: one LDR classifier a joint, early-stopped on held-out anchors; or,
// with ldr.all_regimes, one classifier over every regime that each joint's LDR is read from.
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

// softplus(-d) for label 1, softplus(d) for label 0: the BCE of logit d, in double
double logit_bce(double d, bool positive) {
  const double x = positive ? -d : d;
  return std::max(x, 0.0) + std::log1p(std::exp(-std::abs(x)));
}

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

std::vector<LdrOutcome> train_ldrs_all_regimes(
    const ExperimentConfig& config, const TrainingData& data, const CodeStandardization* codes_map,
    const TrainOptions& options, const MetricsLog& metrics, const fs::path& run_dir, bool bar) {
  const LdrTraining& t = config.ldr_training;
  const std::size_t joints = data.joints.size();
  // the classes: joint j's intervention 1 is 2j, its intervention 2 is 2j + 1; with the
  // observational samples, those are 2 x joints
  std::map<std::int32_t, std::int64_t> class_of_regime;
  for (std::size_t j = 0; j < joints; ++j) {
    class_of_regime[data.joints[j].regime1] = static_cast<std::int64_t>(2 * j);
    class_of_regime[data.joints[j].regime2] = static_cast<std::int64_t>(2 * j + 1);
  }
  const auto classes =
      static_cast<std::int64_t>(2 * joints + (t.all_regimes.observational ? 1 : 0));
  std::vector<std::int64_t> class_of(static_cast<std::size_t>(data.rows), -1);
  std::vector<std::int64_t> train_rows, held_rows;
  for (std::int64_t r = 0; r < data.rows; ++r) {
    const auto u = static_cast<std::size_t>(r);
    if (const auto it = class_of_regime.find(data.regime[u]); it != class_of_regime.end())
      class_of[u] = it->second;
    else if (t.all_regimes.observational && data.observational_row[u] == r)
      class_of[u] = classes - 1;
    if (class_of[u] >= 0)
      (data.held_out_anchor(r) ? held_rows : train_rows).push_back(r);
  }
  if (train_rows.empty() || held_rows.empty())
    throw std::invalid_argument("ldr.all_regimes: the held-out split of " +
                                std::to_string(train_rows.size() + held_rows.size()) +
                                " samples leaves one side empty; the dataset needs more anchors");
  RegimeClassifier net(config.ldr, classes);
  net.initialize(derive_seed(options.seed, "ldr.init.all_regimes"));
  if (config.ldr.input_normalization == "standardize")
    net.set_input_map(*codes_map);
  // the pair loss: each training row's partner and its joint
  const double pair_weight = t.pair_loss.weight;
  std::map<std::int64_t, std::pair<std::int64_t, std::size_t>> partner;
  if (pair_weight > 0)
    for (std::size_t j = 0; j < joints; ++j)
      for (const auto& [r1, r2] : data.training_pairs(data.joints[j])) {
        partner[r1] = {r2, j};
        partner[r2] = {r1, j};
      }
  std::vector<Tensor> trained;
  std::vector<std::pair<std::string, Tensor>> named = net.trained_parameters();
  nn::Adam adam(named, nn::AdamOptions{t.optimizer.lr});
  std::unique_ptr<WeightAverage> average;
  if (t.weight_average.decay > 0) {
    for (const auto& [name, w] : named)
      trained.push_back(w);
    average = std::make_unique<WeightAverage>(std::move(trained), t.weight_average.decay);
  }
  const std::int64_t batches =
      (static_cast<std::int64_t>(train_rows.size()) + t.batch_size - 1) / t.batch_size;
  nn::LrSchedule schedule = t.optimizer.make_schedule(batches * t.max_epochs);
  const auto one_hot_of = [&](const std::vector<std::int64_t>& rows) {
    std::vector<float> v(rows.size() * static_cast<std::size_t>(classes), 0.0f);
    for (std::size_t i = 0; i < rows.size(); ++i)
      v[i * static_cast<std::size_t>(classes) +
        static_cast<std::size_t>(class_of[static_cast<std::size_t>(rows[i])])] = 1.0f;
    return Tensor(Shape{static_cast<std::int64_t>(rows.size()), classes}, v);
  };
  // the held-out cross-entropy, and each joint's LDR's held-out BCE and accuracy on its rows
  struct Held {
    double loss = 0;
    std::vector<double> joint_loss, joint_accuracy;
  };
  const auto evaluate = [&] {
    nn::GradModeGuard no_grad(false);
    Held h;
    std::vector<double> loss(joints, 0), correct(joints, 0), count(joints, 0);
    for (std::size_t b = 0; b < held_rows.size(); b += 512) {
      const std::vector<std::int64_t> part(
          held_rows.begin() + static_cast<std::ptrdiff_t>(b),
          held_rows.begin() + static_cast<std::ptrdiff_t>(std::min(held_rows.size(), b + 512)));
      const Tensor f = net(data.codes_of(part));
      h.loss += nn::sum(softmax_cross_entropy(f, one_hot_of(part))).item();
      for (std::size_t i = 0; i < part.size(); ++i) {
        const std::int64_t c = class_of[static_cast<std::size_t>(part[i])];
        if (c >= 2 * static_cast<std::int64_t>(joints))
          continue;
        const auto j = static_cast<std::size_t>(c / 2);
        const float* row = f.data() + i * static_cast<std::size_t>(classes);
        const double d = static_cast<double>(row[2 * j + 1]) - static_cast<double>(row[2 * j]);
        const bool positive = c % 2 == 1;
        loss[j] += logit_bce(d, positive);
        correct[j] += (d > 0) == positive ? 1 : 0;
        count[j] += 1;
      }
    }
    h.loss /= static_cast<double>(held_rows.size());
    for (std::size_t j = 0; j < joints; ++j) {
      h.joint_loss.push_back(count[j] > 0 ? loss[j] / count[j] : NAN);
      h.joint_accuracy.push_back(count[j] > 0 ? correct[j] / count[j] : NAN);
    }
    return h;
  };
  // each joint's LDR is kept at the epoch of its own lowest held-out loss, as a per-joint
  // classifier's early stopping would keep it; the stage stops when no joint's has fallen for
  // `patience` epochs
  std::vector<std::vector<std::vector<float>>> best(joints);
  std::vector<double> best_loss(joints, INFINITY), best_accuracy(joints, 0);
  std::vector<std::int64_t> best_epoch(joints, 0);
  std::int64_t since_best = 0, epoch = 0;
  Progress progress("ldr all regimes", t.max_epochs, 0, bar, 1);
  const fs::path checkpoint_name = run_dir / "ldr.all_regimes";
  for (; epoch < t.max_epochs && since_best < t.patience; ++epoch) {
    const std::vector<std::int64_t> order = core::shuffled_indices(
        static_cast<std::int64_t>(train_rows.size()),
        derive_seed(options.seed, "ldr.data.all_regimes"), static_cast<std::uint64_t>(epoch));
    double train_loss = 0;
    for (std::int64_t b = 0; b < batches; ++b) {
      std::vector<std::int64_t> rows;
      for (std::int64_t k = b * t.batch_size;
           k < std::min<std::int64_t>((b + 1) * t.batch_size, train_rows.size()); ++k)
        rows.push_back(train_rows[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])]);
      const Tensor y = data.codes_of(rows);
      const Tensor one_hot = one_hot_of(rows);
      // with the pair loss: each interventional row with its partner, (intervention 1,
      // intervention 2), and the sign row that reads LDR_j = f_{2j+1} - f_{2j} of the pair
      std::vector<std::int64_t> firsts, seconds;
      std::vector<float> signs;
      if (pair_weight > 0)
        for (std::int64_t r : rows)
          if (const auto it = partner.find(r); it != partner.end()) {
            const auto [other, j] = it->second;
            const bool first = data.regime[static_cast<std::size_t>(r)] == data.joints[j].regime1;
            firsts.push_back(first ? r : other);
            seconds.push_back(first ? other : r);
            std::vector<float> s(static_cast<std::size_t>(classes), 0.0f);
            s[2 * j] = -1.0f;
            s[2 * j + 1] = 1.0f;
            signs.insert(signs.end(), s.begin(), s.end());
          }
      const auto n = static_cast<std::int64_t>(rows.size());
      const auto p = static_cast<std::int64_t>(firsts.size());
      Tensor pair_codes, sign;  // outlive the loss, which reads them
      if (p > 0) {
        std::vector<std::int64_t> both = firsts;
        both.insert(both.end(), seconds.begin(), seconds.end());
        pair_codes = data.codes_of(both);
        sign = Tensor(Shape{p, classes}, signs);
      }
      nn::StepOptions so;
      so.schedule = &schedule;
      so.clip_norm = t.optimizer.clip_norm;
      // the cross-entropy's per-sample terms, then the pairs', scaled so that their mean is the
      // cross-entropy's mean + weight x the pairs' mean
      nn::BatchLoss loss = nn::mean_loss([&](std::size_t) {
        const Tensor ce = softmax_cross_entropy(net(y), one_hot);
        if (p == 0)
          return ce;
        const float total = static_cast<float>(n + p);
        const Tensor f = net(pair_codes);  // [2p, R]: firsts, then seconds
        const Tensor d = nn::reshape(
            nn::sum(nn::mul(nn::sub(nn::slice(f, 0, p, 2 * p), nn::slice(f, 0, 0, p)), sign), {1}),
            Shape{p});
        const Tensor pair = nn::bce_with_logits_elementwise(
            d, Tensor(Shape{p}, nn::Buffer(static_cast<std::size_t>(p), 1.0f)));
        return nn::concat(
            {nn::mul_scalar(ce, total / static_cast<float>(n)),
             nn::mul_scalar(pair, static_cast<float>(pair_weight) * total / static_cast<float>(p))},
            0);
      });
      train_loss += checked_step(adam, loss, so, "ldr all regimes", checkpoint_name).loss;
      if (average)
        average->update();
    }
    if (average)
      average->swap();
    const Held held = evaluate();
    metrics.append({{"stage", "ldr"},
                    {"joint", "all_regimes"},
                    {"epoch", epoch + 1},
                    {"train_loss", train_loss / static_cast<double>(batches)},
                    {"held_out_loss", held.loss}});
    std::string accuracies;
    for (std::size_t j = 0; j < joints; ++j) {
      metrics.append({{"stage", "ldr"},
                      {"joint", data.joints[j].name},
                      {"epoch", epoch + 1},
                      {"held_out_loss", held.joint_loss[j]},
                      {"held_out_accuracy", held.joint_accuracy[j]},
                      {"bayes_accuracy", data.joints[j].bayes_accuracy}});
      accuracies += (j ? " " : "acc ") + std::to_string(held.joint_accuracy[j]).substr(0, 5);
    }
    progress.update(epoch + 1, held.loss, accuracies);
    bool improved = false;
    for (std::size_t j = 0; j < joints; ++j)
      if (held.joint_loss[j] < best_loss[j]) {
        improved = true;
        best_loss[j] = held.joint_loss[j];
        best_accuracy[j] = held.joint_accuracy[j];
        best_epoch[j] = epoch + 1;
        best[j].clear();
        for (const Tensor& w : net.parameters())
          best[j].push_back(w.to_vector());
      }
    since_best = improved ? 0 : since_best + 1;
    if (average)
      average->swap();
  }
  // each joint's LDR from its kept weights: the trunk, and the difference of its two columns
  // of the output layer
  std::vector<Tensor> params = net.parameters();
  std::vector<LdrOutcome> outcomes;
  for (std::size_t j = 0; j < joints; ++j) {
    const JointRegimes& joint = data.joints[j];
    if (best[j].empty())
      throw std::invalid_argument("ldr.all_regimes: joint " + joint.name +
                                  " has no held-out sample of its interventions to stop on; the "
                                  "dataset needs more anchors");
    for (std::size_t i = 0; i < params.size(); ++i)
      std::copy(best[j][i].begin(), best[j][i].end(), params[i].mutable_data());
    Ldr ldr(config.ldr);
    net.write_ratio(static_cast<std::int64_t>(2 * j + 1), static_cast<std::int64_t>(2 * j), ldr);
    const LdrOutcome o{best_loss[j], best_accuracy[j], epoch};
    nn::save_module(ldr, ldr_file(run_dir, joint.name),
                    network_metadata("ldr", config.ldr.to_json(), config,
                                     {{"joint", joint.name},
                                      {"all_regimes", true},
                                      {"held_out_loss", o.loss},
                                      {"held_out_accuracy", o.accuracy},
                                      {"bayes_accuracy", joint.bayes_accuracy},
                                      {"epochs", epoch},
                                      {"kept_epoch", best_epoch[j]}}));
    outcomes.push_back(o);
  }
  std::string kept;
  for (std::size_t j = 0; j < joints; ++j)
    kept += (j ? " " : "") + std::to_string(best_accuracy[j]).substr(0, 5);
  progress.finish("held-out accuracy " + kept + " after " + std::to_string(epoch) + " epochs");
  return outcomes;
}

}  // namespace ropes::crl::detail
