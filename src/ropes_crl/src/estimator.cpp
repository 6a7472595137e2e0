#include "ropes_crl/estimator.hpp"

#include <ropes_core/file_format_error.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_nn/checkpoint.hpp>
#include <ropes_nn/ops.hpp>

#include <algorithm>
#include <stdexcept>

#include "json_fields.hpp"
#include "ropes_crl/run_directory.hpp"
#include "run_files.hpp"

namespace ropes::crl {

namespace fs = std::filesystem;
using nn::Shape;

struct Estimator::State {
  ExperimentConfig config;
  std::unique_ptr<Ae1> ae1;
  std::vector<std::unique_ptr<Ae2>> ae2;  // per_joint: one a joint; joint: one
  std::unique_ptr<Ae2> lambda0;
  std::vector<std::unique_ptr<Ldr>> ldr;
  bool calibrated = false;
  Calibration calibration;
};

Estimator::Estimator(std::unique_ptr<State> state) : state_(std::move(state)) {}
Estimator::Estimator(Estimator&&) noexcept = default;
Estimator& Estimator::operator=(Estimator&&) noexcept = default;
Estimator::~Estimator() = default;

namespace {
// loads `path` into `net`, strictly, with the file named in every error
template <class Net>
void load_weights(Net& net, const fs::path& path) {
  if (!fs::exists(path))
    throw core::FileFormatError(path.string() + ": missing; the run is incomplete");
  nn::load_module(net, path);
}
}  // namespace

Estimator Estimator::load(const fs::path& run_dir) {
  return load(RunDirectory::open(run_dir));
}

Estimator Estimator::load(const RunDirectory& run) {
  const fs::path& run_dir = run.dir();
  if (!run.complete())
    throw core::FileFormatError(run.run_file().string() +
                                ": the run has not finished training; run ropes-train again "
                                "with the same arguments to resume it");
  auto s = std::make_unique<State>();
  s->config = run.config();
  const ExperimentConfig& c = s->config;
  s->ae1 = std::make_unique<Ae1>(c.ae1);
  load_weights(*s->ae1, detail::ae1_file(run_dir));
  if (c.ae2_training.mode == "per_joint") {
    for (const std::string& joint : c.joints) {
      s->ae2.push_back(std::make_unique<Ae2>(c.ae2));
      load_weights(*s->ae2.back(), detail::ae2_file(run_dir, joint));
    }
  } else {
    s->ae2.push_back(std::make_unique<Ae2>(c.ae2));
    load_weights(*s->ae2.back(), detail::ae2_file(run_dir, "joint"));
  }
  if (c.ae2_training.lambda0_baseline) {
    s->lambda0 = std::make_unique<Ae2>(c.ae2);
    load_weights(*s->lambda0, detail::ae2_file(run_dir, "lambda0"));
  }
  for (const std::string& joint : c.joints) {
    s->ldr.push_back(std::make_unique<Ldr>(c.ldr));
    load_weights(*s->ldr.back(), detail::ldr_file(run_dir, joint));
  }
  return Estimator(std::move(s));
}

const ExperimentConfig& Estimator::config() const {
  return state_->config;
}

Tensor Estimator::codes(const Tensor& images) {
  const ExperimentConfig& c = state_->config;
  if (images.rank() != 4 || images.shape()[1] != c.cameras || images.shape()[2] != c.image_size ||
      images.shape()[3] != c.image_size)
    throw std::invalid_argument("Estimator::codes: images are " + images.shape().str() +
                                ", expected [n, " + std::to_string(c.cameras) + ", " +
                                std::to_string(c.image_size) + ", " + std::to_string(c.image_size) +
                                "]");
  nn::GradModeGuard no_grad(false);
  const std::int64_t n = images.shape()[0];
  const Tensor y =
      state_->ae1->encode(nn::reshape(images, Shape{n * c.cameras, 1, c.image_size, c.image_size}));
  const std::int64_t side = y.shape()[2];
  return nn::reshape(y, Shape{n, c.code_channels(), side, side});
}

namespace {
// column k of [n, d]
Tensor column(const Tensor& z, std::int64_t k) {
  return nn::slice(z, 1, k, k + 1);
}
}  // namespace

Tensor Estimator::latents_from_codes(const Tensor& y) {
  nn::GradModeGuard no_grad(false);
  const std::int64_t j = static_cast<std::int64_t>(joints().size());
  // joint mode: one AE2, its first J latents; per_joint: latent k of joint k's AE2
  if (state_->ae2.size() == 1)
    return nn::slice(state_->ae2[0]->encode(y), 1, 0, j);
  std::vector<Tensor> cols;
  for (std::int64_t k = 0; k < j; ++k)
    cols.push_back(column(state_->ae2[static_cast<std::size_t>(k)]->encode(y), k));
  return nn::concat(cols, 1);
}

Tensor Estimator::full_latents_from_codes(const Tensor& y, std::size_t joint) {
  if (joint >= joints().size())
    throw std::invalid_argument("Estimator::full_latents_from_codes: joint " +
                                std::to_string(joint) + " of " + std::to_string(joints().size()));
  nn::GradModeGuard no_grad(false);
  Ae2& net = *state_->ae2[state_->ae2.size() == 1 ? 0 : joint];
  return net.encode(y);
}

Tensor Estimator::latents(const Tensor& images) {
  return latents_from_codes(codes(images));
}

Tensor Estimator::ldr_logits_from_codes(const Tensor& y) {
  nn::GradModeGuard no_grad(false);
  std::vector<Tensor> cols;
  for (const auto& ldr : state_->ldr)
    cols.push_back(nn::reshape((*ldr)(y), Shape{y.shape()[0], 1}));
  return nn::concat(cols, 1);
}

Tensor Estimator::reconstruct(const Tensor& images) {
  const ExperimentConfig& c = state_->config;
  const Tensor y = codes(images);  // checks the shape
  nn::GradModeGuard no_grad(false);
  const std::int64_t n = images.shape()[0], side = y.shape()[2];
  const Tensor x = state_->ae1->decode(
      nn::reshape(y, Shape{n * c.cameras, y.shape()[1] / c.cameras, side, side}));
  return nn::reshape(x, images.shape());
}

Tensor Estimator::reconstruct_through_ae2(const Tensor& images, std::size_t joint) {
  if (joint >= joints().size())
    throw std::invalid_argument("Estimator::reconstruct_through_ae2: joint " +
                                std::to_string(joint) + " of " + std::to_string(joints().size()));
  const ExperimentConfig& c = state_->config;
  const Tensor y = codes(images);
  nn::GradModeGuard no_grad(false);
  Ae2& net = *state_->ae2[state_->ae2.size() == 1 ? 0 : joint];
  Tensor back = net.decode(net.encode(y));
  // AE2's coordinates -> Y's: s = (y - shift) * scale, so y = s / scale + shift (scale 0:
  // the element was dropped; its shift is what the map assumed)
  if (const CodeStandardization* map = net.input_map()) {
    std::vector<float> v(back.data(), back.data() + back.numel());
    const std::int64_t per = map->shift().numel();
    for (std::int64_t i = 0; i < back.numel(); ++i) {
      const float scale = map->scale().data()[i % per], shift = map->shift().data()[i % per];
      v[static_cast<std::size_t>(i)] =
          scale != 0.0f ? v[static_cast<std::size_t>(i)] / scale + shift : shift;
    }
    back = Tensor(back.shape(), v);
  }
  const std::int64_t n = images.shape()[0], side = y.shape()[2];
  const Tensor x = state_->ae1->decode(
      nn::reshape(back, Shape{n * c.cameras, y.shape()[1] / c.cameras, side, side}));
  return nn::reshape(x, images.shape());
}

bool Estimator::has_lambda0() const {
  return state_->lambda0 != nullptr;
}

Tensor Estimator::lambda0_latents_from_codes(const Tensor& y) {
  if (!state_->lambda0)
    throw std::logic_error("Estimator: this run trained no lambda = 0 baseline");
  nn::GradModeGuard no_grad(false);
  const Tensor z = state_->lambda0->encode(y);
  return nn::slice(z, 1, 0, static_cast<std::int64_t>(joints().size()));
}

void Estimator::set_calibration(const Calibration& calibration) {
  if (calibration.joints != joints())
    throw std::invalid_argument(
        "Estimator::set_calibration: the calibration is for other "
        "joints than this run's");
  state_->calibration = calibration;
  state_->calibrated = true;
}

bool Estimator::calibrated() const {
  return state_->calibrated;
}

Tensor Estimator::angles_from_latents(const Tensor& latents) const {
  if (!state_->calibrated)
    throw std::logic_error("Estimator::angles_from_latents: no calibration was set");
  const std::int64_t n = latents.shape()[0], j = static_cast<std::int64_t>(joints().size());
  std::vector<float> out(static_cast<std::size_t>(n * j));
  for (std::int64_t i = 0; i < n; ++i)
    for (std::int64_t k = 0; k < j; ++k)
      out[static_cast<std::size_t>(i * j + k)] = static_cast<float>(
          state_->calibration.scale[static_cast<std::size_t>(k)] * latents.data()[i * j + k] +
          state_->calibration.offset[static_cast<std::size_t>(k)]);
  return Tensor(Shape{n, j}, out);
}

// The per-frame path of streaming: the same networks as latents(), written so that a warm
// call allocates nothing from the system (the tensors' storage comes from ropes_nn's pool,
// no vector of columns is built, the latents are read in place).
void Estimator::estimate_frame(const std::uint8_t* pixels, float* latents_out, float* angles_out) {
  const ExperimentConfig& c = state_->config;
  const std::int64_t count = c.cameras * c.image_size * c.image_size;
  nn::GradModeGuard no_grad(false);
  nn::Buffer x(static_cast<std::size_t>(count));
  for (std::int64_t i = 0; i < count; ++i)
    x[static_cast<std::size_t>(i)] = static_cast<float>(pixels[i]) / 255.0f;
  const Tensor y =
      state_->ae1->encode(Tensor(Shape{c.cameras, 1, c.image_size, c.image_size}, std::move(x)));
  const std::int64_t side = y.shape()[2];
  const Tensor code = nn::reshape(y, Shape{1, c.code_channels(), side, side});
  const std::size_t joints = c.joints.size();
  if (state_->ae2.size() == 1) {
    const Tensor z = state_->ae2[0]->encode(code);
    std::copy_n(z.data(), joints, latents_out);
  } else {
    for (std::size_t k = 0; k < joints; ++k)
      latents_out[k] = state_->ae2[k]->encode(code).data()[k];
  }
  if (angles_out != nullptr && state_->calibrated) {
    const Calibration& cal = state_->calibration;
    for (std::size_t k = 0; k < joints; ++k)
      angles_out[k] = static_cast<float>(cal.scale[k] * latents_out[k] + cal.offset[k]);
  }
}

}  // namespace ropes::crl
