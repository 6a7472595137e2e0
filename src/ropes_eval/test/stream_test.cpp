// Streaming end to end over the loopback profile (ROPES_DDS_LOOPBACK=1, a domain of its own,
// set by CTest), through the installed executables: ropes-sim-stream -> ropes-stream -> this
// process, ropes-stream --replay, bad frames, ropes-eval --live and ropes-train --status.
// Witness for the estimates: the Estimator run offline in this process on the very bytes
// each frame carried.
#include <ropes_core/child_process.hpp>
#include <ropes_core/dataset.hpp>
#include <ropes_crl/calibration.hpp>
#include <ropes_crl/estimator.hpp>
#include <ropes_crl/run_directory.hpp>
#include <ropes_eval/correlation.hpp>
#include <ropes_msgs/dds.hpp>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <signal.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace fs = std::filesystem;
namespace msgs = ropes::msgs;
using ropes::core::ChildOptions;
using ropes::core::ChildProcess;
using namespace std::chrono_literals;

const fs::path kDir = ROPES_EVAL_STREAM_TEST_DIR;

int run_to_end(std::vector<std::string> args, const fs::path& log) {
  ChildProcess c(std::move(args), ChildOptions::to_log(log));
  return c.wait(std::chrono::seconds(300));
}

std::string text_of(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// a tiny dataset and a run trained on it, with a calibration (made up: scale 1.5 + 0.1 k,
// offset -0.2 k), made once and reused
fs::path tiny_run(const std::string& cameras) {
  const fs::path data = kDir / ("data-" + cameras), run = kDir / ("run-" + cameras);
  fs::create_directories(kDir);
  const std::vector<std::string> generate = {
      ROPES_GENERATE_EXE, "--config", "tiny-" + cameras, "--out", data.string(), "--seed", "0"};
  // a dataset an earlier build made (another rig or distribution) is refused: made again
  if (run_to_end(generate, kDir / "generate.log") != 0) {
    fs::remove_all(data);
    fs::remove_all(run);
    EXPECT_EQ(run_to_end(generate, kDir / "generate.log"), 0) << text_of(kDir / "generate.log");
  }
  EXPECT_EQ(run_to_end({ROPES_TRAIN_EXE, "--config", cameras + "-tiny", "--data", data.string(),
                        "--out", run.string(), "--progress", "lines"},
                       kDir / "train.log"),
            0)
      << text_of(kDir / "train.log");
  auto estimator = ropes::crl::Estimator::load(run);
  // where ropes-eval writes it (RUN-eval, beside the run): ropes-stream finds it by default
  ropes::crl::Calibration c;
  c.joints = estimator.joints();
  c.run = ropes::crl::RunIdentity::of(ropes::crl::RunDirectory::open(run));
  for (std::size_t k = 0; k < estimator.joints().size(); ++k) {
    c.scale.push_back(1.5 + 0.1 * static_cast<double>(k));
    c.offset.push_back(-0.2 * static_cast<double>(k));
  }
  fs::create_directories(ropes::crl::default_evaluation_dir(run));
  c.write(ropes::crl::default_evaluation_dir(run) / "calibration.json");
  return run;
}

ropes::crl::Estimator offline(const fs::path& run) {
  auto estimator = ropes::crl::Estimator::load(run);
  estimator.set_calibration(
      ropes::crl::Calibration::read(ropes::crl::default_evaluation_dir(run) / "calibration.json"));
  return estimator;
}

// every field of `e` against the Estimator on `pixels`, bit for bit
void expect_offline_estimate(ropes::crl::Estimator& estimator, const std::uint8_t* pixels,
                             const msgs::PoseEstimate& e) {
  const std::size_t j = estimator.joints().size();
  std::vector<float> latents(j), angles(j);
  estimator.estimate_frame(pixels, latents.data(), angles.data());
  EXPECT_EQ(e.latents(), latents) << "frame " << e.frame_sequence_number();
  EXPECT_EQ(e.joint_angles(), angles) << "frame " << e.frame_sequence_number();
  EXPECT_EQ(e.joint_names(), estimator.joints());
  EXPECT_EQ(e.valid(), std::vector<bool>(j, true));
}

class Streaming : public ::testing::TestWithParam<std::string> {};

TEST_P(Streaming, EveryFrameGetsExactlyOneEstimateEqualToTheOfflineEstimator) {
  const std::string cameras = GetParam();
  const fs::path run = tiny_run(cameras);
  msgs::Participant participant({"stream-test"});
  msgs::Subscriber<msgs::ImageFrame> frames(participant, msgs::kImageFrameTopic,
                                            msgs::Qos::reliable_all);
  msgs::Subscriber<msgs::PoseEstimate> estimates(participant);
  // --wait-for-subscribers 1: the node reads no frame before its estimate writer has matched
  // this reader. That this reader matched the writer says nothing of the other direction, and
  // a volatile writer drops what it writes before (an estimate lost under ASan in CI).
  ChildProcess node({ROPES_STREAM_EXE, "--run", run.string(), "--frame-qos", "reliable_all",
                     "--wait-for-subscribers", "1"},
                    ChildOptions::to_log(kDir / ("node-" + cameras + ".log")));
  ASSERT_TRUE(estimates.wait_for_matched(1, 30s)) << text_of(kDir / ("node-" + cameras + ".log"));
  const int n = 60;
  std::vector<std::string> sim = {ROPES_SIM_STREAM_EXE,
                                  "--config",
                                  "tiny-" + cameras,
                                  "--frames",
                                  std::to_string(n),
                                  "--rate",
                                  "60",
                                  "--frame-qos",
                                  "reliable_all",
                                  "--wait-for-subscribers",
                                  "2"};
  if (cameras == "2c")
    sim.push_back("--split-cameras");  // the node groups the cameras of one instant
  ChildProcess simulator(sim, ChildOptions::to_log(kDir / ("sim-" + cameras + ".log")));

  // the frames as they were published (a whole instant, assembled for --split-cameras)
  std::map<unsigned long long, std::vector<std::uint8_t>> pixels;
  std::map<unsigned long long, int> parts;
  std::map<unsigned long long, std::vector<msgs::PoseEstimate>> answers;
  const int per_instant = cameras == "2c" ? 2 : 1;
  msgs::ImageFrame f;
  msgs::PoseEstimate e;
  unsigned long long received = 0;
  int all_parts = 0;
  const auto end = std::chrono::steady_clock::now() + 60s;
  while ((all_parts < n * per_instant || received < static_cast<unsigned long long>(n)) &&
         std::chrono::steady_clock::now() < end) {
    while (frames.take(f, 0ms)) {
      auto& p = pixels[f.sequence_number()];
      const std::size_t image = static_cast<std::size_t>(f.width()) * f.height();
      p.resize(image * static_cast<std::size_t>(per_instant));
      for (std::size_t c = 0; c < f.camera_ids().size(); ++c)
        std::copy(f.pixels().begin() + static_cast<long>(c * image),
                  f.pixels().begin() + static_cast<long>((c + 1) * image),
                  p.begin() + static_cast<long>(f.camera_ids()[c] * image));
      parts[f.sequence_number()] += static_cast<int>(f.camera_ids().size());
      all_parts += static_cast<int>(f.camera_ids().size());
    }
    if (estimates.take(e, 10ms)) {
      answers[e.frame_sequence_number()].push_back(e);
      ++received;
    }
  }
  EXPECT_EQ(simulator.wait(30s), 0) << text_of(kDir / ("sim-" + cameras + ".log"));
  EXPECT_FALSE(estimates.take(e, 500ms))
      << "an estimate too many, for frame " << e.frame_sequence_number();
  node.signal(SIGTERM);
  EXPECT_EQ(node.wait(20s), 0) << "no clean exit on SIGTERM";

  ASSERT_EQ(parts.size(), static_cast<std::size_t>(n));
  auto estimator = offline(run);
  unsigned long long expected_sequence = 0;
  for (int i = 0; i < n; ++i) {
    const auto seq = static_cast<unsigned long long>(i);
    ASSERT_EQ(parts[seq], per_instant) << "frame " << i;
    ASSERT_EQ(answers[seq].size(), 1u)
        << "frame " << i << " got " << answers[seq].size() << " estimates";
    const msgs::PoseEstimate& a = answers[seq][0];
    EXPECT_EQ(a.sequence_number(), expected_sequence++);
    EXPECT_EQ(a.run_id(), "run-" + cameras);
    EXPECT_EQ(a.rejected_frames(), 0u);
    EXPECT_GT(a.latency_ns(), 0);
    expect_offline_estimate(estimator, pixels[seq].data(), a);
  }
  const std::string log = text_of(kDir / ("node-" + cameras + ".log"));
  EXPECT_NE(log.find(std::to_string(n) + " estimates"), std::string::npos) << log;
}

INSTANTIATE_TEST_SUITE_P(Rigs, Streaming, ::testing::Values("1c", "2c"));

msgs::ImageFrame frame(unsigned long long seq, int size, std::vector<std::uint16_t> ids,
                       const std::string& encoding = "mono8") {
  msgs::ImageFrame f;
  f.sequence_number(seq);
  f.stamp_ns(msgs::now_ns());
  f.width(static_cast<std::uint16_t>(size));
  f.height(static_cast<std::uint16_t>(size));
  f.encoding(encoding);
  std::vector<std::string> names;
  for (const auto id : ids)
    names.push_back("cam" + std::to_string(id));
  f.camera_names(names);
  f.camera_ids(ids);
  std::vector<std::uint8_t> p(ids.size() * static_cast<std::size_t>(size * size));
  for (std::size_t i = 0; i < p.size(); ++i)
    p[i] = static_cast<std::uint8_t>((i * 7 + seq) % 251);
  f.pixels(p);
  return f;
}

TEST(StreamingNode, BadFramesAreRefusedCountedAndLoggedWithoutStoppingTheNode) {
  const fs::path run = tiny_run("1c");
  auto estimator = offline(run);
  const int s = static_cast<int>(estimator.image_size());
  msgs::Participant participant({"bad-frame-test"});
  msgs::Publisher<msgs::ImageFrame> pub(participant, msgs::kImageFrameTopic,
                                        msgs::Qos::reliable_all);
  msgs::Subscriber<msgs::PoseEstimate> estimates(participant);
  const fs::path log = kDir / "node-bad.log";
  // the node opens its frame reader once its estimate writer has matched `estimates` (see
  // Streaming above), so a frame writer matched to that reader loses no estimate
  ChildProcess node({ROPES_STREAM_EXE, "--run", run.string(), "--frame-qos", "reliable_all",
                     "--wait-for-subscribers", "1"},
                    ChildOptions::to_log(log));
  ASSERT_TRUE(pub.wait_for_matched(1, 30s)) << text_of(log);
  ASSERT_TRUE(estimates.wait_for_matched(1, 30s));
  std::vector<msgs::ImageFrame> sent = {
      frame(0, s, {0}),          // good
      frame(1, s / 2, {0}),      // wrong size
      frame(2, s, {0}, "rgb8"),  // wrong encoding
      frame(3, s, {0, 1}),       // a camera the 1C run does not have
      frame(4, s, {0}),          // pixels cut short
      frame(5, s, {}),           // no camera
      frame(6, s, {0}),          // good
  };
  auto cut = sent[4].pixels();
  cut.resize(cut.size() - 5);
  sent[4].pixels(cut);
  for (const auto& f : sent)
    ASSERT_TRUE(pub.write(f));
  msgs::PoseEstimate e;
  ASSERT_TRUE(estimates.take(e, 20s)) << text_of(log);
  EXPECT_EQ(e.frame_sequence_number(), 0u);
  EXPECT_EQ(e.rejected_frames(), 0u);
  expect_offline_estimate(estimator, sent[0].pixels().data(), e);
  ASSERT_TRUE(estimates.take(e, 20s)) << text_of(log);
  EXPECT_EQ(e.frame_sequence_number(), 6u);
  EXPECT_EQ(e.rejected_frames(), 5u) << "the estimate stream counts the refused frames";
  expect_offline_estimate(estimator, sent[6].pixels().data(), e);
  // a publisher that starts again from 0 after the node answered up to 40: a new stream,
  // not frames already answered
  ASSERT_TRUE(pub.write(frame(40, s, {0})));
  ASSERT_TRUE(estimates.take(e, 20s)) << text_of(log);
  EXPECT_EQ(e.frame_sequence_number(), 40u);
  const msgs::ImageFrame again = frame(0, s, {0});
  ASSERT_TRUE(pub.write(again));
  ASSERT_TRUE(estimates.take(e, 20s)) << text_of(log);
  EXPECT_EQ(e.frame_sequence_number(), 0u);
  EXPECT_EQ(e.rejected_frames(), 5u);
  expect_offline_estimate(estimator, again.pixels().data(), e);
  EXPECT_FALSE(estimates.take(e, 500ms));
  EXPECT_TRUE(node.running()) << "a bad frame stopped the node";
  node.signal(SIGINT);
  EXPECT_EQ(node.wait(20s), 0);
  const std::string text = text_of(log);
  const std::vector<std::string> reasons = {
      "frame 1 rejected", "size " + std::to_string(s / 2) + "x" + std::to_string(s / 2),
      "frame 2 rejected", "encoding 'rgb8', expected mono8",
      "frame 3 rejected", "camera id 1, the run has 1 camera(s)",
      "frame 4 rejected", "pixel bytes",
      "frame 5 rejected", "5 frames rejected"};
  for (const std::string& reason : reasons)
    EXPECT_NE(text.find(reason), std::string::npos) << "'" << reason << "' not in:\n" << text;
}

TEST(StreamingNode, ReplayOfADatasetAndTheLiveEvaluationOfIt) {
  const fs::path run = tiny_run("1c");
  const fs::path data = kDir / "data-1c";
  const auto reader = ropes::core::DatasetReader::open(data);
  const int rows = 40;
  msgs::Participant participant({"replay-test"});
  msgs::Subscriber<msgs::PoseEstimate> estimates(participant);
  msgs::Subscriber<msgs::JointState> truths(participant);
  const fs::path live_json = kDir / "live.json";
  fs::remove(live_json);
  ChildProcess live({ROPES_EVAL_EXE, "--live", "--estimates", std::to_string(rows), "--window",
                     "1000", "--out", live_json.string()},
                    ChildOptions::to_log(kDir / "live.log"));
  std::this_thread::sleep_for(1s);
  const int rc = run_to_end({ROPES_STREAM_EXE, "--run", run.string(), "--replay", data.string(),
                             "--rows", std::to_string(rows), "--wait-for-subscribers", "2"},
                            kDir / "replay.log");
  EXPECT_EQ(rc, 0) << text_of(kDir / "replay.log");
  EXPECT_EQ(live.wait(30s), 0) << text_of(kDir / "live.log");

  auto estimator = offline(run);
  const std::size_t j = estimator.joints().size();
  const auto images = reader.read_rows("images", 0, rows);
  const auto angles = reader.read_rows("angles", 0, rows);
  const std::size_t bytes = images.data.size() / rows;
  const auto names = reader.metadata()["joint_names"].get<std::vector<std::string>>();
  Eigen::MatrixXd latent(rows, static_cast<Eigen::Index>(j)),
      truth(rows, static_cast<Eigen::Index>(j));
  msgs::PoseEstimate e;
  msgs::JointState t;
  for (int r = 0; r < rows; ++r) {
    ASSERT_TRUE(estimates.take(e, 10s)) << "row " << r;
    ASSERT_EQ(e.frame_sequence_number(), static_cast<unsigned long long>(r));
    expect_offline_estimate(estimator, images.data.data() + r * bytes, e);
    ASSERT_TRUE(truths.take(t, 10s)) << "row " << r;
    ASSERT_EQ(t.sequence_number(), static_cast<unsigned long long>(r));
    ASSERT_EQ(t.names(), names);
    ASSERT_EQ(t.positions().size(), names.size());
    for (std::size_t i = 0; i < names.size(); ++i) {
      float a = 0;
      std::memcpy(&a, angles.data.data() + (static_cast<std::size_t>(r) * names.size() + i) * 4, 4);
      EXPECT_EQ(t.positions()[i], static_cast<double>(a));
    }
    for (std::size_t k = 0; k < j; ++k) {
      const auto at = std::find(names.begin(), names.end(), estimator.joints()[k]);
      ASSERT_NE(at, names.end());
      latent(r, static_cast<Eigen::Index>(k)) = e.latents()[k];
      truth(r, static_cast<Eigen::Index>(k)) =
          t.positions()[static_cast<std::size_t>(at - names.begin())];
    }
  }
  // ropes-eval --live's MCC over the window is |Pearson| of the pairs it matched
  const nlohmann::json figures = nlohmann::json::parse(text_of(live_json));
  EXPECT_EQ(figures["pairs"], rows);
  for (std::size_t k = 0; k < j; ++k) {
    const auto& f = figures["joints"][k];
    EXPECT_EQ(f["joint"], estimator.joints()[k]);
    EXPECT_NEAR(f["mcc"].get<double>(),
                std::abs(ropes::eval::pearson(latent.col(static_cast<Eigen::Index>(k)),
                                              truth.col(static_cast<Eigen::Index>(k)))),
                1e-9);
    EXPECT_EQ(f["calibrated_pairs"], rows);
  }
}

TEST(StreamingNode, TrainingPublishesItsStatusStageByStage) {
  tiny_run("1c");  // the dataset
  const fs::path out = kDir / "run-status";
  fs::remove_all(out);
  msgs::Participant participant({"status-test"});
  msgs::Subscriber<msgs::RunStatus> status(participant);
  ChildProcess train({ROPES_TRAIN_EXE, "--config", "1c-tiny", "--data", (kDir / "data-1c").string(),
                      "--out", out.string(), "--status", "--progress", "lines"},
                     ChildOptions::to_log(kDir / "train-status.log"));
  std::vector<msgs::RunStatus> seen;
  msgs::RunStatus s;
  while (status.take(s, 30s)) {
    seen.push_back(s);
    if (s.stage() == "complete" || s.stage() == "failed")
      break;
  }
  EXPECT_EQ(train.wait(60s), 0) << text_of(kDir / "train-status.log");
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back().stage(), "complete");
  std::map<std::string, std::int64_t> last_step;
  std::vector<std::string> kinds;
  for (std::size_t i = 0; i + 1 < seen.size(); ++i) {
    const auto& r = seen[i];
    EXPECT_EQ(r.run_id(), "run-status");
    EXPECT_GT(r.step(), last_step[r.stage()]) << r.stage();
    last_step[r.stage()] = r.step();
    EXPECT_LE(r.step(), r.total_steps()) << r.stage();
    EXPECT_EQ(r.loss_names().size(), r.loss_values().size());
    const std::string kind = r.stage().substr(0, r.stage().find(' '));
    if (kinds.empty() || kinds.back() != kind)
      kinds.push_back(kind);
  }
  EXPECT_EQ(kinds, (std::vector<std::string>{"ae1", "ldr", "ae2"}));
}

TEST(StreamingNode, BadCommandLinesAndRunsAreRefusedWithAClearMessage) {
  struct Case {
    std::vector<std::string> args;
    int rc;
    std::string message;
  };
  const std::vector<Case> cases = {
      {{ROPES_STREAM_EXE}, 2, "--run is required"},
      {{ROPES_STREAM_EXE, "--run", (kDir / "no-such-run").string()}, 1, "no-such-run"},
      {{ROPES_STREAM_EXE, "--run", "x", "--frame-qos", "fast"},
       2,
       "--frame-qos: QoS 'fast'; expected sensor or reliable_all"},
      {{ROPES_STREAM_EXE, "--run", "x", "--rate", "0"}, 2, "--rate is '0'"},
      {{ROPES_SIM_STREAM_EXE, "--config", "tiny-1c", "--rate", "-3"}, 2, "--rate is '-3'"},
      {{ROPES_SIM_STREAM_EXE, "--config", "no-such-config"}, 2, "'no-such-config' is neither"},
      {{ROPES_ECHO_EXE, "frames"}, 2, "TOPIC is 'frames'; expected image_frames"},
      {{ROPES_ECHO_EXE, "pose_estimates", "--count", "0"}, 2, "--count is '0'"},
      {{ROPES_ECHO_EXE, "pose_estimates", "image_frames"},
       2,
       "one TOPIC only (got 'pose_estimates' and 'image_frames')"},
      {{ROPES_EVAL_EXE, "--live", "--window", "2"}, 2, "--window is 2; expected at least 3"},
  };
  fs::create_directories(kDir);
  for (const Case& c : cases) {
    const fs::path log = kDir / "cli.log";
    EXPECT_EQ(run_to_end(c.args, log), c.rc) << c.args[0] << " " << c.args.back();
    const std::string text = text_of(log);
    EXPECT_NE(text.find(c.message), std::string::npos) << "'" << c.message << "' not in " << text;
  }
  // a bad domain in the environment is named before anything starts
  ::setenv("ROPES_DDS_DOMAIN", "999", 1);
  EXPECT_EQ(run_to_end({ROPES_ECHO_EXE, "pose_estimates"}, kDir / "cli.log"), 1);
  EXPECT_NE(text_of(kDir / "cli.log").find("ROPES_DDS_DOMAIN is '999'"), std::string::npos);
}

// ropes-stream's calibration: the run's latest evaluation's by default (tiny_run puts one in
// RUN-eval, and the Streaming tests compare the angles); one fitted for another run is
// refused, naming both runs; "none" streams latents only
TEST(StreamingNode, ACalibrationOfAnotherRunIsRefused) {
  const fs::path run = tiny_run("1c");
  auto fit =
      ropes::crl::Calibration::read(ropes::crl::default_evaluation_dir(run) / "calibration.json");
  ASSERT_TRUE(fit.run.has_value());
  fit.run->seed += 1;
  const fs::path other = kDir / "other-run-calibration.json";
  fit.write(other);
  const fs::path log = kDir / "calibration.log";
  EXPECT_EQ(run_to_end({ROPES_STREAM_EXE, "--run", run.string(), "--calibration", other.string(),
                        "--estimates", "1"},
                       log),
            1);
  EXPECT_NE(text_of(log).find("ropes-stream: error: " + other.string() +
                              ": the calibration was fitted for another run (config 1c-tiny"),
            std::string::npos)
      << text_of(log);
  // the replay of two rows, with no calibration: latents, no angles
  const fs::path data = kDir / "data-1c";
  EXPECT_EQ(run_to_end({ROPES_STREAM_EXE, "--run", run.string(), "--calibration", "none",
                        "--replay", data.string(), "--rows", "2"},
                       log),
            0)
      << text_of(log);
  EXPECT_NE(text_of(log).find("uncalibrated: latents only"), std::string::npos) << text_of(log);
  EXPECT_EQ(
      run_to_end(
          {ROPES_STREAM_EXE, "--run", run.string(), "--replay", data.string(), "--rows", "2"}, log),
      0)
      << text_of(log);
  EXPECT_NE(
      text_of(log).find("ropes-stream: calibration " +
                        (ropes::crl::default_evaluation_dir(run) / "calibration.json").string()),
      std::string::npos)
      << text_of(log);
}

std::set<std::string> shm_entries() {
  std::set<std::string> out;
  for (const auto& e : fs::directory_iterator("/dev/shm"))
    out.insert(e.path().filename().string());
  return out;
}

TEST(StreamingNode, TheDemoNodesStopCleanlyOnSigtermAndLeaveNoSharedMemory) {
  const fs::path run = tiny_run("1c");
  const std::set<std::string> before = shm_entries();
  {
    ChildProcess node({ROPES_STREAM_EXE, "--run", run.string()},
                      ChildOptions::to_log(kDir / "demo-node.log"));
    ChildProcess echo({ROPES_ECHO_EXE, "pose_estimates"},
                      ChildOptions::to_log(kDir / "demo-echo.log"));
    ChildProcess sim({ROPES_SIM_STREAM_EXE, "--config", "tiny-1c"},
                     ChildOptions::to_log(kDir / "demo-sim.log"));
    // until the echo has printed estimates: the three are talking over shared memory
    const auto end = std::chrono::steady_clock::now() + 30s;
    while (text_of(kDir / "demo-echo.log").find("estimate 5 ") == std::string::npos &&
           std::chrono::steady_clock::now() < end)
      std::this_thread::sleep_for(50ms);
    EXPECT_NE(text_of(kDir / "demo-echo.log").find("estimate 5 "), std::string::npos)
        << text_of(kDir / "demo-echo.log") << text_of(kDir / "demo-node.log");
    sim.signal(SIGTERM);
    node.signal(SIGTERM);
    echo.signal(SIGINT);
    EXPECT_EQ(sim.wait(20s), 0) << text_of(kDir / "demo-sim.log");
    EXPECT_EQ(node.wait(20s), 0) << text_of(kDir / "demo-node.log");
    EXPECT_EQ(echo.wait(20s), 0) << text_of(kDir / "demo-echo.log");
  }
  std::vector<std::string> left;
  for (const std::string& e : shm_entries())
    if (before.count(e) == 0)
      left.push_back(e);
  EXPECT_TRUE(left.empty()) << left.size() << " new entries in /dev/shm, the first " << left[0];
  EXPECT_NE(text_of(kDir / "demo-sim.log").find("(stopped by a signal)"), std::string::npos);
}

}  // namespace
