// ropes-train: the three stages of ROPES on a dataset, into a run directory; resumable.
#include <ropes_core/cli.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_crl/trainer.hpp>
#ifdef ROPES_TRAIN_STATUS
#include <ropes_msgs/dds.hpp>
#endif

#include <unistd.h>

#include <charconv>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

const char* const kUsage = R"(usage: ropes-train --config C --data DIR --out RUN [options]

Trains AE1 on every image of the dataset in DIR, one LDR classifier per intervened joint,
and AE2 with the score-sparsity loss (ROPES, section 3), into RUN: weights (*.safetensors),
metrics.jsonl and run.json. Run again with the same arguments after a kill, it resumes.
C is a file or an installed config name (1c-tiny, 1c-small, 1c-paper, 2c-small, ...).

options:
  --threads T        compute threads (default 1); a resumed run must use the same T
  --seed S           the run's seed (default 0)
  --set KEY=VALUE    override a config value, KEY a dotted path (ae2.lambda=10,
                     ae2.latent_dim=12), VALUE JSON; repeatable; an optional key the
                     config leaves out may be set too (ae1.code_head=linear)
  --sweep-lambda L   comma-separated lambdas: one run per lambda and seed, in
                     RUN/lambda-<L>_seed-<S>
  --sweep-seeds S    comma-separated seeds for the sweep (default: --seed)
  --progress MODE    bar, lines or auto (a bar on a terminal; the default)
  --stages LIST      ae1, ae1,ldr or ae1,ldr,ae2 (the default): stop after AE1 and its
                     codes, or after the LDRs, to screen an AE1 with ropes-eval --screen
                     before training AE2; the same command without --stages continues
  --status           publish the run's progress as RunStatus on the DDS topic
                     ropes/run_status (ropes-echo run_status prints it); needs a build
                     with Fast DDS
)";

using ropes::core::parse_number;
using ropes::core::UsageError;

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= s.size()) {
    const std::size_t comma = s.find(',', start);
    out.push_back(s.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos)
      break;
    start = comma + 1;
  }
  return out;
}

// whether the config, without `key` (a dotted path whose parent is an object), would read it:
// with the key added it is not refused as an unknown key
bool optional_key_of(const nlohmann::json& config, const std::string& key) {
  nlohmann::json trial = config;
  nlohmann::json* at = &trial;
  std::size_t start = 0;
  for (std::size_t dot = key.find('.'); dot != std::string::npos; dot = key.find('.', start)) {
    const std::string part = key.substr(start, dot - start);
    if (!at->is_object() || !at->contains(part))
      return false;
    at = &(*at)[part];
    start = dot + 1;
  }
  if (!at->is_object())
    return false;
  (*at)[key.substr(start)] = nullptr;
  try {
    ropes::crl::ExperimentConfig::from_json(trial, "--set");
  } catch (const std::exception& e) {
    return std::string(e.what()).find("config." + key + ": unknown key") == std::string::npos;
  }
  return true;
}

// KEY=VALUE into the config's JSON; the key must exist, or be an optional key the config
// reads (ae1.code_head, ldr.input_normalization, ...): a misspelt key is an error
void apply_override(nlohmann::json& config, const std::string& assignment) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw UsageError("--set '" + assignment + "': expected KEY=VALUE");
  const std::string key = assignment.substr(0, eq), text = assignment.substr(eq + 1);
  nlohmann::json value = ropes::core::parse_json_or_discarded(text);
  if (value.is_discarded())
    value = text;  // a bare word is a string
  nlohmann::json* at = &config;
  std::size_t start = 0;
  while (true) {
    const std::size_t dot = key.find('.', start);
    const std::string part =
        key.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
    const bool last = dot == std::string::npos;
    if (!at->is_object() || (!at->contains(part) && !(last && optional_key_of(config, key))))
      throw UsageError("--set " + key + ": the config has no '" + part + "' there");
    at = &(*at)[part];
    if (last)
      break;
    start = dot + 1;
  }
  *at = value;
}

#ifdef ROPES_TRAIN_STATUS
// the run id: the run directory's name ("a/b/" is "b")
std::string run_name(const fs::path& out) {
  const fs::path p = fs::absolute(out).lexically_normal();
  return p.has_filename() ? p.filename().string() : p.parent_path().filename().string();
}

// RunStatus from the run's metrics records: the stage's step and total, its losses and an
// ETA from the stage's pace since its first record in this process
class StatusPublisher {
 public:
  StatusPublisher(const ropes::crl::ExperimentConfig& config, std::string run_id)
      : participant_({"ropes-train"}), pub_(participant_), run_id_(std::move(run_id)) {
    totals_["ae1"] = config.ae1_training.steps;
    totals_["ldr"] = config.ldr_training.max_epochs;
    totals_["ae2"] = config.ae2_training.steps;
    std::fprintf(stderr, "ropes-train: publishing RunStatus on %s, domain %d\n",
                 ropes::msgs::kRunStatusTopic, participant_.domain());
    // a watcher started before the run sees its first records (discovery takes a moment)
    pub_.wait_for_matched(1, std::chrono::seconds(3));
  }
  void on_record(const nlohmann::json& r) {
    const std::lock_guard<std::mutex> lock(mutex_);
    const std::string kind = r.value("stage", std::string("?"));
    std::string stage = kind;
    for (const char* part : {"joint", "model"})
      if (r.contains(part) && r[part].is_string())
        stage += " " + r[part].get<std::string>();
    const std::int64_t step = r.contains("step") && r["step"].is_number_integer()
                                  ? r["step"].get<std::int64_t>()
                                  : r.value("epoch", std::int64_t{0});
    const auto total = totals_.count(kind) ? totals_[kind] : 0;
    std::vector<std::string> names;
    std::vector<double> values;
    for (const auto& [key, value] : r.items())
      if (value.is_number_float()) {
        names.push_back(key);
        values.push_back(value.get<double>());
      }
    const auto now = std::chrono::steady_clock::now();
    auto& [t0, s0] = first_.try_emplace(stage, now, step).first->second;
    double eta = -1;
    if (step > s0 && total > 0)
      eta = std::chrono::duration<double>(now - t0).count() / static_cast<double>(step - s0) *
            static_cast<double>(std::max<std::int64_t>(total - step, 0));
    send(stage, step, total, names, values, eta);
  }
  void finish(const std::string& stage) {
    const std::lock_guard<std::mutex> lock(mutex_);
    send(stage, 0, 0, {}, {}, 0);
    pub_.wait_for_acknowledgments(std::chrono::seconds(2));
  }

 private:
  void send(const std::string& stage, std::int64_t step, std::int64_t total,
            const std::vector<std::string>& names, const std::vector<double>& values, double eta) {
    ropes::msgs::RunStatus s;
    s.stamp_ns(ropes::msgs::now_ns());
    s.run_id(run_id_);
    s.stage(stage);
    s.step(step);
    s.total_steps(total);
    s.loss_names(names);
    s.loss_values(values);
    s.eta_s(eta);
    pub_.write(s, std::chrono::milliseconds(200));  // a stuck reader never stalls training
  }
  ropes::msgs::Participant participant_;
  ropes::msgs::Publisher<ropes::msgs::RunStatus> pub_;
  std::string run_id_;
  std::map<std::string, std::int64_t> totals_;
  std::map<std::string, std::pair<std::chrono::steady_clock::time_point, std::int64_t>> first_;
  std::mutex mutex_;
};
#endif

int run(int argc, char** argv) {
  std::string config_arg, data, out, progress = "auto", sweep_lambda, sweep_seeds;
  std::vector<std::string> sets;
  ropes::crl::TrainOptions options;
  bool status = false;
  ropes::core::CommandLine command_line(kUsage);
  command_line
      .flag("--status",
            [&] {
#ifdef ROPES_TRAIN_STATUS
              status = true;
#else
              throw UsageError(
                  "--status: this ropes-train was built without Fast DDS (ROPES_WITH_DDS)");
#endif
            })
      .option("--config", [&](const std::string& v) { config_arg = v; })
      .option("--data", [&](const std::string& v) { data = v; })
      .option("--out", [&](const std::string& v) { out = v; })
      .option("--threads",
              [&](const std::string& v) { options.threads = parse_number<int>("--threads", v); })
      .option(
          "--seed",
          [&](const std::string& v) { options.seed = parse_number<std::uint64_t>("--seed", v); })
      .option("--set", [&](const std::string& v) { sets.push_back(v); })
      .option("--sweep-lambda", [&](const std::string& v) { sweep_lambda = v; })
      .option("--sweep-seeds", [&](const std::string& v) { sweep_seeds = v; })
      .option("--progress", [&](const std::string& v) { progress = v; })
      .option("--stages", [&](const std::string& value) {
        if (value == "ae1")
          options.last_stage = 1;
        else if (value == "ae1,ldr")
          options.last_stage = 2;
        else if (value == "ae1,ldr,ae2")
          options.last_stage = 3;
        else
          throw UsageError("--stages is '" + value +
                           "'; expected ae1, ae1,ldr or ae1,ldr,ae2 (each stage needs the ones "
                           "before it)");
      });
  if (!command_line.parse(argc, argv))
    return 0;
  if (config_arg.empty() || data.empty() || out.empty())
    throw UsageError("--config, --data and --out are required (see --help)");
  if (options.threads < 1 || options.threads > 256)
    throw UsageError("--threads is " + std::to_string(options.threads) + "; expected 1..256");
  if (progress != "auto" && progress != "bar" && progress != "lines")
    throw UsageError("--progress is '" + progress + "'; expected bar, lines or auto");
  options.progress_bar = progress == "bar" || (progress == "auto" && ::isatty(2));

  ropes::crl::ExperimentConfig base = ropes::crl::load_experiment_config(config_arg);
  nlohmann::json raw = base.raw;
  for (const std::string& s : sets)
    apply_override(raw, s);
  if (status && !sweep_lambda.empty())
    throw UsageError("--status is for one run, not a --sweep-lambda sweep");
  if (sweep_lambda.empty()) {
    const auto config = ropes::crl::ExperimentConfig::from_json(raw, config_arg + " (with --set)");
#ifdef ROPES_TRAIN_STATUS
    std::unique_ptr<StatusPublisher> publisher;
    if (status) {
      publisher = std::make_unique<StatusPublisher>(config, run_name(out));
      options.on_metrics = [&](const nlohmann::json& r) { publisher->on_record(r); };
    }
    try {
      ropes::crl::train(config, data, out, options);
    } catch (...) {
      if (publisher)
        publisher->finish("failed");
      throw;
    }
    if (publisher)
      publisher->finish(options.last_stage == 3   ? "complete"
                        : options.last_stage == 2 ? "stopped after ldr (--stages)"
                                                  : "stopped after ae1 (--stages)");
#else
    (void)status;
    ropes::crl::train(config, data, out, options);
#endif
    if (options.last_stage == 3)
      std::fprintf(stderr, "ropes-train: %s complete\n", out.c_str());
    else
      std::fprintf(stderr, "ropes-train: %s: stages up to %s done; run without --stages to go on\n",
                   out.c_str(), options.last_stage == 1 ? "ae1" : "ldr");
    return 0;
  }
  // the sweep: every lambda x seed, one run directory each, in order
  const std::vector<std::string> seeds =
      sweep_seeds.empty() ? std::vector<std::string>{std::to_string(options.seed)}
                          : split(sweep_seeds);
  for (const std::string& l : split(sweep_lambda)) {
    nlohmann::json r = raw;
    r["ae2"]["lambda"] = parse_number<double>("--sweep-lambda", l);
    const auto config = ropes::crl::ExperimentConfig::from_json(r, config_arg + " (sweep)");
    for (const std::string& s : seeds) {
      ropes::crl::TrainOptions o = options;
      o.seed = parse_number<std::uint64_t>("--sweep-seeds", s);
      const fs::path dir = fs::path(out) / ("lambda-" + l + "_seed-" + s);
      std::fprintf(stderr, "ropes-train: sweep run %s\n", dir.c_str());
      ropes::crl::train(config, data, dir, o);
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return ropes::core::run_main("ropes-train", run, argc, argv);
}
