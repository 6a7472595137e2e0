// ropes_stream_bench: the streaming pipeline's throughput and latency on this machine
// (README "Streaming benchmark"). For each trained run given: the peer, rendering and the
// Estimator called in one process with no transport; then ropes-sim-stream -> ropes-stream ->
// this process over DDS (the loopback profile), at the target rate and as fast as it goes.
// Latency is from frame publication (ImageFrame.stamp_ns, taken after rendering) to the
// estimate's reception here; inference is the node's own latency_ns (frame taken -> estimate
// written); transport and queueing are the rest. Every process shares the same cores.
#include <ropes_core/child_process.hpp>
#include <ropes_crl/estimator.hpp>
#include <ropes_msgs/dds.hpp>
#include <ropes_sim/dataset_config.hpp>
#include <ropes_sim/renderer.hpp>
#include <ropes_sim/rig_renderer.hpp>
#include <ropes_sim/trajectory.hpp>

#include <csignal>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "ropes_eval/test_data.hpp"

namespace {

namespace fs = std::filesystem;
namespace msgs = ropes::msgs;
using Clock = std::chrono::steady_clock;
using ropes::core::ChildOptions;
using ropes::core::ChildProcess;

const char* const kUsage = R"(usage: ropes_stream_bench --run RUN [--run RUN2 ...] [options]

options:
  --seconds S   length of each streamed measurement (default 20)
  --rate HZ     the target frame rate (default 30)
  --work DIR    where the node logs go (default /tmp/ropes_stream_bench)
)";

double percentile(std::vector<double> v, double p) {
  if (v.empty())
    return NAN;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1) + 0.5);
  return v[std::min(i, v.size() - 1)];
}

std::string text_of(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

struct Peer {
  double render_ms = 0, infer_ms = 0;
};

// rendering and inference in this process, one frame at a time, no transport
Peer in_process(ropes::crl::Estimator& estimator, const ropes::sim::DatasetConfig& config,
                int frames) {
  ropes::sim::RigRenderer rig(config);
  ropes::sim::Trajectory trajectory(rig.sampler(), 0, 2.0, 30);
  std::vector<std::uint8_t> pixels(rig.frame_bytes());
  std::vector<float> latents(estimator.joints().size()), angles(latents.size());
  Peer p;
  for (int i = -20; i < frames; ++i) {
    const auto q = trajectory.next().q;
    const auto t0 = Clock::now();
    rig.render(q, pixels.data());
    const auto t1 = Clock::now();
    estimator.estimate_frame(pixels.data(), latents.data(), nullptr);
    const auto t2 = Clock::now();
    if (i >= 0) {
      p.render_ms += std::chrono::duration<double, std::milli>(t1 - t0).count();
      p.infer_ms += std::chrono::duration<double, std::milli>(t2 - t1).count();
    }
  }
  p.render_ms /= frames;
  p.infer_ms /= frames;
  return p;
}

struct Streamed {
  long long frames = 0, estimates = 0;
  double seconds = 0, render_ms = NAN;
  std::vector<double> latency_ms, inference_ms;
};

Streamed stream(const fs::path& run, const std::string& dataset_config, double rate,
                long long frames, const fs::path& work) {
  Streamed out;
  msgs::Participant participant({"ropes_stream_bench"});
  msgs::Subscriber<msgs::PoseEstimate> estimates(participant);
  const fs::path node_log = work / "node.log", sim_log = work / "sim.log";
  ChildProcess node({ROPES_STREAM_EXE, "--run", run.string(), "--run-id", "bench"},
                    ChildOptions::to_log(node_log));
  if (!estimates.wait_for_matched(1, std::chrono::seconds(60)))
    throw std::runtime_error("ropes-stream did not come up: " + text_of(node_log));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // its frame reader, matched too
  ChildProcess sim(
      {ROPES_SIM_STREAM_EXE, "--config", dataset_config, "--rate", std::to_string(rate), "--frames",
       std::to_string(frames), "--wait-for-subscribers", "1"},
      ChildOptions::to_log(sim_log));
  msgs::PoseEstimate e;
  Clock::time_point first{}, last{};
  Clock::time_point quiet = Clock::now();
  while (true) {
    if (estimates.take(e, std::chrono::milliseconds(50))) {
      const auto now = Clock::now();
      out.latency_ms.push_back(static_cast<double>(msgs::now_ns() - e.frame_stamp_ns()) / 1e6);
      out.inference_ms.push_back(static_cast<double>(e.latency_ns()) / 1e6);
      if (out.estimates == 0)
        first = now;
      last = quiet = now;
      ++out.estimates;
    } else if (!sim.running() && Clock::now() - quiet > std::chrono::seconds(1)) {
      break;
    }
  }
  node.signal(SIGINT);
  node.wait(std::chrono::seconds(20));
  out.seconds = std::chrono::duration<double>(last - first).count();
  const std::string s = text_of(sim_log);
  std::smatch m;
  if (std::regex_search(s, m, std::regex(R"((\d+) frames in .* rendering ([0-9.]+) ms a frame)"))) {
    out.frames = std::stoll(m[1]);
    out.render_ms = std::stod(m[2]);
  }
  return out;
}

void report(const std::string& what, const Streamed& s) {
  const double rate = s.seconds > 0 ? static_cast<double>(s.estimates - 1) / s.seconds : NAN;
  const double p50 = percentile(s.latency_ms, 0.5), inf50 = percentile(s.inference_ms, 0.5);
  std::printf(
      "  %-16s %5lld frames -> %5lld estimates  %6.1f estimates/s  latency p50 %6.2f  p99 %6.2f  "
      "max %6.2f ms  | rendering %.2f ms a frame (before publication), inference p50 %.2f, "
      "transport + queueing p50 %.2f ms\n",
      what.c_str(), s.frames, s.estimates, rate, p50, percentile(s.latency_ms, 0.99),
      s.latency_ms.empty() ? NAN : *std::max_element(s.latency_ms.begin(), s.latency_ms.end()),
      s.render_ms, inf50, p50 - inf50);
}

int run(int argc, char** argv) {
  std::vector<std::string> runs;
  double seconds = 20, rate = 30;
  fs::path work = "/tmp/ropes_stream_bench";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::printf("%s", kUsage);
      return 0;
    }
    if (i + 1 >= argc)
      throw std::invalid_argument("'" + a + "' needs a value");
    const std::string v = argv[++i];
    if (a == "--run")
      runs.push_back(v);
    else if (a == "--seconds")
      seconds = std::stod(v);
    else if (a == "--rate")
      rate = std::stod(v);
    else if (a == "--work")
      work = v;
    else
      throw std::invalid_argument("unknown option '" + a + "'");
  }
  if (runs.empty())
    throw std::invalid_argument("--run RUN is required (see --help)");
  fs::create_directories(work);
  std::printf("ropes_stream_bench: %u hardware threads; DDS loopback profile %s, domain %d\n",
              std::thread::hardware_concurrency(), msgs::loopback_from_environment() ? "on" : "off",
              msgs::domain_from_environment());
  for (const std::string& r : runs) {
    auto estimator = ropes::crl::Estimator::load(r);
    const auto& c = estimator.config();
    const auto config =
        ropes::sim::DatasetConfig::load(ropes::eval::installed_dataset_config(c.dataset_config));
    std::printf("run %s: %s, %lld camera(s) %lldx%lld, %zu joints (dataset config %s)\n", r.c_str(),
                c.name.c_str(), static_cast<long long>(c.cameras),
                static_cast<long long>(c.image_size), static_cast<long long>(c.image_size),
                c.joints.size(), c.dataset_config.c_str());
    const Peer p = in_process(estimator, config, 300);
    std::printf(
        "  in-process peer  rendering %.2f ms + inference %.2f ms a frame, no transport: %.1f "
        "frames/s on one core\n",
        p.render_ms, p.infer_ms, 1e3 / (p.render_ms + p.infer_ms));
    report(std::to_string(static_cast<int>(rate)) + " Hz target",
           stream(r, c.dataset_config, rate, static_cast<long long>(rate * seconds), work));
    // as fast as it goes: frames the node cannot take in time are dropped (sensor QoS)
    report("as fast as it goes",
           stream(r, c.dataset_config, 1000, static_cast<long long>(200 * seconds), work));
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ropes::sim::tune_malloc_for_rendering();
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ropes_stream_bench: %s\n", e.what());
    return 1;
  }
}
