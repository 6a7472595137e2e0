// ropes-stream: a trained run's Estimator as a DDS node: ImageFrames in, PoseEstimates out.
#include <ropes_core/cli.hpp>
#include <ropes_core/dataset.hpp>
#include <ropes_core/dtype.hpp>
#include <ropes_core/file_io.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_crl/calibration.hpp>
#include <ropes_crl/dataset_version.hpp>
#include <ropes_crl/estimator.hpp>
#include <ropes_crl/run_directory.hpp>
#include <ropes_msgs/dds.hpp>

#include <ropes_crl/frame_grouper.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
namespace msgs = ropes::msgs;
using ropes::crl::stream::Clock;

const char* const kUsage = R"(usage: ropes-stream --run RUN [options]
       ropes-stream --run RUN --replay DIR [options]

Loads the Estimator of the trained run RUN (ropes-train's output) and its calibration (by
default the calibration.json of RUN's latest evaluation by ropes-eval or ropes-run, which
keep it beside the run, never in it) and answers every ImageFrame
on ropes/image_frames with a PoseEstimate on ropes/pose_estimates. The cameras of one instant
(one sequence number) may come in one frame or in several; an estimate is made once all the
run's cameras are there. A frame of the wrong size, encoding or cameras is refused with a log
line and counted in every later estimate's rejected_frames. Runs until SIGINT or SIGTERM.

With --replay, reads the rows of the dataset in DIR instead (ropes-generate's output) and
publishes, per row, its JointState (ropes/joint_states) and its estimate, then exits.

options:
  --calibration FILE        the affine calibration (a ropes-eval calibration.json fitted for
                            this run; default: the newest of RUN-eval/calibration.json,
                            RUN-eval/report/calibration.json and, for ropes-run's OUT/run,
                            OUT/report/calibration.json that records RUN; none: no
                            calibration). Without one, estimates carry latents, no angles
  --run-id ID               the run id in the estimates (default: RUN's directory name, or
                            its parent's for ropes-run's OUT/run)
  --frame-qos Q             sensor (default) or reliable_all: the QoS of the frame reader,
                            as the publisher of the frames uses
  --estimates N             exit after N estimates
  --wait-for-subscribers N  wait until N (1 to 1000) readers of ropes/pose_estimates match
  --rate HZ                 --replay: rows a second (default: as fast as readers take them)
  --rows N                  --replay: the first N rows only
The domain is ROPES_DDS_DOMAIN (default 0); ROPES_DDS_LOOPBACK=1 keeps to this host.
)";

using ropes::core::UsageError;

long long parse_count(const std::string& flag, const std::string& text) {
  return ropes::core::parse_number<long long>(flag, text, 1, std::numeric_limits<long long>::max());
}

// a rate in (0, 100000] Hz
double parse_rate(const std::string& flag, const std::string& text) {
  const double v = ropes::core::parse_number<double>(flag, text, 0.0, 1e5);
  if (v == 0)
    throw UsageError(flag + " is '" + text + "'; expected a rate in (0, 100000] Hz");
  return v;
}

class Node {
 public:
  Node(ropes::crl::Estimator& estimator, msgs::Publisher<msgs::PoseEstimate>& pub,
       std::string run_id)
      : estimator_(estimator),
        pub_(pub),
        grouper_(static_cast<int>(estimator.cameras()), static_cast<int>(estimator.image_size()),
                 [this](unsigned long long seq, std::int64_t stamp, const std::uint8_t* pixels,
                        Clock::time_point received) { publish(seq, stamp, pixels, received); }) {
    joints_ = static_cast<std::size_t>(estimator.joints().size());
    latents_.resize(joints_);
    angles_.resize(joints_);
    out_.run_id(std::move(run_id));
    out_.joint_names(estimator.joints());
  }

  void on_frame(const msgs::ImageFrame& f) { grouper_.on_frame(f); }

  void publish(unsigned long long frame_seq, std::int64_t frame_stamp, const std::uint8_t* pixels,
               Clock::time_point received) {
    const bool calibrated = estimator_.calibrated();
    estimator_.estimate_frame(pixels, latents_.data(), calibrated ? angles_.data() : nullptr);
    out_.sequence_number(sent_);
    out_.frame_sequence_number(frame_seq);
    out_.frame_stamp_ns(frame_stamp);
    out_.latents(latents_);
    std::vector<bool> valid(joints_, false);
    if (calibrated) {
      out_.joint_angles(angles_);
      for (std::size_t k = 0; k < joints_; ++k)
        valid[k] = std::isfinite(angles_[k]);
    }
    out_.valid(valid);
    out_.rejected_frames(grouper_.rejected());
    out_.stamp_ns(msgs::now_ns());
    const auto latency = Clock::now() - received;
    out_.latency_ns(std::chrono::duration_cast<std::chrono::nanoseconds>(latency).count());
    latency_s_ += std::chrono::duration<double>(latency).count();
    if (!pub_.write(out_))
      std::fprintf(stderr, "ropes-stream: estimate %llu: the write timed out (a reader stuck?)\n",
                   static_cast<unsigned long long>(sent_));
    ++sent_;
  }

  unsigned long long sent() const { return sent_; }
  void summary(double seconds) const {
    std::fprintf(stderr,
                 "ropes-stream: %llu estimates in %.1f s, %llu frames rejected, mean latency "
                 "(frame received -> estimate written) %.2f ms\n",
                 static_cast<unsigned long long>(sent_), seconds,
                 static_cast<unsigned long long>(grouper_.rejected()),
                 sent_ > 0 ? 1e3 * latency_s_ / static_cast<double>(sent_) : 0.0);
    for (const auto& [reason, count] : grouper_.reasons())
      std::fprintf(stderr, "ropes-stream:   rejected %llu x %s...\n",
                   static_cast<unsigned long long>(count), reason.c_str());
  }

 private:
  ropes::crl::Estimator& estimator_;
  msgs::Publisher<msgs::PoseEstimate>& pub_;
  ropes::crl::stream::FrameGrouper grouper_;
  std::size_t joints_ = 0;
  std::vector<float> latents_, angles_;
  msgs::PoseEstimate out_;
  unsigned long long sent_ = 0;
  double latency_s_ = 0;
};

int replay(Node& node, ropes::crl::Estimator& estimator, const ropes::core::DatasetReader& reader,
           msgs::Publisher<msgs::JointState>& joint_pub, const msgs::ShutdownSignals& signals,
           double rate, long long rows_limit) {
  const fs::path& dir = reader.dir();
  const auto& images = reader.column("images");
  const std::vector<std::int64_t> want = {estimator.cameras(), estimator.image_size(),
                                          estimator.image_size()};
  if (images.row_shape != want || images.dtype != ropes::core::DType::kU8)
    throw std::runtime_error(dir.string() + ": its images column is not u8 rows of [" +
                             std::to_string(want[0]) + ", " + std::to_string(want[1]) + ", " +
                             std::to_string(want[2]) + "] (the run's cameras and image size)");
  std::vector<std::string> names;
  if (reader.metadata().contains("joint_names"))
    names = reader.metadata()["joint_names"].get<std::vector<std::string>>();
  msgs::JointState joints;
  joints.names(names);
  const std::int64_t rows =
      rows_limit > 0 ? std::min<std::int64_t>(rows_limit, reader.rows()) : reader.rows();
  const std::size_t bytes = static_cast<std::size_t>(want[0] * want[1] * want[2]);
  std::vector<std::uint8_t> pixels(bytes);
  std::vector<float> angles(names.size());
  const Clock::time_point start = Clock::now();
  for (std::int64_t r = 0; r < rows && !signals.requested(); ++r) {
    if (rate > 0 &&
        signals.sleep_for(start +
                          std::chrono::duration_cast<Clock::duration>(
                              std::chrono::duration<double>(static_cast<double>(r) / rate)) -
                          Clock::now()))
      break;
    reader.read_rows("images", r, 1, pixels.data());
    const Clock::time_point received = Clock::now();
    const std::int64_t stamp = msgs::now_ns();
    if (!names.empty()) {
      reader.read_rows("angles", r, 1, angles.data());
      joints.stamp_ns(stamp);
      joints.sequence_number(static_cast<unsigned long long>(r));
      joints.positions(std::vector<double>(angles.begin(), angles.end()));
      joint_pub.write(joints);
    }
    node.publish(static_cast<unsigned long long>(r), stamp, pixels.data(), received);
  }
  joint_pub.wait_for_acknowledgments(std::chrono::seconds(5));
  return 0;
}

int run(int argc, char** argv) {
  std::string run_dir, calibration, run_id, replay_dir;
  msgs::Qos frame_qos = msgs::Qos::sensor;
  long long estimates = -1, rows = -1;
  int wait_for = 0;
  double rate = 0;
  ropes::core::CommandLine command_line(kUsage);
  command_line.option("--run", [&](const std::string& v) { run_dir = v; })
      .option("--calibration", [&](const std::string& v) { calibration = v; })
      .option("--run-id", [&](const std::string& v) { run_id = v; })
      .option("--replay", [&](const std::string& v) { replay_dir = v; })
      .option("--estimates",
              [&](const std::string& v) { estimates = parse_count("--estimates", v); })
      .option("--rows", [&](const std::string& v) { rows = parse_count("--rows", v); })
      .option("--wait-for-subscribers",
              [&](const std::string& v) {
                wait_for = ropes::core::parse_number<int>("--wait-for-subscribers", v, 1, 1000);
              })
      .option("--rate", [&](const std::string& v) { rate = parse_rate("--rate", v); })
      .option("--frame-qos", [&](const std::string& v) {
        frame_qos = ropes::core::for_flag("--frame-qos", [&] { return msgs::qos_from_name(v); });
      });
  if (!command_line.parse(argc, argv))
    return 0;
  if (run_dir.empty())
    throw UsageError("--run is required (see --help)");
  const auto run = ropes::crl::RunDirectory::open(run_dir);
  auto estimator = ropes::crl::Estimator::load(run);
  if (calibration.empty()) {
    std::vector<std::string> skipped;
    if (const auto latest = ropes::crl::latest_calibration(run, &skipped))
      calibration = latest->string();
    for (const std::string& why : skipped)
      std::fprintf(stderr, "ropes-stream: passed over %s\n", why.c_str());
  }
  if (!calibration.empty() && calibration != "none") {
    const auto fit = ropes::crl::Calibration::read(calibration);
    try {
      fit.check_fits(run);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(calibration + ": " + e.what());
    }
    estimator.set_calibration(fit);
    std::fprintf(stderr, "ropes-stream: calibration %s\n", calibration.c_str());
  }
  if (run_id.empty()) {
    // the directory's name; ropes-run's OUT/run is called by OUT's
    fs::path p = fs::absolute(run_dir).lexically_normal();
    if (!p.has_filename())
      p = p.parent_path();
    run_id = p.filename() == "run" ? p.parent_path().filename().string() : p.filename().string();
  }

  msgs::ShutdownSignals signals;
  msgs::Participant participant({"ropes-stream"});
  msgs::Publisher<msgs::PoseEstimate> pub(participant);
  Node node(estimator, pub, run_id);
  std::fprintf(
      stderr, "ropes-stream: run %s (%lld camera(s) %lldx%lld, %zu joints, %s) on domain %d\n",
      run_id.c_str(), static_cast<long long>(estimator.cameras()),
      static_cast<long long>(estimator.image_size()),
      static_cast<long long>(estimator.image_size()), estimator.joints().size(),
      estimator.calibrated() ? "calibrated" : "uncalibrated: latents only", participant.domain());
  // --replay: the dataset is opened (and checked) before anything is published
  std::unique_ptr<ropes::core::DatasetReader> reader;
  std::unique_ptr<msgs::Publisher<msgs::JointState>> joint_pub;
  if (!replay_dir.empty()) {
    reader =
        std::make_unique<ropes::core::DatasetReader>(ropes::core::DatasetReader::open(replay_dir));
    ropes::crl::require_current_sim_dataset(*reader);  // not the old reading of TN(mean, x)
    joint_pub = std::make_unique<msgs::Publisher<msgs::JointState>>(participant);
  }
  if (wait_for > 0) {
    std::fprintf(stderr, "ropes-stream: waiting for %d subscriber(s)\n", wait_for);
    const auto step = std::chrono::milliseconds(100);
    while (!signals.requested() && !(pub.wait_for_matched(wait_for, step) &&
                                     (!joint_pub || joint_pub->wait_for_matched(wait_for, step)))) {
    }
  }
  const Clock::time_point start = Clock::now();
  int rc = 0;
  if (!replay_dir.empty()) {
    rc = replay(node, estimator, *reader, *joint_pub, signals, rate, rows);
  } else {
    msgs::Subscriber<msgs::ImageFrame> frames(participant, msgs::kImageFrameTopic, frame_qos);
    msgs::ImageFrame frame;
    while (!signals.requested() &&
           (estimates < 0 || node.sent() < static_cast<unsigned long long>(estimates))) {
      if (frames.take(frame, std::chrono::milliseconds(50)))
        node.on_frame(frame);
    }
  }
  pub.wait_for_acknowledgments(std::chrono::seconds(5));
  node.summary(std::chrono::duration<double>(Clock::now() - start).count());
  return rc;
}

}  // namespace

int main(int argc, char** argv) {
  return ropes::core::run_main("ropes-stream", run, argc, argv);
}
