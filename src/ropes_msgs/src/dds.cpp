// The Fast DDS entities behind dds.hpp: participant profiles, QoS presets, endpoints.
#include "ropes_msgs/dds.hpp"

#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>

#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdlib>
#include <thread>

// AddressSanitizer builds (ci/test --sanitize): Debian's Fast DDS 2.9 deletes its RTPS
// readers and writers through a base-class pointer with sized delete (88-byte objects freed
// as 56-byte ones, inside RTPSParticipantImpl::deleteUserEndpoint, reached from
// delete_datawriter / delete_datareader). It is in libfastrtps, not in ropes code, and it
// would fail every process that closes a DDS endpoint, so every process that links this
// file turns that one check off; everything else ASan checks stays on (ASAN_OPTIONS from
// the environment still applies on top of this default).
#if defined(__SANITIZE_ADDRESS__)
#define ROPES_MSGS_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ROPES_MSGS_ASAN 1
#endif
#endif
#if defined(ROPES_MSGS_ASAN)
extern "C" const char* __asan_default_options() {
  return "new_delete_type_mismatch=0";
}
#endif

namespace ropes::msgs {

namespace dds = eprosima::fastdds::dds;
using eprosima::fastrtps::Duration_t;

namespace {

Duration_t duration(std::chrono::nanoseconds d) {
  const auto ns = d.count() < 0 ? 0 : d.count();
  return Duration_t(static_cast<int32_t>(ns / 1000000000), static_cast<uint32_t>(ns % 1000000000));
}

std::string env(const char* name) {
  const char* v = std::getenv(name);
  return v == nullptr ? std::string() : std::string(v);
}

}  // namespace

const char* qos_name(Qos qos) {
  return qos == Qos::reliable_all ? "reliable_all" : "sensor";
}

Qos qos_from_name(const std::string& text) {
  if (text == "reliable_all")
    return Qos::reliable_all;
  if (text == "sensor")
    return Qos::sensor;
  throw std::invalid_argument("QoS '" + text + "'; expected sensor or reliable_all");
}

int domain_from_environment() {
  const std::string text = env("ROPES_DDS_DOMAIN");
  if (text.empty())
    return 0;
  std::size_t end = 0;
  int value = -1;
  try {
    value = std::stoi(text, &end);
  } catch (const std::exception&) {
    end = 0;
  }
  if (end != text.size() || value < 0 || value > 232)
    throw DdsError("ROPES_DDS_DOMAIN is '" + text + "'; expected an integer in [0, 232]");
  return value;
}

bool loopback_from_environment() {
  const std::string text = env("ROPES_DDS_LOOPBACK");
  if (text.empty() || text == "0")
    return false;
  if (text == "1")
    return true;
  throw DdsError("ROPES_DDS_LOOPBACK is '" + text + "'; expected 0 or 1");
}

bool shm_from_environment() {
  const std::string text = env("ROPES_DDS_SHM");
  if (text.empty() || text == "1")
    return true;
  if (text == "0")
    return false;
  throw DdsError("ROPES_DDS_SHM is '" + text + "'; expected 0 or 1");
}

Participant::Participant(const ParticipantOptions& options)
    : domain_(options.domain < 0 ? domain_from_environment() : options.domain),
      loopback_(options.loopback < 0 ? loopback_from_environment() : options.loopback != 0),
      shm_(options.shm < 0 ? shm_from_environment() : options.shm != 0) {
  dds::DomainParticipantQos qos = dds::PARTICIPANT_QOS_DEFAULT;
  qos.name(options.name);
  auto& builtin = qos.wire_protocol().builtin;
  // a peer killed without a goodbye is dropped after 5 s, not Fast DDS's default 20 s
  builtin.discovery_config.leaseDuration = Duration_t(5, 0);
  builtin.discovery_config.leaseDuration_announcementperiod = Duration_t(1, 0);
  if (loopback_ || !shm_) {
    qos.transport().use_builtin_transports = false;
    if (shm_)
      qos.transport().user_transports.push_back(
          std::make_shared<eprosima::fastdds::rtps::SharedMemTransportDescriptor>());
    auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
    if (loopback_) {
      udp->interfaceWhiteList.emplace_back("127.0.0.1");
      udp->maxInitialPeersRange = 32;  // participants on one host that find each other
      eprosima::fastrtps::rtps::Locator_t peer;
      peer.kind = LOCATOR_KIND_UDPv4;
      eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
      builtin.initialPeersList.push_back(peer);
    }
    qos.transport().user_transports.push_back(udp);
  }
  participant_ = dds::DomainParticipantFactory::get_instance()->create_participant(
      static_cast<dds::DomainId_t>(domain_), qos);
  if (participant_ == nullptr)
    throw DdsError("Fast DDS could not create a participant '" + options.name + "' on domain " +
                   std::to_string(domain_) + (loopback_ ? " (loopback profile)" : "") +
                   (shm_ ? "" : " (no shared memory)"));
}

Participant::~Participant() {
  participant_->delete_contained_entities();
  dds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
}

Endpoint::Endpoint(Participant& participant, const std::string& topic, Qos qos,
                   dds::TypeSupport type, bool writer)
    : participant_(participant), topic_(topic), qos_(qos) {
  dds::DomainParticipant& p = *participant.participant_;
  const std::string type_name = type.get_type_name();
  if (p.find_type(type_name).empty() && p.register_type(type) != ReturnCode_t::RETCODE_OK)
    throw DdsError("Fast DDS could not register type " + type_name);
  dds::Topic* t = dynamic_cast<dds::Topic*>(p.lookup_topicdescription(topic));
  if (t == nullptr)
    t = p.create_topic(topic, type_name, dds::TOPIC_QOS_DEFAULT);
  if (t == nullptr || t->get_type_name() != type_name)
    throw DdsError("topic '" + topic + "': cannot be made for type " + type_name +
                   (t != nullptr ? " (it has type " + t->get_type_name() + ")" : ""));
  const bool reliable = qos == Qos::reliable_all;
  if (writer) {
    dds::Publisher* pub = p.create_publisher(dds::PUBLISHER_QOS_DEFAULT);
    dds::DataWriterQos wq = dds::DATAWRITER_QOS_DEFAULT;
    wq.durability().kind = dds::VOLATILE_DURABILITY_QOS;
    if (reliable) {
      wq.reliability().kind = dds::RELIABLE_RELIABILITY_QOS;
      wq.reliability().max_blocking_time = Duration_t(0, 100000000);
      wq.history().kind = dds::KEEP_ALL_HISTORY_QOS;
      wq.resource_limits().max_samples = 1000;
      wq.resource_limits().allocated_samples = 64;
      // quick acknowledgement, so that a KEEP_ALL history drains fast
      wq.reliable_writer_qos().times.heartbeatPeriod = Duration_t(0, 20000000);
    } else {
      wq.reliability().kind = dds::BEST_EFFORT_RELIABILITY_QOS;
      wq.history().kind = dds::KEEP_LAST_HISTORY_QOS;
      wq.history().depth = 4;
    }
    writer_ = pub == nullptr ? nullptr : pub->create_datawriter(t, wq);
  } else {
    dds::Subscriber* sub = p.create_subscriber(dds::SUBSCRIBER_QOS_DEFAULT);
    dds::DataReaderQos rq = dds::DATAREADER_QOS_DEFAULT;
    rq.durability().kind = dds::VOLATILE_DURABILITY_QOS;
    if (reliable) {
      rq.reliability().kind = dds::RELIABLE_RELIABILITY_QOS;
      rq.history().kind = dds::KEEP_ALL_HISTORY_QOS;
      rq.resource_limits().max_samples = 1000;
      rq.resource_limits().allocated_samples = 64;
    } else {
      rq.reliability().kind = dds::BEST_EFFORT_RELIABILITY_QOS;
      rq.history().kind = dds::KEEP_LAST_HISTORY_QOS;
      rq.history().depth = 4;
    }
    reader_ = sub == nullptr ? nullptr : sub->create_datareader(t, rq);
  }
  if (writer_ == nullptr && reader_ == nullptr)
    throw DdsError(std::string("Fast DDS could not create a data ") +
                   (writer ? "writer" : "reader") + " on topic '" + topic + "' (" + qos_name(qos) +
                   ")");
}

Endpoint::~Endpoint() {
  // the participant deletes the topic, publisher and subscriber with itself
  if (writer_ != nullptr) {
    dds::Publisher* pub = const_cast<dds::Publisher*>(writer_->get_publisher());
    pub->delete_datawriter(writer_);
    participant_.participant_->delete_publisher(pub);
  }
  if (reader_ != nullptr) {
    dds::Subscriber* sub = const_cast<dds::Subscriber*>(reader_->get_subscriber());
    sub->delete_datareader(reader_);
    participant_.participant_->delete_subscriber(sub);
  }
}

int Endpoint::matched() const {
  if (writer_ != nullptr) {
    dds::PublicationMatchedStatus s;
    writer_->get_publication_matched_status(s);
    return s.current_count;
  }
  dds::SubscriptionMatchedStatus s;
  reader_->get_subscription_matched_status(s);
  return s.current_count;
}

bool Endpoint::wait_for_matched(int count, std::chrono::milliseconds timeout) const {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (matched() < count) {
    if (std::chrono::steady_clock::now() >= end)
      return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

bool Endpoint::wait_for_acknowledgments(std::chrono::milliseconds timeout) {
  return writer_ == nullptr ||
         writer_->wait_for_acknowledgments(duration(timeout)) == ReturnCode_t::RETCODE_OK;
}

bool Endpoint::write_sample(void* sample, std::chrono::milliseconds timeout) {
  // write() is false when the history stayed full for max_blocking_time (a reader behind):
  // try again until `timeout`
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!writer_->write(sample)) {
    if (std::chrono::steady_clock::now() >= end)
      return false;
  }
  return true;
}

bool Endpoint::take_sample(void* sample, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (true) {
    dds::SampleInfo info;
    if (reader_->take_next_sample(sample, &info) == ReturnCode_t::RETCODE_OK) {
      if (info.valid_data)
        return true;
      continue;  // a lifecycle notification, not data
    }
    const auto left = end - std::chrono::steady_clock::now();
    if (left <= std::chrono::nanoseconds(0))
      return false;
    reader_->wait_for_unread_message(duration(left));
  }
}

namespace {
std::atomic<int> g_signal{0};
std::atomic<int> g_installed{0};
struct sigaction g_old_int, g_old_term;

extern "C" void on_signal(int sig) {
  int expected = 0;
  if (!g_signal.compare_exchange_strong(expected, sig))
    ::_exit(128 + sig);  // a second signal: the user insists
}
}  // namespace

ShutdownSignals::ShutdownSignals() {
  if (g_installed.exchange(1) != 0)
    throw std::logic_error("ShutdownSignals: one at a time");
  g_signal = 0;
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, &g_old_int);
  sigaction(SIGTERM, &sa, &g_old_term);
}

ShutdownSignals::~ShutdownSignals() {
  sigaction(SIGINT, &g_old_int, nullptr);
  sigaction(SIGTERM, &g_old_term, nullptr);
  g_installed = 0;
}

bool ShutdownSignals::requested() const {
  return g_signal.load() != 0;
}
int ShutdownSignals::signal() const {
  return g_signal.load();
}

bool ShutdownSignals::sleep_for(std::chrono::nanoseconds d) const {
  const auto end = std::chrono::steady_clock::now() + d;
  while (!requested()) {
    const auto left = end - std::chrono::steady_clock::now();
    if (left <= std::chrono::nanoseconds(0))
      return false;
    std::this_thread::sleep_for(
        std::min<std::chrono::nanoseconds>(left, std::chrono::milliseconds(5)));
  }
  return true;
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace ropes::msgs
