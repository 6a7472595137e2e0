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
#include "training_data.hpp"

namespace ropes::crl {

using namespace detail;
using nn::Shape;

const char* ropes_crl_version() {
  return ROPES_CRL_VERSION_STRING;
}

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

namespace {

using Clock = std::chrono::steady_clock;

// load_checkpoint; a refusal (a damaged or foreign file) says what to do about it
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
                                                    const nlohmann::json& extra = {}) {
  nlohmann::json net = {{"kind", kind}, {"spec", spec}};
  if (!extra.is_null())
    net["info"] = extra;
  return {{kNetworkKey, net.dump()}, {kConfigKey, config.to_json().dump()}};
}

// one update; a loss or gradient that is not finite names the stage and the step and keeps
// the last checkpoint (train_step changes nothing when it refuses)
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

// a log line (plain logs only) and the test hook, after each checkpoint
void note_checkpoint(const TrainOptions& options, const std::string& stage, std::int64_t step) {
  if (!options.progress_bar) {
    std::fprintf(stderr, "ropes-train: checkpoint %s step %lld\n", stage.c_str(),
                 static_cast<long long>(step));
    std::fflush(stderr);
  }
  if (options.on_checkpoint)
    options.on_checkpoint(stage, step);
}

// --- the run directory ----------------------------------------------------------------------
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
          (run.is_object() && run.contains("format") ? run["format"].dump() : "missing") +
          ", expected \"" + kRunFormat + "\")");
    for (const auto& [key, value] : identity.items())
      if (run[key] != value)
        throw std::invalid_argument(
            run_dir.string() + " holds a run with another " + key + " (" +
            (key == "config" && run[key].is_object() && run[key]["name"].is_string()
                 ? run[key]["name"].get<std::string>()
                 : run[key].dump()) +
            ", this one: " + (key == "config" ? config.name : value.dump()) +
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

// --- stage 1: AE1 ---------------------------------------------------------------------------
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

// Y = E1(x) of every row, cams' codes concatenated along channels: [rows, C, 8, 8]
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

// --- stage 2: the LDRs ----------------------------------------------------------------------
struct LdrOutcome {
  double loss = 0, accuracy = 0;
  std::int64_t epochs = 0;
};

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
  nn::Adam adam(net.trained_parameters(), nn::AdamOptions{t.optimizer.lr});
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
      const nn::BatchLoss loss = nn::mean_loss(
          [&](std::size_t) { return nn::bce_with_logits_elementwise(net(y), labels); });
      train_loss += checked_step(adam, loss, so, "ldr " + joint.name, weights).loss;
    }
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

// --- stage 3: AE2 ---------------------------------------------------------------------------
struct Ae2Model {
  std::string name;                ///< file stem: a joint's name, "joint" or "lambda0"
  std::vector<std::size_t> terms;  ///< indices into config.joints (= target latents)
  double lambda = 0;
};

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
    batch.reconstruction = data.codes_of(recon.rows(s));
    for (std::size_t i = 0; i < model.terms.size(); ++i) {
      const std::size_t k = model.terms[i];
      const std::vector<std::int64_t> picked = term_samplers[i].rows(s);
      batch.term_codes.push_back(data.codes_of(scores.dataset_rows(k, picked)));
      batch.term_scores.push_back(scores.scores_of(k, picked));
      batch.targets.push_back(static_cast<std::int64_t>(k));
    }
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

// How stage 3 uses the threads: an AE2 step is too small to share between threads (a
// 2-thread step takes as long as a 1-thread one, the second thread waiting), so up to
// `threads` AE2s train at once, each on threads / workers threads. A function of the thread
// count and the number of models of the config alone, never of what is left to train, so a
// resumed stage computes with the same thread count as an uninterrupted one.
struct Ae2Plan {
  int workers = 1, threads_each = 1;
};

Ae2Plan ae2_plan(int threads, std::size_t models) {
  Ae2Plan p;
  p.workers = static_cast<int>(
      std::max<std::size_t>(1, std::min(static_cast<std::size_t>(std::max(threads, 1)), models)));
  p.threads_each = std::max(1, threads / p.workers);
  return p;
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

// Trains the models of `todo` on plan.workers threads, each model on plan.threads_each
// kernel threads; `finished(model, seconds)` is called (under a lock) as each one finishes.
// The first failure stops the others at their next step, each with a checkpoint of the step
// it reached, and is rethrown once every worker has stopped.
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

// row k of model m's sparsity matrix: E|J_g^T v_k| over joint k's score rows
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

}  // namespace

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

  // stage 2: one LDR per joint
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
