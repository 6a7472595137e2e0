// ropes_msgs_peer: the other process of the DDS tests (not installed).
//   publish N             waits for a subscriber, publishes PoseEstimates 0..N-1 under
//                         reliable_all, waits for their acknowledgement, exits 0
//   subscribe N           takes N PoseEstimates, exits 0 when they are 0..N-1 in order
//   subscribe-any N       takes N consecutive PoseEstimates starting anywhere (a late
//                         joiner), exits 0; also exits 0 on SIGINT or SIGTERM
//   publish-until-signal  publishes a PoseEstimate every 10 ms until SIGINT or SIGTERM
#include <ropes_msgs/dds.hpp>

#include <cstdio>
#include <string>

using namespace ropes::msgs;

int main(int argc, char** argv) {
  try {
    const std::string mode = argc > 1 ? argv[1] : "";
    const long long n = argc > 2 ? std::stoll(argv[2]) : 0;
    ShutdownSignals signals;
    Participant participant({"ropes_msgs_peer"});
    if (mode == "publish" || mode == "publish-until-signal") {
      Publisher<PoseEstimate> pub(participant);
      if (mode == "publish" && !pub.wait_for_matched(1, std::chrono::seconds(30))) {
        std::fprintf(stderr, "peer: no subscriber within 30 s\n");
        return 1;
      }
      PoseEstimate m;
      m.run_id("peer");
      m.latents({0.5f, -0.25f});
      for (unsigned long long i = 0;
           mode == "publish" ? i < static_cast<unsigned long long>(n) : !signals.requested(); ++i) {
        m.sequence_number(i);
        m.stamp_ns(now_ns());
        if (!pub.write(m)) {
          std::fprintf(stderr, "peer: write %llu timed out\n", i);
          return 1;
        }
        if (mode != "publish")
          signals.sleep_for(std::chrono::milliseconds(10));
      }
      if (!pub.wait_for_acknowledgments(std::chrono::seconds(30))) {
        std::fprintf(stderr, "peer: not acknowledged within 30 s\n");
        return 1;
      }
      return 0;
    }
    if (mode == "subscribe") {
      Subscriber<PoseEstimate> sub(participant);
      PoseEstimate m;
      for (long long i = 0; i < n; ++i) {
        if (!sub.take(m, std::chrono::seconds(30))) {
          std::fprintf(stderr, "peer: sample %lld did not come within 30 s\n", i);
          return 1;
        }
        if (m.sequence_number() != static_cast<unsigned long long>(i)) {
          std::fprintf(stderr, "peer: sample %lld has sequence number %llu\n", i,
                       static_cast<unsigned long long>(m.sequence_number()));
          return 1;
        }
      }
      std::printf("received %lld in order\n", n);
      return 0;
    }
    if (mode == "subscribe-any") {
      Subscriber<PoseEstimate> sub(participant);
      PoseEstimate m;
      unsigned long long first = 0;
      for (long long i = 0; i < n && !signals.requested();) {
        if (!sub.take(m, std::chrono::milliseconds(50)))
          continue;
        if (i == 0)
          first = m.sequence_number();
        if (m.sequence_number() != first + static_cast<unsigned long long>(i)) {
          std::fprintf(stderr, "peer: sample %lld has sequence number %llu, expected %llu\n", i,
                       static_cast<unsigned long long>(m.sequence_number()),
                       first + static_cast<unsigned long long>(i));
          return 1;
        }
        ++i;
      }
      std::printf("received consecutive samples from %llu\n", first);
      return 0;
    }
    std::fprintf(stderr,
                 "usage: ropes_msgs_peer publish N | subscribe N | subscribe-any N | "
                 "publish-until-signal\n");
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "peer: %s\n", e.what());
    return 1;
  }
}
