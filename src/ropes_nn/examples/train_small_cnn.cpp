// Example from the ropes_nn README: define a small CNN, train it a few steps on generated
// data (estimate the radius of a disc from its 16x16 image), save it and load it back.
#include <ropes_core/philox.hpp>
#include <ropes_nn/checkpoint.hpp>
#include <ropes_nn/layers.hpp>
#include <ropes_nn/ops.hpp>
#include <ropes_nn/train_step.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

using namespace ropes::nn;
using namespace ropes::core;

// a batch of discs with random radii in [2, 7]: images [n, 1, 16, 16], radii [n, 1]
void make_batch(std::uint64_t batch_index, int n, Tensor* images, Tensor* radii) {
  std::vector<float> pixels(static_cast<std::size_t>(n) * 256), r(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    PhiloxStream rng(/*seed=*/7, /*stream=*/batch_index * 1000 + static_cast<std::uint64_t>(i));
    r[i] = 2.0f + 5.0f * rng.uniform_float();
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) {
        const float d = std::hypot(x - 7.5f, y - 7.5f);
        pixels[static_cast<std::size_t>(i * 256 + y * 16 + x)] = d < r[i] ? 1.0f : 0.0f;
      }
  }
  *images = Tensor(Shape{n, 1, 16, 16}, pixels);
  *radii = Tensor(Shape{n, 1}, r);
}

std::shared_ptr<Sequential> make_net() {
  auto net = std::make_shared<Sequential>();
  net->add(std::make_shared<Conv2d>(1, 8, 3, 2), "conv1");  // 16 -> 8
  net->add(std::make_shared<ReLU>());
  net->add(std::make_shared<Conv2d>(8, 8, 3, 2), "conv2");  // 8 -> 4
  net->add(std::make_shared<ReLU>());
  return net;
}

int main() {
  auto features = make_net();
  Dense head(8 * 4 * 4, 1);
  features->initialize(/*seed=*/1);
  head.initialize(/*seed=*/1);
  std::vector<Tensor> params = features->parameters();
  for (const Tensor& p : head.parameters())
    params.push_back(p);
  Adam adam(params, AdamOptions{/*lr=*/3e-3});

  auto predict = [&](const Tensor& images) { return head(flatten((*features)(images))); };
  Tensor images, radii;
  float first = 0.0f, last = 0.0f;
  for (std::uint64_t step = 0; step < 150; ++step) {
    make_batch(step, 32, &images, &radii);
    // two micro-batches of 16; the loss is the mean over all 32 per-sample squared errors
    const BatchLoss loss = mean_loss([&](std::size_t half) {
      const std::int64_t begin = static_cast<std::int64_t>(half) * 16;
      const Tensor error =
          sub(predict(slice(images, 0, begin, begin + 16)), slice(radii, 0, begin, begin + 16));
      return reshape(square(error), Shape{16});
    });
    StepOptions options;
    options.micro_batches = 2;
    const double loss_value = train_step(adam, loss, options).loss;
    if (step == 0)
      first = static_cast<float>(loss_value);
    last = static_cast<float>(loss_value);
    if (step % 50 == 0 || step == 149)
      std::printf("step %3llu  mse %.4f\n", (unsigned long long)step, loss_value);
  }

  // save, load into a fresh network, and check it predicts the same
  const auto path = std::filesystem::temp_directory_path() / "ropes_nn_example_head.safetensors";
  save_module(head, path, {{"task", "disc radius"}});
  Dense reloaded(8 * 4 * 4, 1);
  const auto metadata = load_module(reloaded, path).metadata;
  std::filesystem::remove(path);
  const Tensor f = flatten((*features)(images));
  const bool same = head(f).to_vector() == reloaded(f).to_vector();
  std::printf("reloaded '%s' head predicts the same: %s\n", metadata.at("task").c_str(),
              same ? "yes" : "no");
  return same && last < 0.5f * first ? 0 : 1;
}
