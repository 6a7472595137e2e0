// Example from the ropes_nn README: a whole training loop. A dataset in the container of
// dataset.hpp, a BatchLoader, a step over micro-batches of a loss that squares a batch mean,
// a cosine schedule, checkpoints, and a resume after a kill that ends in the same bytes.
//
//   ropes_nn_example_train_loop [DIR] [--steps N] [--checkpoint-every K] [--threads T]
//
// Writes DIR/data (disc images and their radii) unless it is there, trains a small CNN to
// read the radius, saves DIR/checkpoint.safetensors every K steps and DIR/weights.safetensors
// at the end. Started again after a kill, it resumes from the checkpoint. Without DIR it
// works in a temporary directory and removes it.
#include <ropes_core/dataset.hpp>
#include <ropes_core/philox.hpp>
#include <ropes_nn/batch_loader.hpp>
#include <ropes_nn/checkpoint.hpp>
#include <ropes_nn/layers.hpp>
#include <ropes_nn/parallel.hpp>
#include <ropes_nn/train_step.hpp>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

using namespace ropes::nn;
using namespace ropes::core;
namespace fs = std::filesystem;

// 480 discs: image u8 [n, 1, 16, 16], radius f32 [n], split i32 [n] (0 train, 1 held out)
void write_discs(const fs::path& dir) {
  const std::int64_t n = 480;
  NpyArray image{DType::kU8, {n, 1, 16, 16}, std::vector<std::uint8_t>(n * 256)};
  NpyArray radius{DType::kF32, {n}, std::vector<std::uint8_t>(n * 4)};
  NpyArray split{DType::kI32, {n}, std::vector<std::uint8_t>(n * 4)};
  for (std::int64_t i = 0; i < n; ++i) {
    PhiloxStream rng(/*seed=*/7, /*stream=*/static_cast<std::uint64_t>(i));
    const float r = 2.0f + 5.0f * rng.uniform_float();
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x)
        image.data[i * 256 + y * 16 + x] = std::hypot(x - 7.5f, y - 7.5f) < r ? 255 : 0;
    const std::int32_t s = i % 6 == 0 ? 1 : 0;
    std::memcpy(&radius.data[i * 4], &r, 4);
    std::memcpy(&split.data[i * 4], &s, 4);
  }
  const std::vector<ColumnSpec> columns = {
      {"image", DType::kU8, {1, 16, 16}}, {"radius", DType::kF32, {}}, {"split", DType::kI32, {}}};
  write_dataset_shard(dir, 0, columns, {image, radius, split});
  write_dataset_manifest(dir, columns, 1, R"({"what": "discs"})");
}

// image [n, 1, 16, 16] -> radius [n]
class RadiusNet : public Module {
 public:
  RadiusNet() {
    features_ = register_module("features", std::make_shared<Sequential>());
    features_->add(std::make_shared<Conv2d>(1, 8, 3, 2));  // 16 -> 8
    features_->add(std::make_shared<ReLU>());
    features_->add(std::make_shared<Conv2d>(8, 8, 3, 2));  // 8 -> 4
    features_->add(std::make_shared<ReLU>());
    head_ = register_module("head", std::make_shared<Dense>(8 * 4 * 4, 1));
  }

 protected:
  Tensor forward(const Tensor& x) override {
    const Tensor y = (*head_)(flatten((*features_)(x)));
    return reshape(y, Shape{y.shape()[0]});
  }

 private:
  std::shared_ptr<Sequential> features_;
  std::shared_ptr<Dense> head_;
};

int main(int argc, char** argv) {
  fs::path dir;
  std::int64_t steps = 300, every = 50;
  int threads = 2;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--steps" && i + 1 < argc) {
      steps = std::atoll(argv[++i]);
    } else if (a == "--checkpoint-every" && i + 1 < argc) {
      every = std::atoll(argv[++i]);
    } else if (a == "--threads" && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else if (dir.empty() && a[0] != '-') {
      dir = a;
    } else {
      std::fprintf(stderr, "usage: %s [DIR] [--steps N] [--checkpoint-every K] [--threads T]\n",
                   argv[0]);
      return 2;
    }
  }
  const bool scratch = dir.empty();
  if (scratch)
    dir = fs::temp_directory_path() / ("ropes_nn_train_loop_" + std::to_string(::getpid()));
  try {
    set_num_threads(threads);
    if (!fs::exists(dir / "data" / "manifest.json"))
      write_discs(dir / "data");

    // the loader: training rows only (split 0), 32 a batch, a new order every epoch
    const DatasetReader reader = DatasetReader::open(dir / "data");
    BatchLoaderOptions options;
    options.columns = {"image", "radius"};
    options.batch_size = 32;
    options.seed = 11;
    options.filter_column = "split";
    options.filter_values = {0};
    BatchLoader loader(reader, options);

    RadiusNet net;
    net.initialize(/*seed=*/1);
    Adam adam(net.named_parameters(), AdamOptions{3e-3});
    LrSchedule schedule = LrSchedule::cosine(3e-3, steps, /*final_lr=*/1e-4, /*warmup=*/10);

    // resume: weights, optimiser, schedule and data cursor, all from one file
    const fs::path checkpoint = dir / "checkpoint.safetensors";
    if (fs::exists(checkpoint)) {
      const LoadedCheckpoint c = load_checkpoint(checkpoint, net, adam);
      schedule = c.schedule;
      loader.seek({c.progress.epoch, c.progress.position});
      std::printf("resumed at step %lld (epoch %lld, position %lld)\n",
                  static_cast<long long>(c.step), static_cast<long long>(c.progress.epoch),
                  static_cast<long long>(c.progress.position));
    }

    while (adam.steps() < steps) {
      const Batch batch = loader.next();
      const std::vector<RowRange> parts = batch.micro_batches(8);
      // loss = mean (p - r)^2 + (mean p - mean r)^2: the second term squares batch means, so
      // each micro-batch returns per-sample statistics and the step combines them exactly
      BatchLoss loss;
      loss.statistics = [&](std::size_t i, bool) {
        const RowRange& part = parts[i];
        const Tensor image = slice(batch.tensor("image"), 0, part.begin, part.end);
        const Tensor radius = slice(batch.tensor("radius"), 0, part.begin, part.end);
        const Tensor predicted = net(image);
        return std::vector<Tensor>{square(sub(predicted, radius)), predicted, radius};
      };
      loss.outer = [](const std::vector<Tensor>& m) { return add(m[0], square(sub(m[1], m[2]))); };
      StepOptions step;
      step.micro_batches = parts.size();
      step.schedule = &schedule;
      const StepResult result = train_step(adam, loss, step);
      if (adam.steps() % 100 == 0) {
        std::printf("step %4lld  loss %.4f  lr %.2e\n", static_cast<long long>(adam.steps()),
                    result.loss, result.lr);
      }
      if (adam.steps() % every == 0 || adam.steps() == steps) {
        const DataCursor at = loader.cursor();
        save_checkpoint(checkpoint, net, adam, schedule, {/*seed=*/1, at.epoch, at.position},
                        {{"architecture", "RadiusNet"}});
        std::printf("checkpoint %lld\n", static_cast<long long>(adam.steps()));
        std::fflush(stdout);
      }
    }
    save_module(net, dir / "weights.safetensors", {{"architecture", "RadiusNet"}});

    // the held-out rows (split 1): the net must beat predicting the mean radius
    options.filter_values = {1};
    options.batch_size = 1000;
    options.shuffle = false;
    BatchLoader held_out(reader, options);
    const Batch all = held_out.next();
    GradModeGuard no_grad(false);
    const Tensor radius = all.tensor("radius");
    const float mse = mse_loss(net(all.tensor("image")), radius).item();
    const float variance = mean(square(sub(radius, mean(radius)))).item();
    std::printf("held-out mse %.4f (predicting the mean: %.4f)\n", mse, variance);
    if (scratch)
      fs::remove_all(dir);
    return mse < 0.2f * variance ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_loop: %s\n", e.what());
    return 1;
  }
}
