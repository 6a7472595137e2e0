#pragma once
/// @file benchmark.hpp
/// What the workspace's benchmark executables share: a median timer, a GEMM peak, the
/// PyTorch peer run at its best, and one line per figure with the peer's beside it.
/// Benchmarks are executables run by hand, never timed tests.
#include <functional>
#include <map>
#include <string>

namespace ropes::nn::bench {

/// The median seconds of `repeats` calls of `step`, after one warm-up call.
double median_seconds(const std::function<void()>& step, int repeats);

/// The best of a few 1024^3 single-precision products through the kernels' GEMM (Eigen's
/// register kernel at the workspace's blocking, on num_threads() threads), in GFLOP/s.
double gemm_peak_gflops();

/// Runs `/usr/bin/python3 script args` as the PyTorch peer at its best on these machines:
/// Debian's libtcmalloc_minimal.so.4 preloaded when installed, OPENBLAS_NUM_THREADS=1
/// (OpenBLAS's own pool fights PyTorch's OpenMP threads in Linear and ConvTranspose2d),
/// OPENBLAS_CORETYPE and OPENBLAS_L2_SIZE unset for that command only. The script prints
/// "name value" lines; they are returned by name. A missing peer gives an empty map and a
/// printed note, never a failure.
std::map<std::string, double> run_torch_peer(const std::string& script, const std::string& args);

/// One line: name, our figure and unit, then the peer's figure and the ratio (ours over the
/// peer's when higher is better, the peer's over ours otherwise) when the peer has the name,
/// then `extra`.
void report(const std::string& name, double ours, const std::map<std::string, double>& peer,
            const char* unit, bool higher_is_better, const std::string& extra = "");

}  // namespace ropes::nn::bench
