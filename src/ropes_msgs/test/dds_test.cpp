// Two processes over the loopback profile (ROPES_DDS_LOOPBACK=1, set by CTest): no loss
// under reliable_all, and the peer lifecycle: no subscriber, a late one, a killed one, and a
// clean exit on SIGTERM.
#include <ropes_core/child_process.hpp>
#include <ropes_msgs/dds.hpp>

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <set>
#include <string>
#include <thread>
#include <vector>

namespace {

using namespace ropes::msgs;
using namespace std::chrono_literals;

// the test peer (ROPES_MSGS_PEER, set by CMake) with `args`, in a child process, its output
// captured; `env`: "NAME=value" entries over this process's environment
class Peer : public ropes::core::ChildProcess {
 public:
  explicit Peer(std::vector<std::string> args, std::vector<std::string> env = {})
      : ChildProcess(with_peer(std::move(args)), options(std::move(env))) {}

 private:
  static std::vector<std::string> with_peer(std::vector<std::string> args) {
    args.insert(args.begin(), ROPES_MSGS_PEER);
    return args;
  }
  static ropes::core::ChildOptions options(std::vector<std::string> env) {
    ropes::core::ChildOptions o;
    o.environment = std::move(env);
    return o;
  }
};

std::set<std::string> shm_entries() {
  std::set<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator("/dev/shm"))
    out.insert(e.path().filename().string());
  return out;
}

TEST(RopesDds, TenThousandEstimatesUnderReliableAllArriveOnceAndInOrder) {
  Participant participant({"test-subscriber"});
  Subscriber<PoseEstimate> sub(participant);
  Peer publisher({"publish", "10000"});
  PoseEstimate m;
  for (unsigned long long i = 0; i < 10000; ++i) {
    ASSERT_TRUE(sub.take(m, 30s)) << "sample " << i << " never came";
    ASSERT_EQ(m.sequence_number(), i) << "lost, duplicated or out of order";
    ASSERT_EQ(m.run_id(), "peer");
  }
  EXPECT_EQ(publisher.wait(30s), 0);
  EXPECT_FALSE(sub.take(m, 500ms)) << "a sample after the last: " << m.sequence_number();
}

TEST(RopesDds, PublisherWithoutSubscriberDoesNotBlock) {
  Participant participant({"test-lonely-publisher"});
  Publisher<PoseEstimate> pub(participant, "ropes/test_nobody_listens");
  PoseEstimate m;
  // twice the writer's history: a writer that kept samples for nobody would block here
  for (unsigned long long i = 0; i < 2000; ++i) {
    m.sequence_number(i);
    ASSERT_TRUE(pub.write(m, 1000ms)) << "write " << i << " blocked";
  }
  EXPECT_EQ(pub.matched(), 0);
}

TEST(RopesDds, LateSubscriberGetsTheStreamFromWhenItJoins) {
  Peer publisher({"publish-until-signal"});
  std::this_thread::sleep_for(1500ms);  // the publisher writes for nobody meanwhile
  Participant participant({"test-late-subscriber"});
  Subscriber<PoseEstimate> sub(participant);
  PoseEstimate m;
  ASSERT_TRUE(sub.take(m, 20s));
  const unsigned long long first = m.sequence_number();
  EXPECT_GT(first, 0u) << "a volatile reader should not get what was written before it joined";
  for (unsigned long long i = 1; i < 20; ++i) {
    ASSERT_TRUE(sub.take(m, 5s));
    EXPECT_EQ(m.sequence_number(), first + i);
  }
  publisher.signal(SIGTERM);
  EXPECT_EQ(publisher.wait(20s), 0) << "the publisher did not shut down cleanly on SIGTERM";
}

TEST(RopesDds, SubscriberKilledAndRestartedGetsTheStreamAgain) {
  Participant participant({"test-publisher"});
  Publisher<PoseEstimate> pub(participant);
  std::atomic<bool> stop{false};
  std::atomic<int> failed_writes{0};
  std::atomic<unsigned long long> written{0};
  std::thread writer([&] {
    PoseEstimate m;
    for (unsigned long long i = 0; !stop; ++i) {
      m.sequence_number(i);
      if (!pub.write(m, 2000ms))
        ++failed_writes;
      written = i + 1;
      std::this_thread::sleep_for(5ms);
    }
  });
  {
    // UDP only: a process killed with SIGKILL while it touches a Fast DDS 2.9 shared-memory
    // port can leave the port's lock taken for good (the README's note on SIGKILL)
    Peer first({"subscribe-any", "100000000"}, {"ROPES_DDS_SHM=0"});
    ASSERT_TRUE(pub.wait_for_matched(1, 20s));
    std::this_thread::sleep_for(300ms);
    first.signal(SIGKILL);
    first.wait(5s);
  }
  Peer second({"subscribe-any", "100"});
  EXPECT_EQ(second.wait(60s), 0) << "the restarted subscriber did not get 100 consecutive samples";
  const unsigned long long before = written;
  std::this_thread::sleep_for(200ms);
  stop = true;
  writer.join();
  EXPECT_GT(written.load(), before) << "the publisher stopped";
  EXPECT_EQ(failed_writes.load(), 0) << "writes blocked on the killed subscriber";
}

TEST(RopesDds, SigtermLeavesNoSharedMemorySegments) {
  const std::set<std::string> before = shm_entries();
  {
    Peer publisher({"publish-until-signal"});
    Peer subscriber({"subscribe-any", "100000000"});
    std::this_thread::sleep_for(2500ms);  // discovery, then samples over shared memory
    subscriber.signal(SIGTERM);
    publisher.signal(SIGINT);
    EXPECT_EQ(subscriber.wait(20s), 0);
    EXPECT_EQ(publisher.wait(20s), 0);
  }
  std::vector<std::string> left;
  for (const std::string& e : shm_entries())
    if (before.count(e) == 0)
      left.push_back(e);
  EXPECT_TRUE(left.empty()) << left.size() << " new entries in /dev/shm, the first " << left[0];
}

TEST(RopesDds, EnvironmentIsCheckedWithAClearMessage) {
  ::setenv("ROPES_DDS_DOMAIN", "abc", 1);
  try {
    domain_from_environment();
    ADD_FAILURE() << "no error for ROPES_DDS_DOMAIN=abc";
  } catch (const DdsError& e) {
    EXPECT_NE(std::string(e.what()).find("ROPES_DDS_DOMAIN is 'abc'"), std::string::npos);
  }
  ::setenv("ROPES_DDS_DOMAIN", "233", 1);
  EXPECT_THROW(domain_from_environment(), DdsError);
  ::setenv("ROPES_DDS_DOMAIN", "17", 1);
  EXPECT_EQ(domain_from_environment(), 17);
  ::setenv("ROPES_DDS_LOOPBACK", "yes", 1);
  EXPECT_THROW(loopback_from_environment(), DdsError);
  ::setenv("ROPES_DDS_LOOPBACK", "1", 1);
  EXPECT_TRUE(loopback_from_environment());
  ::setenv("ROPES_DDS_SHM", "no", 1);
  EXPECT_THROW(shm_from_environment(), DdsError);
  ::setenv("ROPES_DDS_SHM", "0", 1);
  EXPECT_FALSE(shm_from_environment());
  EXPECT_EQ(qos_from_name("sensor"), Qos::sensor);
  EXPECT_EQ(qos_from_name(qos_name(Qos::reliable_all)), Qos::reliable_all);
  EXPECT_THROW(qos_from_name("reliable"), std::invalid_argument);
}

}  // namespace
