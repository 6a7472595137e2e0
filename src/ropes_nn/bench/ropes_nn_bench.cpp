// ropes_nn_bench: images/s of one training step (forward, backward, Adam) for the paper's
// networks, next to PyTorch's figures for the same networks measured in the same run by
// bench/torch_peer.py (Debian's python3-torch, tcmalloc preloaded, same thread count).
// Also the achieved GFLOP/s of the convolutions against a GEMM peak measured here.
//
//   ropes_nn_bench [--quick] [--no-peer] [--threads N]
//   ropes_nn_bench --paper-ae1 [--micro-batch M]   one AE1 step at the appendix's width
//                                                 (batch 32 in micro-batches of M), with
//                                                 its time and peak resident memory
#include <sys/resource.h>
#include <unistd.h>
#include <Eigen/Core>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "networks.hpp"
#include "ropes_nn/batch_loader.hpp"
#include "ropes_nn/ops.hpp"
#include "ropes_nn/parallel.hpp"
#include "ropes_nn/philox.hpp"
#include "ropes_nn/train_step.hpp"

using namespace ropes::nn;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// median seconds of `repeats` calls after one warm-up call
double median_seconds(const std::function<void()>& step, int repeats) {
  step();
  std::vector<double> times;
  for (int i = 0; i < repeats; ++i) {
    const auto t0 = Clock::now();
    step();
    times.push_back(seconds_since(t0));
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

// GEMM peak: the best of a few 1024^3 single-precision products through Eigen
double gemm_peak_gflops() {
  using M = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const int n = 1024;
  M a = M::Random(n, n), b = M::Random(n, n), c(n, n);
  double best = 0;
  for (int i = 0; i < 5; ++i) {
    const auto t0 = Clock::now();
    c.noalias() = a * b;
    best = std::max(best, 2.0 * n * n * n / seconds_since(t0) / 1e9);
  }
  return best + 0 * c(0, 0);
}

std::map<std::string, double> run_peer(bool quick, int threads) {
  std::map<std::string, double> peer;
  std::string preload;
  for (const char* lib : {"/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4"}) {
    if (FILE* f = std::fopen(lib, "r")) {
      std::fclose(f);
      preload = std::string("LD_PRELOAD=") + lib + " ";
    }
  }
  if (preload.empty())
    std::printf("note: libtcmalloc-minimal4 missing; PyTorch without it\n");
  // the peer at its best: OPENBLAS_CORETYPE=Haswell (set on these machines for old
  // OpenBLAS builds) is dropped for this command only
  const std::string command = "env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE " + preload +
                              "/usr/bin/python3 " + ROPES_NN_BENCH_DIR +
                              "/torch_peer.py --threads " + std::to_string(threads) +
                              (quick ? " --quick" : "") + " 2>/dev/null";
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe)
    return peer;
  char name[128];
  double value = 0;
  while (std::fscanf(pipe, "%127s %lf", name, &value) == 2)
    peer[name] = value;
  if (pclose(pipe) != 0 && peer.empty()) {
    std::printf("note: the PyTorch peer did not run (apt-get install python3-torch)\n");
  }
  return peer;
}

void report(const char* name, double ours, const std::map<std::string, double>& peer,
            const char* unit, bool higher_is_better, double gflops = 0, double peak = 0) {
  std::printf("%-30s %10.2f %-12s", name, ours, unit);
  const auto it = peer.find(name);
  if (it != peer.end()) {
    const double ratio = higher_is_better ? ours / it->second : it->second / ours;
    std::printf("  pytorch %10.2f  ratio %5.2fx", it->second, ratio);
  }
  if (gflops > 0)
    std::printf("  %6.1f GFLOP/s (%4.1f%% of peak)", gflops, 100 * gflops / peak);
  std::printf("\n");
}

// mean squared error of each sample: [N, ...] -> [N]
Tensor per_sample_mse(const Tensor& prediction, const Tensor& target) {
  std::vector<int> axes;
  for (int a = 1; a < prediction.rank(); ++a)
    axes.push_back(a);
  return mean(square(sub(prediction, target)), axes);
}

struct LoaderFigure {
  double images_per_s = 0;
  std::string what;
};

// BatchLoader throughput: a dataset of 128x128x1 u8 images (4 shards) in a temporary
// directory, read in shuffled batches of 32 and converted to float tensors in [0, 1]. The
// files were just written, so they come from the page cache: this is the loader's own cost.
LoaderFigure loader_rate(bool prefetch, bool quick) {
  const std::int64_t per_shard = 512, shards = 4;
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("ropes_nn_bench_loader_" + std::to_string(::getpid()));
  const std::vector<ColumnSpec> columns = {{"images", DType::kU8, {1, 128, 128}}};
  PhiloxStream rng(4, 0);
  for (int s = 0; s < shards; ++s) {
    NpyArray images{DType::kU8,
                    {per_shard, 1, 128, 128},
                    std::vector<std::uint8_t>(static_cast<std::size_t>(per_shard) * 128 * 128)};
    for (std::uint8_t& v : images.data)
      v = static_cast<std::uint8_t>(rng.next_u32());
    write_dataset_shard(dir, s, columns, {images});
  }
  write_dataset_manifest(dir, columns, static_cast<int>(shards), "{}");
  const DatasetReader reader = DatasetReader::open(dir);
  BatchLoaderOptions options;
  options.columns = {"images"};
  options.batch_size = 32;
  options.prefetch = prefetch;
  BatchLoader loader(reader, options);
  const int batches = quick ? 64 : 256;
  // the consumer touches every value, as a training step would
  double checksum = 0;
  const auto t0 = Clock::now();
  for (int b = 0; b < batches; ++b) {
    const Batch batch = loader.next();
    const float* p = batch.tensor("images").data();
    checksum += p[batch.tensor("images").numel() - 1];
  }
  const double s = seconds_since(t0);
  std::filesystem::remove_all(dir);
  return {batches * 32 / s + 0 * checksum,
          std::string("batch 32, shuffled over ") + std::to_string(per_shard * shards) +
              " rows, page cache warm, " + (prefetch ? "read ahead on a thread" : "no read-ahead")};
}

// one AE1 training step at paper width, batch 32 split into micro-batches
int paper_ae1(int micro_batch) {
  if (micro_batch < 1 || 32 % micro_batch != 0) {
    std::fprintf(stderr, "--micro-batch %d: expected a divisor of 32\n", micro_batch);
    return 2;
  }
  bench::Ae1 ae(1.0);
  std::vector<Tensor> params = ae.encoder->parameters();
  for (const Tensor& p : ae.decoder->parameters())
    params.push_back(p);
  Adam adam(params, AdamOptions{1e-4});
  PhiloxStream rng(1, 0);
  std::vector<float> pixels(32 * 128 * 128);
  for (float& v : pixels)
    v = rng.uniform_float();
  const Tensor x(Shape{32, 1, 128, 128}, pixels);
  const std::size_t parts = static_cast<std::size_t>(32 / micro_batch);
  const auto t0 = Clock::now();
  StepOptions options;
  options.micro_batches = parts;
  const double loss = train_step(adam, mean_loss([&](std::size_t i) {
                                   const Tensor xi =
                                       slice(x, 0, static_cast<std::int64_t>(i) * micro_batch,
                                             static_cast<std::int64_t>(i + 1) * micro_batch);
                                   return per_sample_mse((*ae.decoder)((*ae.encoder)(xi)), xi);
                                 }),
                                 options)
                          .loss;
  const double s = seconds_since(t0);
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  std::printf(
      "paper-width AE1: %lld parameters, batch 32 as %zu micro-batches of %d: %.1f s "
      "(%.2f images/s), loss %.4f, peak RSS %.2f GiB\n",
      static_cast<long long>(ae.encoder->parameter_count() + ae.decoder->parameter_count()), parts,
      micro_batch, s, 32 / s, loss, usage.ru_maxrss / 1048576.0);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, peer_wanted = true, paper = false;
  int threads = 2, micro_batch = 4;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) {
      quick = true;
    } else if (!std::strcmp(argv[i], "--no-peer")) {
      peer_wanted = false;
    } else if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--paper-ae1")) {
      paper = true;
    } else if (!std::strcmp(argv[i], "--micro-batch") && i + 1 < argc) {
      micro_batch = std::atoi(argv[++i]);
    } else {
      std::fprintf(stderr,
                   "usage: ropes_nn_bench [--quick] [--no-peer] [--threads N]\n"
                   "       ropes_nn_bench --paper-ae1 [--micro-batch M] [--threads N]\n");
      return 2;
    }
  }
  set_num_threads(threads);
  if (paper)
    return paper_ae1(micro_batch);
  const int repeats = quick ? 3 : 7;
  const double peak = gemm_peak_gflops();
  std::printf("ropes_nn_bench: %d thread(s); GEMM peak (Eigen sgemm 1024^3) %.1f GFLOP/s\n",
              num_threads(), peak);
  const auto peer = peer_wanted ? run_peer(quick, threads) : std::map<std::string, double>{};

  // AE1 at two widths: 128x128x1 images, batch 32
  std::map<std::string, double> ae1_rate;
  for (const auto& [m, label] : {std::pair{1.0 / 8, "ae1_x1/8"}, std::pair{1.0 / 4, "ae1_x1/4"}}) {
    bench::Ae1 ae(m);
    std::vector<Tensor> params = ae.encoder->parameters();
    for (const Tensor& p : ae.decoder->parameters())
      params.push_back(p);
    Adam adam(params, AdamOptions{1e-4});
    PhiloxStream rng(1, 0);
    std::vector<float> pixels(32 * 128 * 128);
    for (float& v : pixels)
      v = rng.uniform_float();
    const Tensor x(Shape{32, 1, 128, 128}, pixels);
    reset_flop_count();
    const double s = median_seconds(
        [&] {
          train_step(adam, mean_loss([&](std::size_t) {
                       return per_sample_mse((*ae.decoder)((*ae.encoder)(x)), x);
                     }));
        },
        repeats);
    const double flops = static_cast<double>(flop_count()) / (repeats + 1);
    report((std::string(label) + "_train").c_str(), 32 / s, peer, "images/s", true, flops / s / 1e9,
           peak);
    ae1_rate[label] = 32 / s;
    const Tensor one = slice(x, 0, 0, 1);
    GradModeGuard no_grad(false);
    const double latency = median_seconds([&] { (*ae.encoder)(one); }, repeats * 5);
    report((std::string(label) + "_encode_latency_ms").c_str(), 1000 * latency, peer, "ms", false);
  }

  // the loader feeding AE1: shuffled batches of 32 u8 images into float tensors
  for (const bool prefetch : {true, false}) {
    const LoaderFigure f = loader_rate(prefetch, quick);
    std::printf("%-30s %10.2f %-12s  = %.0fx ae1_x1/8_train, %.0fx ae1_x1/4_train (%s)\n",
                prefetch ? "loader_u8_to_f32_prefetch" : "loader_u8_to_f32_sync", f.images_per_s,
                "images/s", f.images_per_s / ae1_rate["ae1_x1/8"],
                f.images_per_s / ae1_rate["ae1_x1/4"], f.what.c_str());
  }

  // LDR: 8x8x2 codes, batch 64
  {
    bench::Ldr ldr(2);
    Adam adam(ldr.parameters(), AdamOptions{1e-3});
    PhiloxStream rng(2, 0);
    std::vector<float> y(64 * 2 * 8 * 8), t(64);
    for (float& v : y)
      v = static_cast<float>(rng.normal());
    for (float& v : t)
      v = rng.uniform_float() < 0.5f ? 0.0f : 1.0f;
    const Tensor codes(Shape{64, 2, 8, 8}, y), labels(Shape{64, 1}, t);
    const double s = median_seconds(
        [&] {
          train_step(adam, mean_loss([&](std::size_t) {
                       return reshape(bce_with_logits_elementwise(ldr.forward(codes), labels),
                                      Shape{64});
                     }));
        },
        repeats * 3);
    report("ldr_train", 64 / s, peer, "images/s", true);
  }

  // AE2 with the double-backward score-sparsity loss: 8x8x2 codes, batch 64
  for (const auto& [m, label] : {std::pair{1.0 / 8, "ae2_x1/8_sparsity_train"},
                                 std::pair{1.0 / 4, "ae2_x1/4_sparsity_train"}}) {
    bench::Ae2 ae(m, 2, 6);
    Adam adam(ae.parameters(), AdamOptions{7e-5});
    PhiloxStream rng(3, 0);
    std::vector<float> y(64 * 128), v(64 * 128);
    for (float& a : y)
      a = static_cast<float>(rng.normal());
    for (float& a : v)
      a = static_cast<float>(rng.normal());
    const Tensor codes(Shape{64, 2, 8, 8}, y), scores(Shape{64, 2, 8, 8}, v);
    std::vector<float> e(6, 0.0f);
    e[1] = 1.0f;
    const Tensor target(Shape{6}, e);
    const double s = median_seconds(
        [&] {
          // statistics: per-sample reconstruction error and |J_g(z)^T v|; the loss is
          // mean error + || mean |J_g^T v| - e_1 ||^2
          BatchLoss loss;
          loss.statistics = [&](std::size_t, bool create_graph) {
            const Tensor z = ae.encode(codes);
            const Tensor recon = ae.decode(z);
            const Tensor jtv = grad({recon}, {z}, {scores}, create_graph)[0];
            return std::vector<Tensor>{per_sample_mse(recon, codes), abs(jtv)};
          };
          loss.outer = [&](const std::vector<Tensor>& m) {
            return add(m[0], sum(square(sub(m[1], target))));
          };
          train_step(adam, loss);
        },
        repeats);
    report(label, 64 / s, peer, "images/s", true);
  }
  return 0;
}
