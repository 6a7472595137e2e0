// ropes_sim_bench: rendering and kinematics throughput (a benchmark, not a test; see the
// package README for one run's figures and the machine).
//   images/s at 128x128 for the primitive Panda and the Panda-Gym mesh asset, 1 and 2 threads
//   FK evaluations/s: Simbody (all link poses) beside a modified-DH chain (the peer)
//   ropes-generate end to end (sample, FK, render, .npy shards, SHA-256) for the 2C config
// usage: ropes_sim_bench [--quick]

#include <Eigen/Geometry>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "../test/panda_dh.hpp"
#include "ropes_sim/dataset_generator.hpp"
#include "ropes_sim/intervention_sampler.hpp"
#include "ropes_sim/kinematics.hpp"
#include "ropes_sim/renderer.hpp"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using ropes::sim::CameraRig;
using ropes::sim::Kinematics;
using ropes::sim::Renderer;
using ropes::sim::RobotModel;
using ropes::sim::Scene;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// the poses ropes-generate renders: the 1C distribution's anchors, every regime, with the
// robot's other coordinates (the Panda-Gym fingers) at 0
std::vector<std::vector<double>> configurations(int n, std::size_t coordinates) {
  const auto sampler = ropes::sim::InterventionSampler::load(
      fs::path(ROPES_SIM_DATASETS_DIR) / "../distributions/1c_independent.json");
  std::vector<std::vector<double>> out;
  for (std::uint64_t anchor = 0; static_cast<int>(out.size()) < n; ++anchor) {
    for (auto q : sampler.sample_anchor(1, anchor)) {
      q.resize(coordinates, 0.0);
      if (static_cast<int>(out.size()) < n)
        out.push_back(q);
    }
  }
  return out;
}

// images/s with `threads` renderers side by side, each on its own thread
double render_rate(const fs::path& urdf, int threads, int images_per_thread) {
  const RobotModel model = RobotModel::load(urdf);
  const auto scene = Scene::build(model);
  const auto camera = CameraRig::single_camera().cameras[0];
  const auto qs = configurations(images_per_thread, model.movable_joints().size());
  std::atomic<int> ready{0};
  std::atomic<bool> go{false};
  std::vector<double> elapsed(static_cast<std::size_t>(threads));
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back([&, t] {
      Kinematics kinematics(model);
      Renderer renderer(scene, 128, 128);
      std::vector<std::uint8_t> image(128 * 128);
      // warm up: llvmpipe compiles its shaders and sizes its buffers on the first frames
      for (std::size_t i = 0; i < std::min<std::size_t>(qs.size(), 20); ++i) {
        kinematics.set_positions(qs[i]);
        renderer.render(kinematics.link_poses(), camera, image.data());
      }
      ++ready;
      while (!go)
        std::this_thread::yield();
      const auto start = Clock::now();
      for (const auto& q : qs) {
        kinematics.set_positions(q);
        renderer.render(kinematics.link_poses(), camera, image.data());
      }
      elapsed[static_cast<std::size_t>(t)] = seconds_since(start);
    });
  }
  while (ready < threads)
    std::this_thread::yield();
  go = true;
  for (auto& th : pool)
    th.join();
  double slowest = 0;
  for (double e : elapsed)
    slowest = std::max(slowest, e);
  return threads * images_per_thread / slowest;
}

// the peer of Simbody's FK: the Panda's modified-DH chain (Craig), 8 frames, the tests' witness
double dh_chain(const std::vector<double>& q) {
  double sink = 0;
  for (const auto& X : ropes::sim::witness::dh_frames(q))
    sink += X.translation().x();
  return sink;
}

}  // namespace

int main(int argc, char** argv) {
  ropes::sim::tune_malloc_for_rendering();  // as ropes-generate does
  const bool quick = argc > 1 && std::string(argv[1]) == "--quick";
  const fs::path ours = fs::path(ROPES_SIM_URDF_DIR) / "panda.urdf";
  const fs::path gym = fs::path(ROPES_SHARED_ASSETS) / "franka_panda" / "panda.urdf";
  const unsigned cores = std::thread::hardware_concurrency();
  std::printf("ropes_sim_bench: %u hardware threads; %s\n", cores,
              Renderer(Scene::build(RobotModel::load(ours)), 8, 8).gl_description().c_str());

  // kinematics
  {
    const RobotModel model = RobotModel::load(ours);
    Kinematics kinematics(model);
    const int n = quick ? 20000 : 200000;
    const auto qs = configurations(1000, 7);
    auto start = Clock::now();
    double sink = 0;
    for (int i = 0; i < n; ++i) {
      kinematics.set_positions(qs[static_cast<std::size_t>(i % 1000)]);
      for (const auto& X : kinematics.link_poses())
        sink += X.translation().x();
    }
    const double simbody = n / seconds_since(start);
    start = Clock::now();
    for (int i = 0; i < n; ++i)
      sink += dh_chain(qs[static_cast<std::size_t>(i % 1000)]);
    const double dh = n / seconds_since(start);
    std::printf(
        "FK evaluations/s (all %zu link poses): Simbody %.0f | modified-DH chain %.0f "
        "(peer)  [%g]\n",
        model.links().size(), simbody, dh, sink > 0 ? 0.0 : 1.0);
  }

  // rendering
  const int per_thread = quick ? 100 : 1000;
  for (const auto& [name, urdf, count] :
       {std::tuple<const char*, fs::path, int>{"primitive Panda (ours)", ours, per_thread},
        std::tuple<const char*, fs::path, int>{"Panda-Gym mesh asset", gym, per_thread / 10}}) {
    if (!fs::exists(urdf)) {
      std::printf("images/s 128x128, %s: skipped, %s is not there\n", name, urdf.c_str());
      continue;
    }
    const double one = render_rate(urdf, 1, count);
    const double two = render_rate(urdf, 2, count);
    std::printf("images/s 128x128, %-24s 1 thread %7.0f | 2 threads %7.0f\n", name, one, two);
  }

  // end to end: ropes-generate's work on the 2C config, into a temporary directory
  const fs::path config_file = fs::path(ROPES_SIM_DATASETS_DIR) / "2c.json";
  auto config = ropes::sim::DatasetConfig::load(config_file);
  config.anchors = quick ? 32 : 256;
  config.anchors_per_shard = 64;
  for (int threads : {1, 2}) {
    const fs::path out = fs::temp_directory_path() / ("ropes_sim_bench_" + std::to_string(threads));
    fs::remove_all(out);
    ropes::sim::GenerateOptions options;
    options.out = out;
    options.seed = 0;
    options.threads = threads;
    const auto start = Clock::now();
    const auto result = ropes::sim::generate_dataset(config, options);
    const double rate = result.images / seconds_since(start);
    fs::remove_all(out);
    std::printf(
        "ropes-generate 2C end to end, %d thread(s): %.0f images/s -> the paper's 260,000 "
        "images in %.1f min (target: < 10 min, >= 450 images/s)\n",
        threads, rate, 260000.0 / rate / 60.0);
  }
  return 0;
}
