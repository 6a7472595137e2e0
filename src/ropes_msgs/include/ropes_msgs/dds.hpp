#pragma once
/// @file dds.hpp
/// A small typed layer over Fast DDS 2.9 for the ROPES topics: a Participant (RAII over a
/// DomainParticipant and its publisher and subscriber), Publisher<T> and Subscriber<T> (RAII
/// over a topic's DataWriter or DataReader), the two QoS presets, the topic names and the
/// domain from the environment. The message types are those generated from idl/*.idl.
///
/// Environment:
///   ROPES_DDS_DOMAIN    the DDS domain id, 0..232 (default 0)
///   ROPES_DDS_LOOPBACK  1: participants use only shared memory and UDP on 127.0.0.1, with
///                       discovery by unicast to 127.0.0.1 (the profile of the tests); 0 or
///                       unset: Fast DDS's default transports (multicast discovery, every
///                       interface, shared memory)
///   ROPES_DDS_SHM       0: no shared-memory transport (UDP only; for a peer that may be
///                       killed with SIGKILL, see the README); 1 or unset: shared memory too
///
/// Lifetimes: a Participant outlives the Publishers and Subscribers made on it. Every entity
/// is deleted by its destructor, so a process that returns from main (after SIGINT or SIGTERM,
/// see ShutdownSignals) leaves no shared-memory segment behind in /dev/shm.
#include <fastcdr/exceptions/Exception.h>
#include <ropes_msgs/ImageFramePubSubTypes.h>
#include <ropes_msgs/JointStatePubSubTypes.h>
#include <ropes_msgs/PoseEstimatePubSubTypes.h>
#include <ropes_msgs/RunStatusPubSubTypes.h>

#include <fastdds/dds/topic/TypeSupport.hpp>

#include <chrono>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>

namespace eprosima::fastdds::dds {
class DomainParticipant;
class DataWriter;
class DataReader;
}  // namespace eprosima::fastdds::dds

namespace ropes::msgs {

/// A DDS entity could not be made, or an environment variable is malformed; the message
/// names which.
class DdsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// reliable_all: reliable, keep all, volatile: nothing is lost or duplicated while a reader is
/// matched (a writer blocks when the reader falls behind). sensor: best effort, keep last 4:
/// a slow reader sees the newest samples and the writer never waits.
enum class Qos { reliable_all, sensor };
const char* qos_name(Qos qos);
/// "reliable_all" or "sensor" -> the preset; std::invalid_argument naming `text` otherwise.
Qos qos_from_name(const std::string& text);

/// The topics of the workspace and the QoS each is published with (the README's table).
inline constexpr const char* kImageFrameTopic = "ropes/image_frames";      // sensor
inline constexpr const char* kJointStateTopic = "ropes/joint_states";      // reliable_all
inline constexpr const char* kPoseEstimateTopic = "ropes/pose_estimates";  // reliable_all
inline constexpr const char* kRunStatusTopic = "ropes/run_status";         // reliable_all

/// Per message type: its generated type support, default topic and QoS.
template <class T>
struct MessageType;
template <>
struct MessageType<ImageFrame> {
  using PubSub = ImageFramePubSubType;
  static constexpr const char* topic = kImageFrameTopic;
  static constexpr Qos qos = Qos::sensor;
};
template <>
struct MessageType<JointState> {
  using PubSub = JointStatePubSubType;
  static constexpr const char* topic = kJointStateTopic;
  static constexpr Qos qos = Qos::reliable_all;
};
template <>
struct MessageType<PoseEstimate> {
  using PubSub = PoseEstimatePubSubType;
  static constexpr const char* topic = kPoseEstimateTopic;
  static constexpr Qos qos = Qos::reliable_all;
};
template <>
struct MessageType<RunStatus> {
  using PubSub = RunStatusPubSubType;
  static constexpr const char* topic = kRunStatusTopic;
  static constexpr Qos qos = Qos::reliable_all;
};

/// ROPES_DDS_DOMAIN (default 0). Throws DdsError naming the variable and its value unless it
/// is an integer in [0, 232].
int domain_from_environment();
/// ROPES_DDS_LOOPBACK: true for "1", false for "0" or unset; DdsError for anything else.
bool loopback_from_environment();
/// ROPES_DDS_SHM: false for "0", true for "1" or unset; DdsError for anything else.
bool shm_from_environment();

struct ParticipantOptions {
  std::string name = "ropes";
  int domain = -1;    ///< < 0: domain_from_environment()
  int loopback = -1;  ///< < 0: loopback_from_environment(); 0 or 1 otherwise
  int shm = -1;       ///< < 0: shm_from_environment(); 0 or 1 otherwise
};

class Participant {
 public:
  /// Throws DdsError (naming the domain) when Fast DDS cannot make the participant.
  explicit Participant(const ParticipantOptions& options = {});
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  int domain() const { return domain_; }
  bool loopback() const { return loopback_; }
  bool shm() const { return shm_; }
  eprosima::fastdds::dds::DomainParticipant& native() { return *participant_; }

 private:
  friend class Endpoint;
  int domain_;
  bool loopback_, shm_;
  eprosima::fastdds::dds::DomainParticipant* participant_ = nullptr;
};

/// What Publisher and Subscriber share: the topic (made, or found when the participant has
/// it), the type's registration and the matched-peer count. Not used directly.
class Endpoint {
 public:
  Endpoint(const Endpoint&) = delete;
  Endpoint& operator=(const Endpoint&) = delete;
  const std::string& topic() const { return topic_; }
  Qos qos() const { return qos_; }
  /// Peers (readers for a publisher, writers for a subscriber) matched now.
  int matched() const;
  /// Waits until at least `count` peers are matched; false on timeout.
  bool wait_for_matched(int count, std::chrono::milliseconds timeout) const;
  /// A publisher: waits until every matched reader acknowledged every sample (reliable_all);
  /// false on timeout. A subscriber: returns true.
  bool wait_for_acknowledgments(std::chrono::milliseconds timeout);

 protected:
  Endpoint(Participant& participant, const std::string& topic, Qos qos,
           eprosima::fastdds::dds::TypeSupport type, bool writer);
  ~Endpoint();
  bool write_sample(void* sample, std::chrono::milliseconds timeout);
  bool take_sample(void* sample, std::chrono::milliseconds timeout);

 private:
  Participant& participant_;
  std::string topic_;
  Qos qos_;
  eprosima::fastdds::dds::DataWriter* writer_ = nullptr;
  eprosima::fastdds::dds::DataReader* reader_ = nullptr;
};

namespace detail {
/// The type support every Publisher and Subscriber registers: the generated one, except that
/// a sample that does not deserialize is dropped (false) whatever Fast CDR throws. The
/// generated deserialize() turns only a short buffer into false; a bad encapsulation
/// (BadParamException) escaped from DataReader::take_next_sample into the node, so a peer
/// could stop ropes-stream with one malformed sample (found by ropes_crl's fuzz/image_frame).
template <class PubSub>
class CheckedPubSub : public PubSub {
 public:
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override {
    try {
      return PubSub::deserialize(payload, data);
    } catch (const eprosima::fastcdr::exception::Exception&) {
      return false;
    }
  }
};
}  // namespace detail

template <class T>
class Publisher : public Endpoint {
 public:
  explicit Publisher(Participant& participant, const std::string& topic = MessageType<T>::topic,
                     Qos qos = MessageType<T>::qos)
      : Endpoint(participant, topic, qos,
                 eprosima::fastdds::dds::TypeSupport(
                     new detail::CheckedPubSub<typename MessageType<T>::PubSub>()),
                 true) {}
  /// Publishes one sample. Under reliable_all it waits while a matched reader's history is
  /// full, up to `timeout`; false when it timed out (nothing was sent), true otherwise (also
  /// with no reader matched).
  bool write(const T& message, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    return write_sample(const_cast<T*>(&message), timeout);
  }
};

template <class T>
class Subscriber : public Endpoint {
 public:
  explicit Subscriber(Participant& participant, const std::string& topic = MessageType<T>::topic,
                      Qos qos = MessageType<T>::qos)
      : Endpoint(participant, topic, qos,
                 eprosima::fastdds::dds::TypeSupport(
                     new detail::CheckedPubSub<typename MessageType<T>::PubSub>()),
                 false) {}
  /// The next sample in order of arrival, waiting up to `timeout`; false when none came.
  bool take(T& message, std::chrono::milliseconds timeout) {
    return take_sample(&message, timeout);
  }
};

/// Turns SIGINT and SIGTERM into a flag (for the lifetime of the object; one at a time), so
/// that a node's loop ends and its destructors delete the DDS entities. A second signal while
/// the first is handled ends the process at once.
class ShutdownSignals {
 public:
  ShutdownSignals();
  ~ShutdownSignals();
  ShutdownSignals(const ShutdownSignals&) = delete;
  ShutdownSignals& operator=(const ShutdownSignals&) = delete;
  /// True once a signal came; its number in signal().
  bool requested() const;
  int signal() const;
  /// Sleeps up to `duration`, returning early (true) when a signal comes.
  bool sleep_for(std::chrono::nanoseconds duration) const;
};

/// Nanoseconds since the Unix epoch (system clock): the stamps of every message.
std::int64_t now_ns();

}  // namespace ropes::msgs
