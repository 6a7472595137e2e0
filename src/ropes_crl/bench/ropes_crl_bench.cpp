// ropes_crl_bench: the speed of each stage of ROPES, next to PyTorch's for the same networks,
// batches and steps, measured in the same run by bench/torch_peer.py (Debian's python3-torch
// at its best: tcmalloc preloaded, OPENBLAS_NUM_THREADS=1, OPENBLAS_CORETYPE unset, the same
// thread count). A benchmark run by hand, never a test.
//
//   ropes_crl_bench [--config NAME|PATH] [--anchors N] [--quick] [--no-peer] [--threads N]
//                   [--only TEXT]             only the cases whose name contains TEXT (for a
//                                             profiler; the projected stage times need all)
//   ropes_crl_bench --run RUN [--threads N]   the Estimator of a trained run: one frame's
//                                             latency and heap allocations per frame
//
// It prints three groups of lines:
//   - the appendix's networks at widths x1/8 and x1/4 (AE1 training step and batch-1 encode,
//     LDR step, the convolutional AE2's score-sparsity step), with AE1's GFLOP/s against a
//     GEMM peak measured here;
//   - each stage of a config (default `1c-small`): AE1 step, encoding, LDR step, score
//     differences, AE2 step with and without the sparsity term, and the latency of one frame
//     through AE1 and AE2's encoders; then each stage's wall time projected from those rates;
//   - one training step of the `paper` preset's AE1 (the appendix's full width) on one
//     micro-batch of the preset.
#include <sys/resource.h>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <ropes_core/philox.hpp>
#include <ropes_crl/estimator.hpp>
#include <ropes_crl/experiment_config.hpp>
#include <ropes_crl/networks.hpp>
#include <ropes_crl/sparsity_objective.hpp>
#include <ropes_nn/adam.hpp>
#include <ropes_nn/allocation_counter.hpp>
#include <ropes_nn/benchmark.hpp>
#include <ropes_nn/ops.hpp>
#include <ropes_nn/parallel.hpp>
#include <ropes_nn/train_step.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace core = ropes::core;
namespace nn = ropes::nn;
namespace crl = ropes::crl;
using nn::Shape;
using nn::Tensor;

namespace {

// the anchors of ropes_sim's `small` datasets (small-1c: 2,000, small-2c: 1,000), for the
// projected stage times; --anchors overrides. Each anchor gives one observational sample
// and two interventional ones per intervened joint.
std::int64_t small_anchors(std::int64_t cameras) {
  return cameras == 1 ? 2000 : 1000;
}

Tensor uniform(const Shape& shape, std::uint64_t seed) {
  core::PhiloxStream rng(seed, 0);
  std::vector<float> v(static_cast<std::size_t>(shape.numel()));
  for (float& x : v)
    x = rng.uniform_float();
  return Tensor(shape, v);
}

Tensor normal(const Shape& shape, std::uint64_t seed) {
  core::PhiloxStream rng(seed, 0);
  std::vector<float> v(static_cast<std::size_t>(shape.numel()));
  for (float& x : v)
    x = static_cast<float>(rng.normal());
  return Tensor(shape, v);
}

Shape code_shape(std::int64_t n, std::int64_t channels, std::int64_t side) {
  return Shape{n, channels, side, side};
}

// one case: what the peer builds and times (its JSON) and how we time it (run); the figure
// is images/s (higher is better) or milliseconds (lower is better)
struct Case {
  nlohmann::json peer;
  std::function<double()> run;
  bool milliseconds = false;
  bool gflops = false;  // also report the convolutions' GFLOP/s
};

nlohmann::json base(const std::string& name, const std::string& kind, std::int64_t batch,
                    int repeats) {
  return {{"name", name}, {"kind", kind}, {"batch", batch}, {"repeats", repeats}};
}

Case ae1_train(const std::string& name, const crl::Ae1Spec& spec, std::int64_t batch, int repeats) {
  nlohmann::json j = base(name, "ae1_train", batch, repeats);
  j["ae1"] = spec.to_json();
  return {j,
          [spec, batch, repeats] {
            crl::Ae1 net(spec);
            net.initialize(1);
            nn::Adam adam(net.named_parameters(), nn::AdamOptions{1e-4});
            const Tensor x = uniform(Shape{batch, 1, spec.image_size, spec.image_size}, 1);
            return batch / nn::bench::median_seconds(
                               [&] {
                                 nn::train_step(
                                     adam, nn::mean_loss([&](std::size_t) {
                                       return nn::mean(nn::square(nn::sub(net(x), x)), {1, 2, 3});
                                     }));
                               },
                               repeats);
          },
          false, true};
}

Case ae1_encode(const std::string& name, const crl::Ae1Spec& spec, std::int64_t batch,
                int repeats) {
  const bool latency = batch == 1;
  nlohmann::json j = base(name, latency ? "ae1_encode_latency" : "ae1_encode", batch, repeats);
  j["ae1"] = spec.to_json();
  return {j,
          [spec, batch, repeats, latency] {
            crl::Ae1 net(spec);
            net.initialize(1);
            const Tensor x = uniform(Shape{batch, 1, spec.image_size, spec.image_size}, 1);
            nn::GradModeGuard no_grad(false);
            const double s = nn::bench::median_seconds([&] { net.encode(x); }, repeats);
            return latency ? 1000 * s : batch / s;
          },
          latency};
}

Case ldr_train(const std::string& name, const crl::LdrSpec& spec, std::int64_t batch, int repeats) {
  nlohmann::json j = base(name, "ldr_train", batch, repeats);
  j["ldr"] = spec.to_json();
  return {j, [spec, batch, repeats] {
            crl::Ldr net(spec);
            net.initialize(2);
            nn::Adam adam(net.named_parameters(), nn::AdamOptions{1e-3});
            const Tensor y = normal(code_shape(batch, spec.in_channels, spec.input_size), 2);
            std::vector<float> t(static_cast<std::size_t>(batch));
            for (std::size_t i = 0; i < t.size(); ++i)
              t[i] = static_cast<float>(i % 2);
            const Tensor labels(Shape{batch}, t);
            return batch /
                   nn::bench::median_seconds(
                       [&] {
                         nn::train_step(adam, nn::mean_loss([&](std::size_t) {
                                          return nn::bce_with_logits_elementwise(net(y), labels);
                                        }));
                       },
                       repeats);
          }};
}

Case score_differences(const std::string& name, const crl::LdrSpec& spec, std::int64_t batch,
                       int repeats) {
  nlohmann::json j = base(name, "score_differences", batch, repeats);
  j["ldr"] = spec.to_json();
  return {j, [spec, batch, repeats] {
            crl::Ldr net(spec);
            net.initialize(2);
            const Tensor codes = normal(code_shape(batch, spec.in_channels, spec.input_size), 2);
            return batch /
                   nn::bench::median_seconds(
                       [&] {
                         Tensor y(codes.shape(),
                                  std::vector<float>(codes.data(), codes.data() + codes.numel()));
                         y.set_requires_grad(true);
                         nn::grad({nn::sum(net(y))}, {y});
                       },
                       repeats);
          }};
}

// AE2's training step as the trainer takes it: `batch` reconstruction rows and, with
// lambda > 0, `sparsity_batch` rows of one joint's unit score differences
Case ae2_train(const std::string& name, const crl::Ae2Spec& spec, std::int64_t batch,
               std::int64_t sparsity_batch, double lambda, std::int64_t micro_batch, int repeats) {
  nlohmann::json j = base(name, "ae2_train", batch, repeats);
  j["ae2"] = spec.to_json();
  j["sparsity_batch"] = sparsity_batch;
  j["lambda"] = lambda;
  j["target"] = 0;
  return {j, [=] {
            crl::Ae2 net(spec);
            net.initialize(3);
            nn::Adam adam(net.named_parameters(), nn::AdamOptions{1e-3});
            crl::Ae2Batch b;
            b.reconstruction = normal(code_shape(batch, spec.in_channels, spec.input_size), 3);
            b.term_codes.push_back(
                normal(code_shape(sparsity_batch, spec.in_channels, spec.input_size), 4));
            b.term_scores.push_back(crl::unit_length_rows(
                normal(code_shape(sparsity_batch, spec.in_channels, spec.input_size), 5)));
            b.targets.push_back(0);
            const double s = nn::bench::median_seconds(
                [&] {
                  std::size_t parts = 1;
                  const nn::BatchLoss loss = crl::ae2_batch_loss(
                      net, b, lambda, crl::SparsityNorm::kL2Squared, micro_batch, &parts);
                  nn::StepOptions options;
                  options.micro_batches = parts;
                  nn::train_step(adam, loss, options);
                },
                repeats);
            return static_cast<double>(batch + (lambda > 0 ? sparsity_batch : 0)) / s;
          }};
}

// one frame of `cameras` images through AE1's and AE2's encoders: the per-frame work of
// the Estimator (and of streaming)
Case frame_latency(const std::string& name, const crl::Ae1Spec& ae1, const crl::Ae2Spec& ae2,
                   std::int64_t cameras, int repeats) {
  nlohmann::json j = base(name, "frame_latency", 1, repeats);
  j["ae1"] = ae1.to_json();
  j["ae2"] = ae2.to_json();
  j["cameras"] = cameras;
  return {j,
          [=] {
            crl::Ae1 first(ae1);
            first.initialize(1);
            crl::Ae2 second(ae2);
            second.initialize(3);
            const Tensor x = uniform(Shape{cameras, 1, ae1.image_size, ae1.image_size}, 1);
            const std::int64_t side = ae1.code_size();
            nn::GradModeGuard no_grad(false);
            return 1000 *
                   nn::bench::median_seconds(
                       [&] {
                         second.encode(nn::reshape(
                             first.encode(x), Shape{1, cameras * ae1.code_channels, side, side}));
                       },
                       repeats);
          },
          true};
}

crl::Ae1Spec appendix_ae1(double m) {
  crl::Ae1Spec s;
  s.widths.clear();
  for (std::int64_t w : {64, 128, 256, 512})
    s.widths.push_back(static_cast<std::int64_t>(w * m));
  return s;
}

crl::Ae2Spec appendix_ae2(double m) {
  crl::Ae2Spec s;
  s.kind = "conv";
  s.in_channels = 2;
  s.latent_dim = 6;
  s.widths.clear();
  s.decoder_widths.clear();
  for (std::int64_t w : {64, 128, 256})
    s.widths.push_back(static_cast<std::int64_t>(w * m));
  for (std::int64_t w : {512, 256, 128})
    s.decoder_widths.push_back(static_cast<std::int64_t>(w * m));
  s.blocks_per_stage = 2;
  s.activation = "relu";
  return s;
}

void write_cases(const std::filesystem::path& file, const std::vector<Case>& cases) {
  nlohmann::json all = nlohmann::json::array();
  for (const Case& c : cases)
    all.push_back(c.peer);
  std::ofstream(file) << all.dump();
}

// the Estimator of a trained run on one frame at a time: latency and allocations per frame
int estimator_frames(const std::string& run, int threads) {
  nn::set_num_threads(threads);
  try {
    crl::Estimator estimator = crl::Estimator::load(run);
    const crl::ExperimentConfig& c = estimator.config();
    const std::size_t pixels = static_cast<std::size_t>(c.cameras * c.image_size * c.image_size);
    std::vector<std::uint8_t> frame(pixels);
    core::PhiloxStream rng(7, 0);
    for (std::uint8_t& v : frame)
      v = static_cast<std::uint8_t>(rng.next_u32());
    std::vector<float> latents(c.joints.size());
    for (int i = 0; i < 20; ++i)  // warm-up: the buffer pool fills
      estimator.estimate_frame(frame.data(), latents.data());
    const int frames = 500;
    std::vector<double> ms;
    nn::allocation_counter::start();
    for (int i = 0; i < frames; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      estimator.estimate_frame(frame.data(), latents.data());
      ms.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
    const std::uint64_t allocations = nn::allocation_counter::stop();
    std::sort(ms.begin(), ms.end());
    std::printf(
        "Estimator::estimate_frame of %s (%s, %lld camera(s), %d thread(s)), %d frames "
        "after 20 of warm-up:\n  latency p50 %.3f ms, p99 %.3f ms, max %.3f ms; %.1f heap "
        "allocations a frame\n",
        run.c_str(), c.name.c_str(), static_cast<long long>(c.cameras), nn::num_threads(), frames,
        ms[ms.size() / 2], ms[ms.size() * 99 / 100], ms.back(),
        static_cast<double>(allocations) / frames);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ropes_crl_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}

// the value of a count option, or 0 after a message when it is not a count >= 1
std::int64_t count_argument(const char* flag, const char* value) {
  char* end = nullptr;
  const long long n = std::strtoll(value, &end, 10);
  if (end == value || *end != '\0' || n < 1 || n > 1000000000) {
    std::fprintf(stderr, "ropes_crl_bench: %s %s: expected a count >= 1\n", flag, value);
    return 0;
  }
  return n;
}

int usage() {
  std::fprintf(stderr,
               "usage: ropes_crl_bench [--config NAME|PATH] [--anchors N] [--quick] [--no-peer]\n"
               "                       [--threads N] [--only TEXT]\n"
               "       ropes_crl_bench --run RUN [--threads N]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, peer_wanted = true;
  int threads = 2;
  std::string config_name = "1c-small", run, only;
  std::int64_t anchors = 0;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) {
      quick = true;
    } else if (!std::strcmp(argv[i], "--no-peer")) {
      peer_wanted = false;
    } else if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) {
      const std::int64_t n = count_argument("--threads", argv[++i]);
      if (n < 1)
        return 2;
      threads = static_cast<int>(n);
    } else if (!std::strcmp(argv[i], "--config") && i + 1 < argc) {
      config_name = argv[++i];
    } else if (!std::strcmp(argv[i], "--anchors") && i + 1 < argc) {
      anchors = count_argument("--anchors", argv[++i]);
      if (anchors < 1)
        return 2;
    } else if (!std::strcmp(argv[i], "--only") && i + 1 < argc) {
      only = argv[++i];
    } else if (!std::strcmp(argv[i], "--run") && i + 1 < argc) {
      run = argv[++i];
    } else {
      return usage();
    }
  }
  if (!run.empty())
    return estimator_frames(run, threads);
  crl::ExperimentConfig config, paper;
  try {
    config = crl::load_experiment_config(config_name);
    paper = crl::load_experiment_config(std::to_string(config.cameras) + "c-paper");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ropes_crl_bench: %s\n", e.what());
    return 2;
  }
  nn::set_num_threads(threads);
  const int r = quick ? 3 : 7;
  const double peak = nn::bench::gemm_peak_gflops();
  std::printf("ropes_crl_bench: %d thread(s); GEMM peak (Eigen sgemm 1024^3) %.1f GFLOP/s\n",
              nn::num_threads(), peak);

  // the cases, in the order they are printed
  std::vector<Case> cases;
  for (const auto& [m, tag] : {std::pair{1.0 / 8, "x1/8"}, std::pair{1.0 / 4, "x1/4"}}) {
    cases.push_back(ae1_train(std::string("ae1_") + tag + "_train", appendix_ae1(m), 32, r));
    cases.push_back(
        ae1_encode(std::string("ae1_") + tag + "_encode_latency_ms", appendix_ae1(m), 1, 5 * r));
  }
  crl::LdrSpec ldr2;
  ldr2.in_channels = 2;
  cases.push_back(ldr_train("ldr_train", ldr2, 64, 3 * r));
  for (const auto& [m, tag] : {std::pair{1.0 / 8, "x1/8"}, std::pair{1.0 / 4, "x1/4"}})
    cases.push_back(ae2_train(std::string("ae2_") + tag + "_sparsity_train", appendix_ae2(m), 64,
                              64, 1.0, 128, r));
  const std::size_t appendix_cases = cases.size();

  const std::string p = config.name + "_";
  const crl::Ae1Training& t1 = config.ae1_training;
  const crl::LdrTraining& tl = config.ldr_training;
  const crl::Ae2Training& t2 = config.ae2_training;
  cases.push_back(ae1_train(p + "ae1_train", config.ae1, t1.batch_size, r));
  cases.push_back(ae1_encode(p + "ae1_encode", config.ae1, 256, r));
  cases.push_back(ldr_train(p + "ldr_train", config.ldr, tl.batch_size, 3 * r));
  cases.push_back(score_differences(p + "score_differences", config.ldr, 256, 3 * r));
  cases.push_back(ae2_train(p + "ae2_train", config.ae2, t2.batch_size, t2.sparsity_batch_size,
                            t2.lambda, t2.micro_batch, 3 * r));
  cases.push_back(ae2_train(p + "ae2_lambda0_train", config.ae2, t2.batch_size,
                            t2.sparsity_batch_size, 0.0, t2.micro_batch, 3 * r));
  cases.push_back(
      frame_latency(p + "frame_latency_ms", config.ae1, config.ae2, config.cameras, 10 * r));
  const std::size_t config_cases = cases.size();

  // the paper preset's AE1: one step on one micro-batch of its batch
  const std::int64_t paper_micro = paper.ae1_training.micro_batch;
  cases.push_back(ae1_train(paper.name + "_ae1_train", paper.ae1, paper_micro, quick ? 1 : 2));

  if (!only.empty()) {
    std::vector<Case> chosen;
    for (Case& c : cases)
      if (c.peer["name"].get<std::string>().find(only) != std::string::npos)
        chosen.push_back(std::move(c));
    if (chosen.empty()) {
      std::fprintf(stderr, "ropes_crl_bench: --only %s: no case's name contains it\n",
                   only.c_str());
      return 2;
    }
    cases = std::move(chosen);
  }
  std::map<std::string, double> peer;
  if (peer_wanted) {
    const std::filesystem::path file = std::filesystem::temp_directory_path() /
                                       ("ropes_crl_bench_" + std::to_string(::getpid()) + ".json");
    write_cases(file, cases);
    peer = nn::bench::run_torch_peer(std::string(ROPES_CRL_BENCH_DIR) + "/torch_peer.py",
                                     file.string() + " --threads " + std::to_string(threads));
    std::filesystem::remove(file);
  }

  std::map<std::string, double> ours;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    // the group headings, where every case runs (--only keeps some)
    const bool headings = only.empty();
    if (headings && i == 0)
      std::printf(
          "-- the appendix's networks (AE1 128x128x1 batch 32, LDR and AE2 8x8x2 batch "
          "64, AE2 loss mse + ||E|J_g^T v| - e||^2)\n");
    if (headings && i == appendix_cases)
      std::printf("-- the stages of %s\n", config.name.c_str());
    if (headings && i == config_cases)
      std::printf(
          "-- %s: AE1 at the appendix's width, one micro-batch of %lld of its %lld-image "
          "step\n",
          paper.name.c_str(), static_cast<long long>(paper_micro),
          static_cast<long long>(paper.ae1_training.batch_size));
    const Case& c = cases[i];
    const std::string name = c.peer["name"];
    nn::reset_flop_count();
    const double figure = c.run();
    const double flops = static_cast<double>(nn::flop_count());
    ours[name] = figure;
    std::string extra;
    if (c.gflops) {
      // the flop counter saw the warm-up and the repeats: (repeats + 1) steps
      const double steps = c.peer["repeats"].get<double>() + 1;
      const double gflops = flops / steps * figure / c.peer["batch"].get<double>() / 1e9;
      char text[64];
      std::snprintf(text, sizeof text, "%6.1f GFLOP/s (%4.1f%% of peak)", gflops,
                    100 * gflops / peak);
      extra = text;
    }
    const auto padding = peer.find(name + ":native_padding");
    if (padding != peer.end())
      extra += std::string(extra.empty() ? "" : "  ") +
               "(peer: " + (padding->second > 0 ? "native" : "explicit") + " padding)";
    nn::bench::report(name, figure, peer, c.milliseconds ? "ms" : "images/s", !c.milliseconds,
                      extra);
  }

  if (!only.empty())
    return 0;
  // the stage wall times these rates imply for one training run of `config`
  const std::int64_t joints = static_cast<std::int64_t>(config.joints.size());
  const std::int64_t dataset_anchors = anchors > 0 ? anchors : small_anchors(config.cameras);
  const double images = static_cast<double>(dataset_anchors * (1 + 2 * joints) * config.cameras);
  const double held_in = (1 - tl.held_out_fraction) * dataset_anchors * 2;
  const double ae2_models = t2.mode == "per_joint" ? static_cast<double>(joints) : 1.0;
  const double ae2_rows = static_cast<double>(t2.batch_size + t2.sparsity_batch_size);
  struct Projection {
    const char* what;
    std::string name;
    double work;  // images (or rows) the stage pushes through the case's figure
  };
  const std::vector<Projection> stages = {
      {"AE1 training", p + "ae1_train", static_cast<double>(t1.steps * t1.batch_size)},
      {"AE1 encoding of the dataset", p + "ae1_encode", images},
      {"one LDR epoch of each joint", p + "ldr_train", held_in * static_cast<double>(joints)},
      {"score differences of each joint", p + "score_differences",
       2.0 * dataset_anchors * static_cast<double>(joints)},
      {"the AE2s with the sparsity term", p + "ae2_train",
       ae2_models * static_cast<double>(t2.steps) * ae2_rows},
      {"the lambda = 0 AE2", p + "ae2_lambda0_train",
       static_cast<double>(t2.steps * t2.batch_size)},
  };
  std::printf(
      "-- %s, wall time of each stage projected from the rates above (a %lld-anchor "
      "dataset of %.0f images)\n",
      config.name.c_str(), static_cast<long long>(dataset_anchors), images);
  double total_ours = 0, total_peer = 0;
  for (const Projection& s : stages) {
    const double mine = s.work / ours[s.name];
    total_ours += mine;
    const auto it = peer.find(s.name);
    std::printf("%-34s %10.1f s", s.what, mine);
    if (it != peer.end() && it->second > 0) {
      const double theirs = s.work / it->second;
      total_peer += theirs;
      std::printf("          pytorch %10.1f s  ratio %5.2fx", theirs, theirs / mine);
    }
    std::printf("\n");
  }
  std::printf("%-34s %10.1f s", "all (one LDR epoch)", total_ours);
  if (total_peer > 0)
    std::printf("          pytorch %10.1f s  ratio %5.2fx", total_peer, total_peer / total_ours);
  std::printf("\n");
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  std::printf("peak RSS %.2f GiB\n", usage.ru_maxrss / 1048576.0);
  return 0;
}
