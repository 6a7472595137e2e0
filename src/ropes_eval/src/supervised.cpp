#include "ropes_eval/supervised.hpp"

#include <ropes_core/dataset.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_core/npy.hpp>
#include <ropes_crl/experiment_config.hpp>
#include <ropes_crl/networks.hpp>
#include <ropes_crl/run_directory.hpp>
#include <ropes_nn/adam.hpp>
#include <ropes_nn/ops.hpp>
#include <ropes_nn/train_step.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "json_file.hpp"

namespace ropes::eval {

namespace fs = std::filesystem;
using nn::Shape;
using nn::Tensor;

struct SupervisedEncoder::State {
  crl::ExperimentConfig config;
  std::unique_ptr<crl::Ae2> net;
  std::vector<double> mean, sd;  // of each joint over the labelled samples
  double fraction = 0, final_loss = 0;
  std::int64_t labels = 0, steps = 0;
};

SupervisedEncoder::SupervisedEncoder(std::unique_ptr<State> state) : state_(std::move(state)) {}
SupervisedEncoder::SupervisedEncoder(SupervisedEncoder&&) noexcept = default;
SupervisedEncoder& SupervisedEncoder::operator=(SupervisedEncoder&&) noexcept = default;
SupervisedEncoder::~SupervisedEncoder() = default;

namespace {

// the paper's RoboPEPP epochs at 1, 5, 10, 100 % of the labels
std::int64_t paper_epochs(double fraction) {
  const double known[][2] = {{0.01, 100}, {0.05, 75}, {0.10, 25}, {1.0, 15}};
  for (const auto& k : known)
    if (std::fabs(fraction - k[0]) < 1e-9)
      return static_cast<std::int64_t>(k[1]);
  return std::min<std::int64_t>(100,
                                static_cast<std::int64_t>(std::ceil(15 / std::sqrt(fraction))));
}

}  // namespace

SupervisedEncoder SupervisedEncoder::train(const fs::path& run_dir, double fraction,
                                           const SupervisedOptions& options) {
  if (!(fraction > 0 && fraction <= 1))
    throw std::invalid_argument("SupervisedEncoder::train: fraction " + std::to_string(fraction) +
                                "; expected 0 < fraction <= 1");
  auto s = std::make_unique<State>();
  const crl::RunDirectory run = crl::RunDirectory::open(run_dir);
  s->config = run.config();
  const crl::ExperimentConfig& c = s->config;
  // the training set's codes (the run's frozen AE1) and angles, row for row
  const core::NpyArray codes = core::read_npy(run.codes_file());
  const core::DatasetReader reader = core::DatasetReader::open(run.data_dir());
  if (codes.dtype != core::DType::kF32 || codes.shape.size() != 4 ||
      codes.shape[0] != reader.rows())
    throw core::FileFormatError((run_dir / "codes.npy").string() + ": expected f32 [" +
                                std::to_string(reader.rows()) +
                                ", C, 8, 8], the codes of every row of the training set");
  const std::int64_t rows = codes.shape[0], per = codes.shape[1] * codes.shape[2] * codes.shape[3];
  if (rows < 2)
    throw core::FileFormatError((run_dir / "codes.npy").string() + ": " + std::to_string(rows) +
                                " rows; the supervised baseline needs at least 2");
  const nlohmann::json& names = reader.metadata_at("/joint_names");
  const std::int64_t width = reader.column("angles").row_shape[0];
  std::vector<std::int64_t> column;
  for (const std::string& j : c.joints) {
    std::int64_t at = -1;
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == j)
        at = static_cast<std::int64_t>(i);
    if (at < 0)
      throw core::FileFormatError(run.data_dir().string() + ": no joint '" + j + "'");
    column.push_back(at);
  }
  const std::int64_t jn = static_cast<std::int64_t>(c.joints.size());
  // the labelled rows: a seeded prefix of one permutation, so 1 % is inside 5 %
  const std::vector<std::int64_t> order = core::shuffled_indices(rows, options.seed, 0);
  const std::int64_t n = std::max<std::int64_t>(
      2, static_cast<std::int64_t>(std::llround(fraction * static_cast<double>(rows))));
  std::vector<std::int64_t> labelled(order.begin(), order.begin() + std::min(n, rows));
  std::sort(labelled.begin(), labelled.end());
  const core::NpyArray angle_rows = reader.read_rows_at("angles", labelled);
  std::vector<float> x(static_cast<std::size_t>(n * per)), t(static_cast<std::size_t>(n * jn));
  for (std::int64_t i = 0; i < n; ++i)
    std::memcpy(&x[static_cast<std::size_t>(i * per)],
                codes.data.data() + labelled[static_cast<std::size_t>(i)] * per * 4,
                static_cast<std::size_t>(per) * 4);
  s->mean.assign(static_cast<std::size_t>(jn), 0.0);
  s->sd.assign(static_cast<std::size_t>(jn), 0.0);
  for (std::int64_t k = 0; k < jn; ++k) {
    std::vector<double> a(static_cast<std::size_t>(n));
    for (std::int64_t i = 0; i < n; ++i) {
      float v;
      std::memcpy(
          &v, angle_rows.data.data() + (i * width + column[static_cast<std::size_t>(k)]) * 4, 4);
      a[static_cast<std::size_t>(i)] = v;
    }
    double mu = 0, ss = 0;
    for (double v : a)
      mu += v / static_cast<double>(n);
    for (double v : a)
      ss += (v - mu) * (v - mu) / static_cast<double>(n);
    s->mean[static_cast<std::size_t>(k)] = mu;
    s->sd[static_cast<std::size_t>(k)] = ss > 0 ? std::sqrt(ss) : 1.0;
    for (std::int64_t i = 0; i < n; ++i)
      t[static_cast<std::size_t>(i * jn + k)] = static_cast<float>(
          (a[static_cast<std::size_t>(i)] - mu) / s->sd[static_cast<std::size_t>(k)]);
  }
  if (c.ae2.latent_dim < jn)
    throw std::invalid_argument("SupervisedEncoder::train: AE2's " +
                                std::to_string(c.ae2.latent_dim) + " latents cannot regress " +
                                std::to_string(jn) + " joints");
  s->net = std::make_unique<crl::Ae2>(c.ae2);
  s->net->initialize(options.seed ^ 0x5eedULL);
  if (c.ae2.input_normalization == "standardize") {
    // the map is label-free: fitted on the codes of the whole training set, as the trainer does
    crl::CodeStandardization map(codes.shape[1], codes.shape[2]);
    nn::Buffer all(static_cast<std::size_t>(rows * per));
    std::memcpy(all.data(), codes.data.data(), all.size() * 4);
    map.fit(Tensor(Shape{rows, codes.shape[1], codes.shape[2], codes.shape[3]}, std::move(all)),
            "the supervised baseline's input map");
    s->net->set_input_map(map);
  }
  nn::Adam adam(s->net->trained_parameters(), nn::AdamOptions{options.lr});
  const std::int64_t epochs = options.epochs > 0 ? options.epochs : paper_epochs(fraction);
  const std::int64_t batch = std::min(options.batch_size, n);
  const std::int64_t per_epoch = (n + batch - 1) / batch;
  std::int64_t steps = epochs * per_epoch;
  if (options.max_steps > 0)
    steps = std::min(steps, options.max_steps);
  double epoch_loss = 0;
  std::int64_t in_epoch = 0;
  for (std::int64_t step = 0; step < steps; ++step) {
    const std::int64_t epoch = step / per_epoch, first = (step % per_epoch) * batch;
    const std::vector<std::int64_t> shuffled =
        core::shuffled_indices(n, options.seed, static_cast<std::uint64_t>(epoch) + 1);
    const std::int64_t m = std::min(batch, n - first);
    nn::Buffer xb(static_cast<std::size_t>(m * per));
    std::vector<float> tb(static_cast<std::size_t>(m * jn));
    for (std::int64_t i = 0; i < m; ++i) {
      const std::int64_t r = shuffled[static_cast<std::size_t>(first + i)];
      std::memcpy(&xb[static_cast<std::size_t>(i * per)], &x[static_cast<std::size_t>(r * per)],
                  static_cast<std::size_t>(per) * 4);
      std::memcpy(&tb[static_cast<std::size_t>(i * jn)], &t[static_cast<std::size_t>(r * jn)],
                  static_cast<std::size_t>(jn) * 4);
    }
    const Tensor input(Shape{m, codes.shape[1], codes.shape[2], codes.shape[3]}, std::move(xb));
    const Tensor target(Shape{m, jn}, tb);
    const double loss = nn::train_step(adam, nn::mean_loss([&](std::size_t) {
                                         const Tensor z =
                                             nn::slice(s->net->encode(input), 1, 0, jn);
                                         return nn::mean(nn::square(nn::sub(z, target)), {1});
                                       }))
                            .loss;
    if (first == 0) {
      epoch_loss = 0;
      in_epoch = 0;
    }
    epoch_loss += loss;
    ++in_epoch;
  }
  s->final_loss = in_epoch > 0 ? epoch_loss / static_cast<double>(in_epoch) : 0.0;
  s->fraction = fraction;
  s->labels = n;
  s->steps = steps;
  return SupervisedEncoder(std::move(s));
}

Eigen::MatrixXd SupervisedEncoder::predict(const Eigen::MatrixXd& codes) const {
  const crl::ExperimentConfig& c = state_->config;
  const std::int64_t ch = c.code_channels(), side = c.ae1.code_size(), per = ch * side * side;
  const std::int64_t jn = static_cast<std::int64_t>(c.joints.size());
  if (codes.cols() != per)
    throw std::invalid_argument("SupervisedEncoder::predict: codes of " +
                                std::to_string(codes.cols()) + " values a row; expected " +
                                std::to_string(per));
  nn::GradModeGuard no_grad(false);
  Eigen::MatrixXd out(codes.rows(), jn);
  for (Eigen::Index b = 0; b < codes.rows(); b += 256) {
    const Eigen::Index m = std::min<Eigen::Index>(256, codes.rows() - b);
    nn::Buffer x(static_cast<std::size_t>(m * per));
    for (Eigen::Index i = 0; i < m; ++i)
      for (std::int64_t j = 0; j < per; ++j)
        x[static_cast<std::size_t>(i * per + j)] = static_cast<float>(codes(b + i, j));
    const Tensor z = state_->net->encode(Tensor(Shape{m, ch, side, side}, std::move(x)));
    const std::int64_t d = z.shape()[1];
    for (Eigen::Index i = 0; i < m; ++i)
      for (std::int64_t k = 0; k < jn; ++k)
        out(b + i, k) = z.data()[i * d + k] * state_->sd[static_cast<std::size_t>(k)] +
                        state_->mean[static_cast<std::size_t>(k)];
  }
  return out;
}

const std::vector<std::string>& SupervisedEncoder::joints() const {
  return state_->config.joints;
}

std::string supervised_method_name(double fraction) {
  char name[48];
  std::snprintf(name, sizeof name, "supervised_%g%%", 100.0 * fraction);
  return name;
}

double SupervisedEncoder::fraction() const {
  return state_->fraction;
}
std::int64_t SupervisedEncoder::labels() const {
  return state_->labels;
}
std::int64_t SupervisedEncoder::steps() const {
  return state_->steps;
}
double SupervisedEncoder::final_loss() const {
  return state_->final_loss;
}

}  // namespace ropes::eval
