// ropes-echo: prints the samples of one ROPES topic, human-readable or as JSON lines.
#include <ropes_core/cli.hpp>
#include <ropes_msgs/dds.hpp>

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <limits>
#include <string>

namespace {

using namespace ropes::msgs;

const char* const kUsage = R"(usage: ropes-echo TOPIC [options]

Subscribes to one topic of the ROPES workspace and prints every sample, one line each.
TOPIC is one of
  image_frames     ImageFrame   (ropes/image_frames, sensor QoS)
  joint_states     JointState   (ropes/joint_states, reliable_all)
  pose_estimates   PoseEstimate (ropes/pose_estimates, reliable_all)
  run_status       RunStatus    (ropes/run_status, reliable_all)

options:
  --json           one JSON object a line (pixels as their count and mean, not the bytes)
  --count N        exit after N samples (default: until SIGINT or SIGTERM)
  --timeout S      exit with status 3 when no sample came for S seconds (default: never)
  --name NAME      the DDS topic name, when it is not the default above
The domain is ROPES_DDS_DOMAIN (default 0); ROPES_DDS_LOOPBACK=1 keeps to this host.
)";

using ropes::core::UsageError;

template <class T>
nlohmann::json list(const T& values) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& v : values)
    j.push_back(v);
  return j;
}

nlohmann::json to_json(const ImageFrame& m) {
  double sum = 0;
  for (const auto p : m.pixels())
    sum += p;
  return {{"stamp_ns", m.stamp_ns()},
          {"sequence_number", m.sequence_number()},
          {"camera_names", list(m.camera_names())},
          {"camera_ids", list(m.camera_ids())},
          {"width", m.width()},
          {"height", m.height()},
          {"encoding", m.encoding()},
          {"pixels", m.pixels().size()},
          {"pixel_mean", m.pixels().empty() ? 0.0 : sum / static_cast<double>(m.pixels().size())}};
}

nlohmann::json to_json(const JointState& m) {
  return {{"stamp_ns", m.stamp_ns()},
          {"sequence_number", m.sequence_number()},
          {"names", list(m.names())},
          {"positions", list(m.positions())}};
}

nlohmann::json to_json(const PoseEstimate& m) {
  nlohmann::json valid = nlohmann::json::array();
  for (const bool v : m.valid())
    valid.push_back(v);
  return {{"stamp_ns", m.stamp_ns()},
          {"sequence_number", m.sequence_number()},
          {"frame_sequence_number", m.frame_sequence_number()},
          {"frame_stamp_ns", m.frame_stamp_ns()},
          {"run_id", m.run_id()},
          {"latents", list(m.latents())},
          {"joint_names", list(m.joint_names())},
          {"joint_angles", list(m.joint_angles())},
          {"valid", valid},
          {"latency_ns", m.latency_ns()},
          {"rejected_frames", m.rejected_frames()}};
}

nlohmann::json to_json(const RunStatus& m) {
  return {{"stamp_ns", m.stamp_ns()},
          {"run_id", m.run_id()},
          {"stage", m.stage()},
          {"step", m.step()},
          {"total_steps", m.total_steps()},
          {"loss_names", list(m.loss_names())},
          {"loss_values", list(m.loss_values())},
          {"eta_s", m.eta_s()}};
}

std::string numbers(const nlohmann::json& values, int precision) {
  std::string out;
  char buf[32];
  for (const auto& v : values) {
    std::snprintf(buf, sizeof buf, "%s%.*f", out.empty() ? "" : " ", precision, v.get<double>());
    out += buf;
  }
  return "[" + out + "]";
}

std::string text(const ImageFrame& m) {
  const nlohmann::json j = to_json(m);
  std::string cams;
  for (const auto& c : m.camera_names())
    cams += (cams.empty() ? "" : ",") + c;
  char buf[256];
  std::snprintf(buf, sizeof buf, "frame %llu  t=%lld  %zu camera(s) %s  %ux%u %s  mean %.1f",
                static_cast<unsigned long long>(m.sequence_number()),
                static_cast<long long>(m.stamp_ns()), m.camera_names().size(), cams.c_str(),
                m.width(), m.height(), m.encoding().c_str(), j["pixel_mean"].get<double>());
  return buf;
}

std::string text(const JointState& m) {
  return "joints " + std::to_string(m.sequence_number()) + "  t=" + std::to_string(m.stamp_ns()) +
         "  " + numbers(list(m.positions()), 3);
}

std::string text(const PoseEstimate& m) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "estimate %llu  frame %llu  latency %.1f ms  rejected %llu  ",
                static_cast<unsigned long long>(m.sequence_number()),
                static_cast<unsigned long long>(m.frame_sequence_number()),
                static_cast<double>(m.latency_ns()) / 1e6,
                static_cast<unsigned long long>(m.rejected_frames()));
  return buf + m.run_id() + "  latents " + numbers(list(m.latents()), 3) + "  angles " +
         numbers(list(m.joint_angles()), 3);
}

std::string text(const RunStatus& m) {
  std::string losses;
  char buf[64];
  for (std::size_t i = 0; i < m.loss_names().size() && i < m.loss_values().size(); ++i) {
    std::snprintf(buf, sizeof buf, "  %s %.4g", m.loss_names()[i].c_str(), m.loss_values()[i]);
    losses += buf;
  }
  std::snprintf(buf, sizeof buf, "  eta %.0f s", m.eta_s());
  return m.run_id() + "  " + m.stage() + " " + std::to_string(m.step()) + "/" +
         std::to_string(m.total_steps()) + losses + (m.eta_s() >= 0 ? buf : "");
}

template <class T>
int echo(const std::string& name, bool json, long long count, double timeout_s) {
  ShutdownSignals signals;
  Participant participant({"ropes-echo"});
  Subscriber<T> subscriber(participant, name.empty() ? MessageType<T>::topic : name);
  std::fprintf(stderr, "ropes-echo: %s on domain %d (%s)\n", subscriber.topic().c_str(),
               participant.domain(), qos_name(subscriber.qos()));
  T message;
  long long seen = 0;
  auto last = std::chrono::steady_clock::now();
  while (!signals.requested() && (count < 0 || seen < count)) {
    if (!subscriber.take(message, std::chrono::milliseconds(100))) {
      if (timeout_s > 0 &&
          std::chrono::steady_clock::now() - last > std::chrono::duration<double>(timeout_s)) {
        std::fprintf(stderr, "ropes-echo: no sample for %g s\n", timeout_s);
        return 3;
      }
      continue;
    }
    last = std::chrono::steady_clock::now();
    ++seen;
    const std::string line = json ? to_json(message).dump() : text(message);
    std::fwrite(line.data(), 1, line.size(), stdout);
    std::fputc('\n', stdout);
    std::fflush(stdout);
  }
  return 0;
}

int run(int argc, char** argv) {
  std::string topic, name;
  bool json = false;
  long long count = -1;
  double timeout_s = 0;
  ropes::core::CommandLine command_line(kUsage);
  command_line.flag("--json", [&] { json = true; })
      .option("--count",
              [&](const std::string& v) {
                count = ropes::core::parse_number<long long>("--count", v, 1,
                                                             std::numeric_limits<long long>::max());
              })
      .option("--timeout",
              [&](const std::string& v) {
                timeout_s = ropes::core::parse_number<double>("--timeout", v);
                if (!(timeout_s > 0))
                  throw UsageError("--timeout is '" + v + "'; expected a positive number");
              })
      .option("--name", [&](const std::string& v) { name = v; })
      .positional([&](const std::string& a) {
        if (!topic.empty())
          throw UsageError("one TOPIC only (got '" + topic + "' and '" + a + "')");
        topic = a;
      });
  if (!command_line.parse(argc, argv))
    return 0;
  if (topic == "image_frames")
    return echo<ImageFrame>(name, json, count, timeout_s);
  if (topic == "joint_states")
    return echo<JointState>(name, json, count, timeout_s);
  if (topic == "pose_estimates")
    return echo<PoseEstimate>(name, json, count, timeout_s);
  if (topic == "run_status")
    return echo<RunStatus>(name, json, count, timeout_s);
  throw UsageError(topic.empty() ? "a TOPIC is required (see --help)"
                                 : "TOPIC is '" + topic +
                                       "'; expected image_frames, joint_states, pose_estimates "
                                       "or run_status");
}

}  // namespace

int main(int argc, char** argv) {
  return ropes::core::run_main("ropes-echo", run, argc, argv);
}
