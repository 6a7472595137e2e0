// The trainer's stage 1: AE1, then the codes of every row (codes.npy).
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

// A linear pair head: y [N, C, 8, 8] -> flatten -> Dense(C*8*8 -> 1) -> [N]
class LinearHead : public nn::Module {
 public:
  explicit LinearHead(std::int64_t in_features)
      : dense_(register_module("dense", std::make_shared<nn::Dense>(in_features, 1))) {}

 protected:
  Tensor forward(const Tensor& y) override {
    return nn::reshape((*dense_)(nn::flatten(y)), Shape{y.shape()[0]});
  }

 private:
  std::shared_ptr<nn::Dense> dense_;
};

// AE1 with its pair heads (config.ae1.pair_heads): one module, so that the optimiser and the
// checkpoint hold both; AE1's parameters come first, named "ae1.<name>", the heads' after
// them, "pair_head.<joint>.<name>". Only AE1 is saved at the end.
class Ae1WithPairHeads : public nn::Module {
 public:
  Ae1WithPairHeads(const std::shared_ptr<Ae1>& ae1,
                   const std::vector<std::shared_ptr<nn::Module>>& heads,
                   const std::vector<JointRegimes>& joints) {
    register_module("ae1", ae1);
    for (std::size_t k = 0; k < heads.size(); ++k)
      register_module("pair_head." + joints[k].name, heads[k]);
  }

 protected:
  Tensor forward(const Tensor&) override {
    throw std::logic_error("Ae1WithPairHeads holds AE1 and its heads for training; call them");
  }
};

// Each joint's training pairs (TrainingData::training_pairs); a joint without any is refused.
std::vector<std::vector<std::pair<std::int64_t, std::int64_t>>> intervention_pairs(
    const TrainingData& data) {
  std::vector<std::vector<std::pair<std::int64_t, std::int64_t>>> out;
  for (const JointRegimes& j : data.joints) {
    out.push_back(data.training_pairs(j));
    if (out.back().empty())
      throw std::invalid_argument(
          "config.ae1.pair_heads pairs each joint's two interventions at one anchor; " +
          data.dir.string() + " has no training anchor with both interventions of joint " + j.name);
  }
  return out;
}

}  // namespace

void train_ae1(const ExperimentConfig& config, const TrainingData& data, const fs::path& run_dir,
               const TrainOptions& options, const MetricsLog& metrics) {
  const Ae1Training& t = config.ae1_training;
  const auto ae1 = std::make_shared<Ae1>(config.ae1);
  Ae1& net = *ae1;
  net.initialize(derive_seed(options.seed, "ae1.init"));

  // the pair heads (an extension): a head a joint (the LDR's architecture or linear), trained
  // with AE1
  const PairHeads& pair_config = t.pair_heads;
  const bool with_heads = pair_config.weight > 0;
  std::vector<std::shared_ptr<nn::Module>> heads;
  std::unique_ptr<Ae1WithPairHeads> with_pair_heads;
  std::vector<std::vector<std::pair<std::int64_t, std::int64_t>>> pairs_of;
  if (with_heads) {
    LdrSpec spec = config.ldr;
    spec.input_normalization = "none";
    spec.members = 1;  // a pair head is one classifier
    const std::int64_t code = config.ae1.code_size();
    for (const JointRegimes& j : data.joints) {
      if (pair_config.head == "linear")
        heads.push_back(std::make_shared<LinearHead>(config.code_channels() * code * code));
      else
        heads.push_back(std::make_shared<Ldr>(spec));
      heads.back()->initialize(derive_seed(options.seed, "ae1.pair_heads"), j.name);
    }
    with_pair_heads = std::make_unique<Ae1WithPairHeads>(ae1, heads, data.joints);
    pairs_of = intervention_pairs(data);
  }
  nn::Module& trained = with_heads ? static_cast<nn::Module&>(*with_pair_heads) : net;
  nn::Adam adam(trained.named_parameters(), nn::AdamOptions{t.optimizer.lr});
  nn::LrSchedule schedule = t.optimizer.make_schedule(t.steps);

  // the difference loss (a variant): half the step's samples are the others' anchors'
  // observational samples
  const double difference_weight = t.difference_loss.weight;
  const bool pairs = difference_weight > 0;
  if (pairs)
    for (std::int64_t r = 0; r < data.rows; ++r)
      if (data.observational_row[static_cast<std::size_t>(r)] < 0)
        throw std::invalid_argument(
            "config.ae1.difference_loss pairs each sample with its anchor's observational "
            "sample; " +
            data.dir.string() + " has none for anchor " +
            std::to_string(data.anchor[static_cast<std::size_t>(r)]) + " (row " +
            std::to_string(r) + ")");

  nn::BatchLoaderOptions lo;
  lo.columns = {"images"};
  lo.batch_size = t.batch_size / config.cameras / (pairs ? 2 : 1);
  lo.seed = derive_seed(options.seed, "ae1.data");
  lo.drop_last = lo.batch_size <= data.rows;
  nn::BatchLoader loader(data.reader, lo);

  const fs::path weights = ae1_file(run_dir), checkpoint = checkpoint_of(weights);
  if (fs::exists(checkpoint)) {
    const nn::LoadedCheckpoint c = resume_from(checkpoint, trained, adam);
    schedule = c.schedule;
    loader.seek({c.progress.epoch, c.progress.position});
  }
  const std::int64_t first = adam.steps();
  metrics.truncate([&](const nlohmann::json& r) {
    return r.value("stage", "") != "ae1" || r.value("step", 0) <= first;
  });
  Progress progress("ae1", t.steps, first, options.progress_bar, config.log_every);
  Clock::time_point window = Clock::now();
  std::int64_t window_images = 0;
  const std::int64_t side = config.image_size;
  const std::uint64_t augmentation_seed = derive_seed(options.seed, "ae1.occlusion");
  // the squares of the difference loss's observational partners: a stream of their own
  const std::uint64_t partner_augmentation_seed =
      derive_seed(options.seed, "ae1.occlusion.partners");
  // the pairs of step s come from stream s of their own seed, so a resumed run draws the same
  const std::uint64_t pair_seed = derive_seed(options.seed, "ae1.pairs");
  const std::int64_t pairs_per_joint = pair_config.pairs_per_joint;
  const std::int64_t pair_count = pairs_per_joint * static_cast<std::int64_t>(data.joints.size());
  double pair_loss = 0, pair_accuracy = 0;  // the last step's, for the log
  while (adam.steps() < t.steps) {
    const nn::Batch batch = loader.next();
    const std::int64_t n = batch.size() * config.cameras;
    // every camera image is one AE1 sample: [rows, cams, S, S] -> [rows * cams, 1, S, S]
    const Tensor images = nn::reshape(batch.tensor("images"), Shape{n, 1, side, side});
    // with the occlusion augmentation (an extension), AE1 sees squares, and its target is the
    // clean image; the squares of step s come from stream s, so a resumed run draws the same
    std::vector<char> squared;  // which images got a square
    const Tensor inputs =
        t.occlusion_augmentation.probability > 0
            ? occlusion_augmented(images, t.occlusion_augmentation, augmentation_seed,
                                  static_cast<std::uint64_t>(adam.steps()), &squared)
            : images;
    std::vector<nn::RowRange> parts;
    nn::BatchLoss loss;
    Tensor observational, observational_inputs, masks;  // outlive the loss, which reads them
    if (pairs) {
      // each image with its anchor's observational image: micro-batches of pairs. A pair
      // occluded together counts in the reconstruction term only: the change a square may
      // hide is not asked of AE1
      std::vector<std::int64_t> partners;
      nn::Buffer mask(static_cast<std::size_t>(n));
      for (std::size_t k = 0; k < batch.rows.size(); ++k) {
        const std::int64_t row = batch.rows[k];
        partners.push_back(data.observational_row[static_cast<std::size_t>(row)]);
        for (std::int64_t c = 0; c < config.cameras; ++c) {
          const std::size_t i =
              k * static_cast<std::size_t>(config.cameras) + static_cast<std::size_t>(c);
          mask[i] = partners.back() == row || (!squared.empty() && squared[i] != 0) ? 0.0f : 1.0f;
        }
      }
      const core::NpyArray raw = data.reader.read_rows_at("images", partners);
      nn::Buffer pixels(raw.data.size());
      for (std::size_t i = 0; i < pixels.size(); ++i)
        pixels[i] = static_cast<float>(raw.data[i]) / 255.0f;
      observational = Tensor(Shape{n, 1, side, side}, std::move(pixels));
      observational_inputs =
          t.occlusion_augmentation.probability > 0
              ? occlusion_augmented_where(observational, squared, t.occlusion_augmentation,
                                          partner_augmentation_seed,
                                          static_cast<std::uint64_t>(adam.steps()))
              : observational;
      masks = Tensor(Shape{n}, std::move(mask));
      parts = nn::split_rows(n, std::max<std::int64_t>(1, t.micro_batch / 2));
      loss = nn::mean_loss([&](std::size_t i) {
        const std::int64_t b = parts[i].begin, e = parts[i].end;
        // with the occlusion augmentation AE1 sees squares in both or neither; targets clean
        const Tensor x = nn::slice(images, 0, b, e), xo = nn::slice(observational, 0, b, e);
        return ae1_difference_loss(net(nn::slice(inputs, 0, b, e)),
                                   net(nn::slice(observational_inputs, 0, b, e)), x, xo,
                                   nn::slice(masks, 0, b, e), difference_weight);
      });
    } else {
      parts = nn::split_rows(n, t.micro_batch);
      loss = nn::mean_loss([&](std::size_t i) {
        const Tensor x = nn::slice(inputs, 0, parts[i].begin, parts[i].end);
        const Tensor target = nn::slice(images, 0, parts[i].begin, parts[i].end);
        return nn::mean(nn::square(nn::sub(net(x), target)), {1, 2, 3});
      });
    }
    // the pair heads' term: one more micro-batch of the step's pairs, weighted so that the
    // batch mean is the reconstruction's mean plus weight x the pairs' mean
    Tensor pair_images;  // outlives the loss, which reads it
    if (with_heads) {
      // rows [first of every pair (joint-major) ..., second of every pair ...]
      core::PhiloxStream rng(pair_seed, static_cast<std::uint64_t>(adam.steps()));
      std::vector<std::int64_t> rows(static_cast<std::size_t>(2 * pair_count));
      for (std::size_t k = 0; k < pairs_of.size(); ++k)
        for (std::int64_t p = 0; p < pairs_per_joint; ++p) {
          const auto& list = pairs_of[k];
          const std::size_t pick = std::min(
              list.size() - 1,
              static_cast<std::size_t>(rng.uniform_double() * static_cast<double>(list.size())));
          const std::size_t at =
              k * static_cast<std::size_t>(pairs_per_joint) + static_cast<std::size_t>(p);
          rows[at] = list[pick].first;
          rows[at + static_cast<std::size_t>(pair_count)] = list[pick].second;
        }
      const core::NpyArray raw = data.reader.read_rows_at("images", rows);
      nn::Buffer pixels(raw.data.size());
      for (std::size_t i = 0; i < pixels.size(); ++i)
        pixels[i] = static_cast<float>(raw.data[i]) / 255.0f;
      pair_images =
          Tensor(Shape{2 * pair_count * config.cameras, 1, side, side}, std::move(pixels));
      const std::size_t recon_parts = parts.size();
      const float total = static_cast<float>(n + pair_count);
      const float recon_scale = total / static_cast<float>(n);
      const float pair_scale =
          static_cast<float>(pair_config.weight) * total / static_cast<float>(pair_count);
      const nn::BatchLoss recon = loss;
      loss = nn::mean_loss([&, recon, recon_parts, recon_scale, pair_scale](std::size_t i) {
        if (i < recon_parts)
          return nn::mul_scalar(recon.statistics(i, true).front(), recon_scale);
        // Y of every pair image: [2P * cams, K, 8, 8] = [2P, C, 8, 8]
        const std::int64_t code = config.ae1.code_size();
        const Tensor y = nn::reshape(net.encode(pair_images),
                                     Shape{2 * pair_count, config.code_channels(), code, code});
        std::vector<Tensor> per_pair;
        for (std::size_t k = 0; k < heads.size(); ++k) {
          const std::int64_t b = static_cast<std::int64_t>(k) * pairs_per_joint;
          const Tensor logits = (*heads[k])(
              nn::concat({nn::slice(y, 0, b, b + pairs_per_joint),
                          nn::slice(y, 0, pair_count + b, pair_count + b + pairs_per_joint)},
                         0));  // [2 * pairs_per_joint]: firsts, then seconds
          per_pair.push_back(nn::sub(nn::slice(logits, 0, pairs_per_joint, 2 * pairs_per_joint),
                                     nn::slice(logits, 0, 0, pairs_per_joint)));
        }
        const Tensor d = nn::concat(per_pair, 0);  // [P]: h_k(y2) - h_k(y1)
        const Tensor bce = nn::bce_with_logits_elementwise(
            d, Tensor(Shape{pair_count}, nn::Buffer(static_cast<std::size_t>(pair_count), 1.0f)));
        pair_loss = nn::mean(bce).item();
        double right = 0;
        for (std::int64_t p = 0; p < pair_count; ++p)
          right += d.data()[p] > 0 ? 1 : 0;
        pair_accuracy = right / static_cast<double>(pair_count);
        return nn::mul_scalar(bce, pair_scale);
      });
    }
    nn::StepOptions so;
    so.micro_batches = parts.size() + (with_heads ? 1 : 0);
    so.schedule = &schedule;
    so.clip_norm = t.optimizer.clip_norm;
    const nn::StepResult r = checked_step(adam, loss, so, "ae1", checkpoint);
    window_images += pairs ? 2 * n : n;
    const std::int64_t step = adam.steps();
    if (step % config.log_every == 0 || step == t.steps) {
      const double rate = static_cast<double>(window_images) / seconds_since(window);
      nlohmann::json record = {{"stage", "ae1"},           {"step", step},
                               {"loss", r.loss},           {"lr", r.lr},
                               {"grad_norm", r.grad_norm}, {"images_per_s", rate}};
      if (with_heads) {  // the last step's pair term (unweighted), and its pairs ordered right
        record["pair_loss"] = pair_loss;
        record["pair_accuracy"] = pair_accuracy;
      }
      metrics.append(record);
      window = Clock::now();
      window_images = 0;
    }
    progress.update(step, r.loss);
    if (step % config.checkpoint_every == 0 && step < t.steps) {
      const nn::DataCursor at = loader.cursor();
      nn::save_checkpoint(checkpoint, trained, adam, schedule,
                          {options.seed, at.epoch, at.position},
                          network_metadata("ae1", config.ae1.to_json(), config));
      note_checkpoint(options, "ae1", step);
    }
  }
  nn::save_module(net, weights, network_metadata("ae1", config.ae1.to_json(), config));
  fs::remove(checkpoint);
  progress.finish(std::to_string(t.steps) + " steps");
}

void encode_codes(const ExperimentConfig& config, const TrainingData& data,
                  const fs::path& run_dir) {
  Ae1 net(config.ae1);
  nn::load_module(net, ae1_file(run_dir));
  nn::GradModeGuard no_grad(false);
  const std::int64_t side = config.image_size, code = config.ae1.code_size();
  const std::int64_t c = config.code_channels();
  const std::int64_t per = c * code * code;
  core::NpyArray out{core::DType::kF32,
                     {data.rows, c, code, code},
                     std::vector<std::uint8_t>(static_cast<std::size_t>(data.rows * per) * 4)};
  const std::int64_t chunk = 128;
  std::vector<std::uint8_t> pixels;
  for (std::int64_t first = 0; first < data.rows; first += chunk) {
    const std::int64_t n = std::min(chunk, data.rows - first);
    const core::NpyArray raw = data.reader.read_rows("images", first, n);
    nn::Buffer x(static_cast<std::size_t>(n * config.cameras * side * side));
    for (std::size_t i = 0; i < x.size(); ++i)
      x[i] = static_cast<float>(raw.data[i]) / 255.0f;
    const Tensor images(Shape{n * config.cameras, 1, side, side}, std::move(x));
    const Tensor y = net.encode(images);  // [n * cams, K, 8, 8] = [n, cams * K, 8, 8]
    std::memcpy(out.data.data() + first * per * 4, y.data(), static_cast<std::size_t>(n * per) * 4);
  }
  core::write_npy(codes_file(run_dir), out);
}

}  // namespace ropes::crl::detail

namespace ropes::crl {

using nn::Shape;

namespace {

// the squares of occlusion_augmented(_where): per image, the coin (unless `given` decides),
// the side, the column and the row from the stream (seed, step)
Tensor paint_squares(const Tensor& images, const OcclusionAugmentation& a, std::uint64_t seed,
                     std::uint64_t step, const std::vector<char>* given,
                     std::vector<char>* squared) {
  const Shape& shape = images.shape();
  if (shape.rank() != 4 || shape[1] != 1 || shape[2] != shape[3] || a.min_size < 1 ||
      a.max_size < a.min_size || a.max_size > shape[2])
    throw std::invalid_argument("occlusion_augmented: images of shape " + shape.str() +
                                ", squares of " + std::to_string(a.min_size) + " to " +
                                std::to_string(a.max_size) +
                                " px; expected [n, 1, S, S] and 1 <= min_size <= max_size <= S");
  const std::int64_t n = shape[0], side = shape[2];
  if (given != nullptr && static_cast<std::int64_t>(given->size()) != n)
    throw std::invalid_argument("occlusion_augmented_where: " + std::to_string(given->size()) +
                                " entries for " + std::to_string(n) +
                                " images; expected one per image");
  core::PhiloxStream rng(seed, step);
  Tensor out = images.detach();
  float* px = out.mutable_data();
  auto uniform_int = [&rng](std::int64_t lo, std::int64_t hi) {  // on [lo, hi]
    const auto places = static_cast<double>(hi - lo + 1);
    return std::min<std::int64_t>(hi,
                                  lo + static_cast<std::int64_t>(rng.uniform_double() * places));
  };
  if (squared != nullptr)
    squared->assign(static_cast<std::size_t>(n), 0);
  for (std::int64_t i = 0; i < n; ++i) {
    const bool square = given != nullptr ? (*given)[static_cast<std::size_t>(i)] != 0
                                         : rng.uniform_double() < a.probability;
    if (!square)
      continue;
    if (squared != nullptr)
      (*squared)[static_cast<std::size_t>(i)] = 1;
    const std::int64_t size = uniform_int(a.min_size, a.max_size);
    const std::int64_t x = uniform_int(0, side - size), y = uniform_int(0, side - size);
    for (std::int64_t r = y; r < y + size; ++r)
      std::fill_n(px + (i * side + r) * side + x, size, 1.0f);
  }
  return out;
}

}  // namespace

Tensor occlusion_augmented(const Tensor& images, const OcclusionAugmentation& a, std::uint64_t seed,
                           std::uint64_t step, std::vector<char>* squared) {
  return paint_squares(images, a, seed, step, nullptr, squared);
}

Tensor occlusion_augmented_where(const Tensor& images, const std::vector<char>& squared,
                                 const OcclusionAugmentation& a, std::uint64_t seed,
                                 std::uint64_t step) {
  return paint_squares(images, a, seed, step, &squared, nullptr);
}

Tensor ae1_difference_loss(const Tensor& recon, const Tensor& recon_o, const Tensor& x,
                           const Tensor& xo, const Tensor& mask, double weight) {
  const Shape& shape = x.shape();
  if (shape.rank() != 4 || recon.shape() != shape || recon_o.shape() != shape ||
      xo.shape() != shape || mask.shape() != Shape{shape[0]})
    throw std::invalid_argument("ae1_difference_loss: reconstructions " + recon.shape().str() +
                                " and " + recon_o.shape().str() + ", images " + shape.str() +
                                " and " + xo.shape().str() + ", mask " + mask.shape().str() +
                                "; expected four equal [n, C, H, W] and a mask [n]");
  const std::vector<int> pixels = {1, 2, 3};
  const Tensor change = nn::sub(x, xo).detach();
  // the normalisation max(||x - xo||^2, 1) times the mask: constants
  Tensor scale = nn::sum(nn::square(change), pixels).detach();
  {
    float* p = scale.mutable_data();
    const float* m = mask.data();
    for (std::int64_t i = 0; i < shape[0]; ++i)
      p[i] = static_cast<float>(weight) * m[i] / std::max(p[i], 1.0f);
  }
  const Tensor reconstruction =
      nn::mul_scalar(nn::add(nn::mean(nn::square(nn::sub(recon, x)), pixels),
                             nn::mean(nn::square(nn::sub(recon_o, xo)), pixels)),
                     0.5f);
  const Tensor change_error = nn::sum(nn::square(nn::sub(nn::sub(recon, recon_o), change)), pixels);
  return nn::add(reconstruction, nn::mul(change_error, scale));
}

}  // namespace ropes::crl
