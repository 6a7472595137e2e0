#include "ropes_nn/benchmark.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "gemm.hpp"
#include "ropes_core/child_process.hpp"

namespace ropes::nn::bench {

namespace {
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}
}  // namespace

double median_seconds(const std::function<void()>& step, int repeats) {
  step();
  std::vector<double> times;
  for (int i = 0; i < std::max(repeats, 1); ++i) {
    const auto t0 = Clock::now();
    step();
    times.push_back(seconds_since(t0));
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

double gemm_peak_gflops() {
  using M = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const int n = 1024;
  M a = M::Random(n, n), b = M::Random(n, n), c(n, n);
  double best = 0;
  for (int i = 0; i < 5; ++i) {
    const auto t0 = Clock::now();
    gemm(a.data(), b.data(), c.data(), n, n, n);
    best = std::max(best, 2.0 * n * n * n / seconds_since(t0) / 1e9);
  }
  return best + 0 * c(0, 0);
}

std::map<std::string, double> run_torch_peer(const std::string& script, const std::string& args) {
  std::map<std::string, double> peer;
  std::string preload;
  const char* tcmalloc = "/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4";
  if (FILE* f = std::fopen(tcmalloc, "r")) {
    std::fclose(f);
    preload = std::string("LD_PRELOAD=") + tcmalloc + " ";
  } else {
    std::printf("note: libtcmalloc-minimal4 missing; PyTorch runs without it\n");
  }
  const std::string command =
      "env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE OPENBLAS_NUM_THREADS=1 " + preload +
      "/usr/bin/python3 " + script + " " + args + " 2>/dev/null";
  const core::ChildResult r = core::run_shell(command);
  std::istringstream lines(r.output);
  std::string name;
  double value = 0;
  while (lines >> name >> value)
    peer[name] = value;
  if (r.rc != 0 || peer.empty())
    std::printf("note: the PyTorch peer did not finish (apt-get install python3-torch)\n");
  return peer;
}

void report(const std::string& name, double ours, const std::map<std::string, double>& peer,
            const char* unit, bool higher_is_better, const std::string& extra) {
  std::printf("%-34s %10.2f %-9s", name.c_str(), ours, unit);
  const auto it = peer.find(name);
  if (it != peer.end() && it->second > 0 && ours > 0) {
    const double ratio = higher_is_better ? ours / it->second : it->second / ours;
    std::printf("  pytorch %10.2f  ratio %5.2fx", it->second, ratio);
  }
  if (!extra.empty())
    std::printf("  %s", extra.c_str());
  std::printf("\n");
  std::fflush(stdout);
}

}  // namespace ropes::nn::bench
