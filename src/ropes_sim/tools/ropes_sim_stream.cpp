// ropes-sim-stream: the simulated Panda follows a minimum-jerk trajectory and each instant
// is rendered by every camera of a rig and published: ImageFrame and ground-truth JointState.
#include <ropes_msgs/dds.hpp>

#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "ropes_sim/dataset_config.hpp"
#include "ropes_sim/renderer.hpp"
#include "ropes_sim/rig_renderer.hpp"
#include "ropes_sim/trajectory.hpp"
#include "tool_common.hpp"

namespace {

using namespace ropes::sim::tools;
namespace msgs = ropes::msgs;
using Clock = std::chrono::steady_clock;

const char* const kUsage = R"(usage: ropes-sim-stream --config C [options]

Moves the arm of dataset config C (a file, or an installed name such as small-1c or
small-2c) along minimum-jerk segments between observational configurations of its
distribution, renders every camera of its rig in real time and publishes, per instant, an
ImageFrame on ropes/image_frames and the true angles as a JointState on ropes/joint_states
(same stamp and sequence number). Runs until SIGINT or SIGTERM, or --frames.

options:
  --rate HZ                frames a second (default 30); a frame that is late is sent at
                           once and counted, never skipped
  --segment S              seconds from one target configuration to the next (default 2)
  --seed N                 the trajectory's seed (default 0)
  --frames N               stop after N frames
  --frame-qos Q            sensor (default: best effort, keep last) or reliable_all (no
                           frame lost; a slow reader slows the stream)
  --split-cameras          one ImageFrame per camera (same sequence number), not one for all
  --wait-for-subscribers N wait until N readers of ropes/image_frames are matched first
The domain is ROPES_DDS_DOMAIN (default 0); ROPES_DDS_LOOPBACK=1 keeps to this host.
)";

int run(int argc, char** argv) {
  std::string config_arg;
  double rate = 30, segment = 2;
  std::uint64_t seed = 0;
  long long frames = -1;
  int wait_for = 0;
  bool split = false;
  msgs::Qos frame_qos = msgs::Qos::sensor;
  ropes::core::CommandLine command_line(kUsage);
  command_line.flag("--split-cameras", [&] { split = true; })
      .option("--config", [&](const std::string& v) { config_arg = v; })
      .option("--rate",
              [&](const std::string& v) { rate = parse_number<double>("--rate", v, 0.01, 10000); })
      .option(
          "--segment",
          [&](const std::string& v) { segment = parse_number<double>("--segment", v, 0.01, 3600); })
      .option("--seed",
              [&](const std::string& v) {
                seed = parse_number<std::uint64_t>("--seed", v, 0, UINT64_MAX);
              })
      .option("--frames",
              [&](const std::string& v) {
                frames = parse_number<long long>("--frames", v, 1, 1LL << 40);
              })
      .option("--wait-for-subscribers",
              [&](const std::string& v) {
                wait_for = parse_number<int>("--wait-for-subscribers", v, 0, 1000);
              })
      .option("--frame-qos", [&](const std::string& v) {
        frame_qos = ropes::core::for_flag("--frame-qos", [&] { return msgs::qos_from_name(v); });
      });
  if (!command_line.parse(argc, argv))
    return 0;
  if (config_arg.empty())
    throw UsageError("--config is required (see --help)");
  const auto config = ropes::sim::DatasetConfig::load(find_config(config_arg));
  ropes::sim::RigRenderer rig(config);
  ropes::sim::Trajectory trajectory(rig.sampler(), seed, segment, rate);

  msgs::ShutdownSignals signals;
  msgs::Participant participant({"ropes-sim-stream"});
  msgs::Publisher<msgs::ImageFrame> frame_pub(participant, msgs::kImageFrameTopic, frame_qos);
  msgs::Publisher<msgs::JointState> joint_pub(participant);
  std::fprintf(stderr,
               "ropes-sim-stream: %s, %d camera(s) %dx%d at %g Hz on domain %d (frames %s)\n",
               config.name.c_str(), rig.cameras(), rig.width(), rig.height(), rate,
               participant.domain(), msgs::qos_name(frame_qos));
  if (wait_for > 0) {
    std::fprintf(stderr, "ropes-sim-stream: waiting for %d subscriber(s)\n", wait_for);
    while (!signals.requested() &&
           !frame_pub.wait_for_matched(wait_for, std::chrono::milliseconds(100))) {
    }
  }

  const std::vector<std::string> cameras = rig.camera_names();
  std::vector<std::uint8_t> pixels(rig.frame_bytes());
  msgs::ImageFrame frame;
  frame.width(static_cast<std::uint16_t>(rig.width()));
  frame.height(static_cast<std::uint16_t>(rig.height()));
  frame.encoding("mono8");
  msgs::JointState joints;
  joints.names(rig.joint_names());
  const std::size_t image = pixels.size() / cameras.size();
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1 / rate));
  const Clock::time_point start = Clock::now();
  long long sent = 0, late = 0;
  double render_s = 0;
  while (!signals.requested() && (frames < 0 || sent < frames)) {
    const Clock::time_point due = start + period * sent;
    if (Clock::now() > due + period)
      ++late;
    else if (signals.sleep_for(due - Clock::now()))
      break;
    const ropes::sim::Trajectory::Point point = trajectory.next();
    const Clock::time_point r0 = Clock::now();
    rig.render(point.q, pixels.data());
    render_s += std::chrono::duration<double>(Clock::now() - r0).count();
    const std::int64_t stamp = msgs::now_ns();
    const auto n = static_cast<unsigned long long>(sent);
    joints.stamp_ns(stamp);
    joints.sequence_number(n);
    joints.positions(point.q);
    frame.stamp_ns(stamp);
    frame.sequence_number(n);
    bool ok = true;
    if (split) {
      for (std::size_t c = 0; c < cameras.size(); ++c) {
        frame.camera_names({cameras[c]});
        frame.camera_ids({static_cast<std::uint16_t>(c)});
        frame.pixels(
            std::vector<std::uint8_t>(pixels.begin() + static_cast<long>(c * image),
                                      pixels.begin() + static_cast<long>((c + 1) * image)));
        ok = frame_pub.write(frame) && ok;
      }
    } else {
      frame.camera_names(cameras);
      std::vector<std::uint16_t> ids;
      for (std::size_t c = 0; c < cameras.size(); ++c)
        ids.push_back(static_cast<std::uint16_t>(c));
      frame.camera_ids(ids);
      frame.pixels(pixels);
      ok = frame_pub.write(frame);
    }
    ok = joint_pub.write(joints) && ok;
    if (!ok)
      std::fprintf(stderr, "ropes-sim-stream: frame %llu: a write timed out (a reader stuck?)\n",
                   n);
    ++sent;
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  // let reliable readers have what was written before the entities go
  frame_pub.wait_for_acknowledgments(std::chrono::seconds(2));
  joint_pub.wait_for_acknowledgments(std::chrono::seconds(2));
  std::fprintf(stderr,
               "ropes-sim-stream: %lld frames in %.1f s (%.1f/s), %lld late, rendering %.2f ms a "
               "frame%s\n",
               sent, seconds, seconds > 0 ? static_cast<double>(sent) / seconds : 0.0, late,
               sent > 0 ? 1e3 * render_s / static_cast<double>(sent) : 0.0,
               signals.requested() ? " (stopped by a signal)" : "");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ropes::sim::tune_malloc_for_rendering();
  return ropes::core::run_main("ropes-sim-stream", run, argc, argv);
}
