// ropes-eval --live: PoseEstimates matched with JointStates by frame sequence number.
#include "live.hpp"

#include <ropes_eval/correlation.hpp>
#include <ropes_msgs/dds.hpp>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <deque>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "cli.hpp"

namespace ropes::eval::tools {

namespace {

namespace msgs = ropes::msgs;
using Clock = std::chrono::steady_clock;

const char* const kLiveUsage = R"(usage: ropes-eval --live [options]

Subscribes to ropes/pose_estimates and ropes/joint_states, pairs each estimate with the
ground truth of its frame (PoseEstimate.frame_sequence_number = JointState.sequence_number)
and prints, every --every seconds, per estimated joint over the last --window pairs: the MCC
(|Pearson| of latent k and the true angle of joint k) and, for calibrated estimates, the RMSE
of the angle in radians. On exit (SIGINT, SIGTERM, --estimates or --timeout) writes the last
figures and the totals to --out.

options:
  --window N      pairs the figures are computed over (default 300)
  --every S       seconds between printed lines (default 1)
  --estimates N   exit after N pairs
  --timeout S     exit when nothing came for S seconds (default: never)
  --out FILE      where the figures go as JSON (default ropes-eval-live.json)
The domain is ROPES_DDS_DOMAIN (default 0); ROPES_DDS_LOOPBACK=1 keeps to this host.
)";

struct Pair {
  std::vector<double> latents, angles, truth;  // per estimated joint
  std::vector<bool> valid;
  double latency_ms = 0;
};

struct JointFigures {
  std::string name;
  double mcc = NAN, rmse = NAN;
  std::size_t n = 0, calibrated = 0;
};

class Live {
 public:
  explicit Live(std::size_t window) : window_(window) {}

  void on_truth(const msgs::JointState& s) {
    std::map<std::string, double> by_name;
    for (std::size_t i = 0; i < s.names().size() && i < s.positions().size(); ++i)
      by_name[s.names()[i]] = s.positions()[i];
    truth_[s.sequence_number()] = by_name;
    ++truths_;
    auto it = pending_.find(s.sequence_number());
    if (it != pending_.end()) {
      pair(it->second, by_name);
      pending_.erase(it);
    }
    while (truth_.size() > 10000)
      truth_.erase(truth_.begin());
  }

  void on_estimate(const msgs::PoseEstimate& e) {
    ++estimates_;
    rejected_ = e.rejected_frames();
    run_id_ = e.run_id();
    auto it = truth_.find(e.frame_sequence_number());
    if (it != truth_.end()) {
      pair(e, it->second);
    } else {
      pending_[e.frame_sequence_number()] = e;
      while (pending_.size() > 10000) {
        pending_.erase(pending_.begin());
        ++unmatched_;
      }
    }
  }

  std::vector<JointFigures> figures() const {
    std::vector<JointFigures> out;
    for (std::size_t k = 0; k < names_.size(); ++k) {
      JointFigures f;
      f.name = names_[k];
      Eigen::VectorXd x(static_cast<Eigen::Index>(pairs_.size()));
      Eigen::VectorXd y(x.size());
      double se = 0;
      for (std::size_t i = 0; i < pairs_.size(); ++i) {
        const Pair& p = pairs_[i];
        x[static_cast<Eigen::Index>(i)] = p.latents[k];
        y[static_cast<Eigen::Index>(i)] = p.truth[k];
        if (p.valid[k]) {
          se += (p.angles[k] - p.truth[k]) * (p.angles[k] - p.truth[k]);
          ++f.calibrated;
        }
      }
      f.n = pairs_.size();
      if (f.calibrated > 0)
        f.rmse = std::sqrt(se / static_cast<double>(f.calibrated));
      try {
        if (f.n >= 3)
          f.mcc = std::abs(ropes::eval::pearson(x, y));
      } catch (const std::invalid_argument&) {
        // constant over the window (the arm at rest): undefined
      }
      out.push_back(f);
    }
    return out;
  }

  std::string line() const {
    std::string out = std::to_string(matched_) + " pairs";
    char buf[160];
    for (const JointFigures& f : figures()) {
      std::snprintf(buf, sizeof buf, " | %s mcc %.3f rmse %.3f", f.name.c_str(), f.mcc, f.rmse);
      out += buf;
    }
    std::snprintf(buf, sizeof buf, " | latency %.2f ms | rejected %llu", mean_latency(),
                  static_cast<unsigned long long>(rejected_));
    return out + buf;
  }

  nlohmann::json to_json() const {
    nlohmann::json joints = nlohmann::json::array();
    auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
    for (const JointFigures& f : figures())
      joints.push_back({{"joint", f.name},
                        {"mcc", number(f.mcc)},
                        {"rmse_rad", number(f.rmse)},
                        {"pairs", f.n},
                        {"calibrated_pairs", f.calibrated}});
    return {{"run_id", run_id_},
            {"window", window_},
            {"estimates", estimates_},
            {"joint_states", truths_},
            {"pairs", matched_},
            {"unmatched_estimates", unmatched_ + pending_.size()},
            {"rejected_frames", rejected_},
            {"mean_latency_ms", number(mean_latency())},
            {"joints", joints}};
  }

  unsigned long long matched() const { return matched_; }

 private:
  void pair(const msgs::PoseEstimate& e, const std::map<std::string, double>& truth) {
    if (names_.empty())
      names_ = e.joint_names();
    Pair p;
    for (std::size_t k = 0; k < names_.size(); ++k) {
      const auto t = truth.find(names_[k]);
      if (t == truth.end() || k >= e.latents().size()) {
        ++unmatched_;  // the ground truth does not have this joint
        return;
      }
      p.truth.push_back(t->second);
      p.latents.push_back(e.latents()[k]);
      const bool valid = k < e.valid().size() && e.valid()[k] && k < e.joint_angles().size();
      p.valid.push_back(valid);
      p.angles.push_back(valid ? e.joint_angles()[k] : 0.0);
    }
    p.latency_ms = static_cast<double>(e.latency_ns()) / 1e6;
    latency_sum_ += p.latency_ms;
    pairs_.push_back(std::move(p));
    if (pairs_.size() > window_) {
      latency_sum_ -= pairs_.front().latency_ms;
      pairs_.pop_front();
    }
    ++matched_;
  }
  double mean_latency() const {
    return pairs_.empty() ? NAN : latency_sum_ / static_cast<double>(pairs_.size());
  }

  std::size_t window_;
  std::vector<std::string> names_;
  std::deque<Pair> pairs_;
  double latency_sum_ = 0;
  std::map<unsigned long long, std::map<std::string, double>> truth_;
  std::map<unsigned long long, msgs::PoseEstimate> pending_;
  unsigned long long estimates_ = 0, truths_ = 0, matched_ = 0, unmatched_ = 0, rejected_ = 0;
  std::string run_id_;
};

}  // namespace

int run_live(int argc, char** argv) {
  std::size_t window = 300;
  double every = 1, timeout = 0;
  long long limit = -1;
  std::string out = "ropes-eval-live.json";
  ropes::core::CommandLine command_line(kLiveUsage, "see ropes-eval --live --help");
  command_line
      .option("--window",
              [&](const std::string& v) { window = parse_number<std::size_t>("--window", v); })
      .option("--every", [&](const std::string& v) { every = parse_number<double>("--every", v); })
      .option("--estimates",
              [&](const std::string& v) { limit = parse_number<long long>("--estimates", v); })
      .option("--timeout",
              [&](const std::string& v) { timeout = parse_number<double>("--timeout", v); })
      .option("--out", [&](const std::string& v) { out = v; });
  if (!command_line.parse(argc, argv, 2))
    return 0;
  if (window < 3)
    throw UsageError("--window is " + std::to_string(window) + "; expected at least 3");
  if (!(every > 0) || timeout < 0 || (limit != -1 && limit < 1))
    throw UsageError("--every must be positive, --timeout and --estimates not negative");

  msgs::ShutdownSignals signals;
  msgs::Participant participant({"ropes-eval-live"});
  msgs::Subscriber<msgs::PoseEstimate> estimates(participant);
  msgs::Subscriber<msgs::JointState> truths(participant);
  std::fprintf(stderr, "ropes-eval: live on domain %d: %s against %s\n", participant.domain(),
               estimates.topic().c_str(), truths.topic().c_str());
  Live live(window);
  msgs::PoseEstimate e;
  msgs::JointState s;
  Clock::time_point last_print = Clock::now(), last_sample = Clock::now();
  int rc = 0;
  while (!signals.requested() &&
         (limit < 0 || live.matched() < static_cast<unsigned long long>(limit))) {
    bool got = false;
    while (truths.take(s, std::chrono::milliseconds(0))) {
      live.on_truth(s);
      got = true;
    }
    if (estimates.take(e, std::chrono::milliseconds(20))) {
      live.on_estimate(e);
      got = true;
    }
    const auto now = Clock::now();
    if (got)
      last_sample = now;
    else if (timeout > 0 && now - last_sample > std::chrono::duration<double>(timeout)) {
      std::fprintf(stderr, "ropes-eval: nothing came for %g s\n", timeout);
      rc = 3;
      break;
    }
    if (now - last_print > std::chrono::duration<double>(every)) {
      std::printf("%s\n", live.line().c_str());
      std::fflush(stdout);
      last_print = now;
    }
  }
  // what had already arrived when the loop ended counts too (up to --estimates)
  while (truths.take(s, std::chrono::milliseconds(0)))
    live.on_truth(s);
  while ((limit < 0 || live.matched() < static_cast<unsigned long long>(limit)) &&
         estimates.take(e, std::chrono::milliseconds(0)))
    live.on_estimate(e);
  std::printf("%s\n", live.line().c_str());
  write_text(out, live.to_json().dump(2) + "\n");
  std::fprintf(stderr, "ropes-eval: wrote %s\n", out.c_str());
  return rc;
}

}  // namespace ropes::eval::tools
