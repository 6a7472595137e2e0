// ropes_nn_bench: the generic pieces of ropes_nn a trainer leans on: the GEMM peak the
// kernels are measured against, and the BatchLoader's throughput. The paper's networks and
// their PyTorch peer are timed by ropes_crl_bench (ropes_crl owns those networks).
//
//   ropes_nn_bench [--quick] [--threads N]
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "ropes_core/philox.hpp"
#include "ropes_nn/batch_loader.hpp"
#include "ropes_nn/benchmark.hpp"
#include "ropes_nn/build_info.hpp"
#include "ropes_nn/layers.hpp"
#include "ropes_nn/ops.hpp"
#include "ropes_nn/parallel.hpp"

using namespace ropes::nn;
using namespace ropes::core;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
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

// A training step of an AE1-like encoder (the `small` preset's shapes: a 4x4 stride-4 stem,
// residual blocks with group norm at 32, 16 and 8 pixels, stride-2 convolutions between):
// forward and backward of a batch of 32 images of 128x128, in images/s. Every kernel a
// trainer runs is in it: the GEMM (at the dispatched level), im2col, group norm, elementwise.
double encoder_step_rate(bool quick) {
  Sequential net;
  net.add(std::make_shared<Conv2d>(1, 16, 4, 4));
  net.add(std::make_shared<ResBlockGN>(16, 4));
  net.add(std::make_shared<Conv2d>(16, 32, 3, 2));
  net.add(std::make_shared<ResBlockGN>(32, 8));
  net.add(std::make_shared<Conv2d>(32, 64, 3, 2));
  net.add(std::make_shared<ResBlockGN>(64, 8));
  net.initialize(3);
  PhiloxStream rng(6, 0);
  std::vector<float> pixels(32 * 128 * 128);
  for (float& v : pixels)
    v = rng.uniform_float();
  const Tensor x(Shape{32, 1, 128, 128}, pixels);
  const std::vector<Tensor> params = net.parameters();
  const double s = bench::median_seconds(
      [&] {
        const Tensor y = net(x);
        const Tensor loss = mean(mul(y, y));
        (void)grad({loss}, params);
      },
      quick ? 3 : 9);
  return 32 / s;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  int threads = 2;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) {
      quick = true;
    } else if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: ropes_nn_bench [--quick] [--threads N]\n");
      return 2;
    }
  }
  set_num_threads(threads);
  const BuildInfo& build = build_info();
  std::printf("ropes_nn_bench: %d thread(s); kernels %s (build %s, baseline %s)\n", num_threads(),
              build.isa_level.c_str(), build.isa_build.c_str(), build.isa_baseline.c_str());
  std::printf("GEMM peak (Eigen's kernel, sgemm 1024^3) %.1f GFLOP/s\n", bench::gemm_peak_gflops());
  bench::report("encoder_train_step", encoder_step_rate(quick), {}, "images/s", true,
                "(AE1-like encoder, batch 32 of 128x128, forward and backward)");
  // the loader feeding AE1: shuffled batches of 32 u8 images into float tensors
  for (const bool prefetch : {true, false}) {
    const LoaderFigure f = loader_rate(prefetch, quick);
    bench::report(prefetch ? "loader_u8_to_f32_prefetch" : "loader_u8_to_f32_sync", f.images_per_s,
                  {}, "images/s", true, "(" + f.what + ")");
  }
  return 0;
}
