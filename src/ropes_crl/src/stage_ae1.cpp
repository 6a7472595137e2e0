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

void train_ae1(const ExperimentConfig& config, const TrainingData& data, const fs::path& run_dir,
               const TrainOptions& options, const MetricsLog& metrics) {
  const Ae1Training& t = config.ae1_training;
  Ae1 net(config.ae1);
  net.initialize(derive_seed(options.seed, "ae1.init"));
  nn::Adam adam(net.named_parameters(), nn::AdamOptions{t.optimizer.lr});
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
    const nn::LoadedCheckpoint c = resume_from(checkpoint, net, adam);
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
  while (adam.steps() < t.steps) {
    const nn::Batch batch = loader.next();
    const std::int64_t n = batch.size() * config.cameras;
    // every camera image is one AE1 sample: [rows, cams, S, S] -> [rows * cams, 1, S, S]
    const Tensor images = nn::reshape(batch.tensor("images"), Shape{n, 1, side, side});
    // with the occlusion augmentation (an extension), AE1 sees squares, and its target is the
    // clean image; the squares of step s come from stream s, so a resumed run draws the same
    const Tensor inputs =
        t.occlusion_augmentation.probability > 0
            ? occlusion_augmented(images, t.occlusion_augmentation, augmentation_seed,
                                  static_cast<std::uint64_t>(adam.steps()))
            : images;
    std::vector<nn::RowRange> parts;
    nn::BatchLoss loss;
    Tensor observational, observational_inputs, masks;  // outlive the loss, which reads them
    if (pairs) {
      // each image with its anchor's observational image: micro-batches of pairs
      std::vector<std::int64_t> partners;
      nn::Buffer mask(static_cast<std::size_t>(n));
      for (std::size_t k = 0; k < batch.rows.size(); ++k) {
        const std::int64_t row = batch.rows[k];
        partners.push_back(data.observational_row[static_cast<std::size_t>(row)]);
        for (std::int64_t c = 0; c < config.cameras; ++c)
          mask[k * static_cast<std::size_t>(config.cameras) + static_cast<std::size_t>(c)] =
              partners.back() == row ? 0.0f : 1.0f;
      }
      const core::NpyArray raw = data.reader.read_rows_at("images", partners);
      nn::Buffer pixels(raw.data.size());
      for (std::size_t i = 0; i < pixels.size(); ++i)
        pixels[i] = static_cast<float>(raw.data[i]) / 255.0f;
      observational = Tensor(Shape{n, 1, side, side}, std::move(pixels));
      observational_inputs = t.occlusion_augmentation.probability > 0
                                 ? occlusion_augmented(observational, t.occlusion_augmentation,
                                                       partner_augmentation_seed,
                                                       static_cast<std::uint64_t>(adam.steps()))
                                 : observational;
      masks = Tensor(Shape{n}, std::move(mask));
      parts = nn::split_rows(n, std::max<std::int64_t>(1, t.micro_batch / 2));
      loss = nn::mean_loss([&](std::size_t i) {
        const std::int64_t b = parts[i].begin, e = parts[i].end;
        // with the occlusion augmentation AE1 sees squares in both; the targets are clean
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
    nn::StepOptions so;
    so.micro_batches = parts.size();
    so.schedule = &schedule;
    so.clip_norm = t.optimizer.clip_norm;
    const nn::StepResult r = checked_step(adam, loss, so, "ae1", checkpoint);
    window_images += pairs ? 2 * n : n;
    const std::int64_t step = adam.steps();
    if (step % config.log_every == 0 || step == t.steps) {
      const double rate = static_cast<double>(window_images) / seconds_since(window);
      metrics.append({{"stage", "ae1"},
                      {"step", step},
                      {"loss", r.loss},
                      {"lr", r.lr},
                      {"grad_norm", r.grad_norm},
                      {"images_per_s", rate}});
      window = Clock::now();
      window_images = 0;
    }
    progress.update(step, r.loss);
    if (step % config.checkpoint_every == 0 && step < t.steps) {
      const nn::DataCursor at = loader.cursor();
      nn::save_checkpoint(checkpoint, net, adam, schedule, {options.seed, at.epoch, at.position},
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

Tensor occlusion_augmented(const Tensor& images, const OcclusionAugmentation& a, std::uint64_t seed,
                           std::uint64_t step) {
  const Shape& shape = images.shape();
  if (shape.rank() != 4 || shape[1] != 1 || shape[2] != shape[3] || a.min_size < 1 ||
      a.max_size < a.min_size || a.max_size > shape[2])
    throw std::invalid_argument("occlusion_augmented: images of shape " + shape.str() +
                                ", squares of " + std::to_string(a.min_size) + " to " +
                                std::to_string(a.max_size) +
                                " px; expected [n, 1, S, S] and 1 <= min_size <= max_size <= S");
  const std::int64_t n = shape[0], side = shape[2];
  core::PhiloxStream rng(seed, step);
  Tensor out = images.detach();
  float* px = out.mutable_data();
  auto uniform_int = [&rng](std::int64_t lo, std::int64_t hi) {  // on [lo, hi]
    const auto places = static_cast<double>(hi - lo + 1);
    return std::min<std::int64_t>(hi,
                                  lo + static_cast<std::int64_t>(rng.uniform_double() * places));
  };
  for (std::int64_t i = 0; i < n; ++i) {
    if (!(rng.uniform_double() < a.probability))
      continue;
    const std::int64_t size = uniform_int(a.min_size, a.max_size);
    const std::int64_t x = uniform_int(0, side - size), y = uniform_int(0, side - size);
    for (std::int64_t r = y; r < y + size; ++r)
      std::fill_n(px + (i * side + r) * side + x, size, 1.0f);
  }
  return out;
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
