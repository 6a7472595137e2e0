#include "ropes_eval/main_job.hpp"

#include <ropes_core/file_io.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_crl/experiment_config.hpp>
#include <ropes_crl/trainer.hpp>
#include <ropes_nn/parallel.hpp>
#include <ropes_sim/dataset_config.hpp>
#include <ropes_sim/dataset_generator.hpp>

#include <nlohmann/json.hpp>

#include <chrono>
#include <stdexcept>
#include <system_error>

#include "ropes_eval/test_data.hpp"

namespace ropes::eval {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

// OUT/ropes-run.json: {"format": "ropes-run", "identity": {...}, "stages": {...}}
nlohmann::json read_state(const fs::path& p) {
  if (!fs::exists(p))
    return nlohmann::json::object();
  const nlohmann::json j =
      core::parse_json_or_discarded(core::read_text_file(p, core::kMaxJsonFileBytes));
  const bool shaped = j.is_object() && j.value("format", "") == "ropes-run" &&
                      (!j.contains("identity") || j["identity"].is_object()) &&
                      (!j.contains("stages") || j["stages"].is_object());
  if (!shaped)
    throw std::runtime_error(p.string() +
                             ": not a ropes-run state file (format \"ropes-run\" with objects "
                             "\"identity\" and \"stages\"); remove it to start over");
  return j;
}

void check(const MainJobOptions& o) {
  const RunEvaluationOptions& e = o.suites.evaluation;
  if (o.threads < 1 || o.threads > 256)
    throw std::invalid_argument("threads is " + std::to_string(o.threads) + "; expected 1..256");
  check_protocol(e);
  check_suites(o.suites.suites);
}

}  // namespace

MainJobResult run_main_job(const MainJobOptions& options,
                           const std::function<void(int, const std::string&)>& log_to) {
  const auto log = [&log_to](int stage, const std::string& line) {
    if (log_to)
      log_to(stage, line);
  };
  check(options);
  const crl::ExperimentConfig config = crl::load_experiment_config(options.config);
  // the dataset config the experiment config names (1c-small: small-1c)
  const std::string dataset_config =
      options.dataset_config.empty() ? config.dataset_config : options.dataset_config;
  // found before anything is written, so that a misspelt name leaves no state behind; a
  // path in an experiment config file is relative to that file (a robot of the user's own)
  fs::path dataset_file;
  const bool is_path = dataset_config.find('/') != std::string::npos ||
                       fs::path(dataset_config).extension() == ".json";
  if (options.dataset_config.empty() && is_path && core::is_regular_file(options.config) &&
      fs::path(dataset_config).is_relative()) {
    dataset_file = fs::path(options.config).parent_path() / dataset_config;
    if (!core::is_regular_file(dataset_file))
      throw std::invalid_argument(options.config + ": dataset.config is '" + dataset_config +
                                  "': " + dataset_file.string() + " does not exist");
  } else {
    dataset_file = installed_dataset_config(dataset_config);
  }
  MainJobResult r;
  r.dir = options.out.empty() ? fs::path("runs") / config.name : options.out;
  r.train_data = r.dir / "train-data";
  r.run_dir = r.dir / "run";
  r.report_dir = r.dir / "report";
  r.state_file = r.dir / "ropes-run.json";
  // the threads, and the kernels' level (a bad ROPES_ISA is refused before anything is written)
  nn::set_num_threads(options.threads);
  fs::create_directories(r.dir);
  // OUT is the user's; what the job makes inside it stays inside it
  for (const fs::path& inside :
       {r.train_data, r.run_dir, r.report_dir, r.dir / "test-data", r.state_file}) {
    std::error_code ec;
    if (fs::is_symlink(inside, ec))
      throw std::runtime_error(inside.string() +
                               " is a symbolic link; ropes-run writes only inside " +
                               r.dir.string() + " (remove the link)");
  }
  // the state: what this directory is for, and the stages finished
  nlohmann::json state = read_state(r.state_file);
  // not the thread count: every count gives the same bytes (ropes_nn/parallel.hpp)
  const nlohmann::json identity = {{"config", config.raw},
                                   {"dataset_config", dataset_config},
                                   {"seed", options.seed},
                                   {"data_seed", options.data_seed}};
  // the identity binds the directory once a stage has finished
  bool any_finished = false;
  if (state.contains("stages"))
    for (auto it = state["stages"].begin(); it != state["stages"].end(); ++it)
      any_finished =
          any_finished || (it.value().is_object() && it.value().value("complete", false));
  if (any_finished && state.contains("identity") && state["identity"] != identity) {
    for (auto it = identity.begin(); it != identity.end(); ++it)
      if (state["identity"].value(it.key(), nlohmann::json()) != it.value())
        throw std::runtime_error(
            r.state_file.string() + ": this directory holds a run with another " + it.key() + " (" +
            state["identity"][it.key()].dump().substr(0, 80) + ", now " +
            it.value().dump().substr(0, 80) + "); use another --out or the same arguments");
  }
  state["format"] = "ropes-run";
  state["identity"] = identity;
  if (!state.contains("stages"))
    state["stages"] = nlohmann::json::object();
  auto save = [&] { core::write_text_file_atomically(r.state_file, state.dump(2) + "\n"); };
  save();
  // a stage finished: recorded with where its output is and how long it took
  auto record = [&](const char* stage, const fs::path& where, Clock::time_point since,
                    const nlohmann::json& extra = nlohmann::json::object()) {
    nlohmann::json entry = {
        {"complete", true},
        {"dir", where.string()},
        {"wall_s", std::chrono::duration<double>(Clock::now() - since).count()}};
    entry.update(extra);
    state["stages"][stage] = entry;
    save();
  };
  auto finished = [&](const char* stage) {
    return state["stages"].contains(stage) && state["stages"][stage].value("complete", false);
  };

  // 1: the training set
  if (!finished("generate")) {
    const sim::DatasetConfig data = sim::DatasetConfig::load(dataset_file);
    sim::GenerateOptions g;
    g.out = r.train_data;
    g.seed = options.data_seed;
    g.threads = options.threads;
    g.progress = [&](int done, int total, const std::string&) {
      log(1, dataset_config + " (seed " + std::to_string(options.data_seed) + "): shard " +
                 std::to_string(done) + "/" + std::to_string(total));
    };
    const auto t = Clock::now();
    const sim::GenerateResult generated = sim::generate_dataset(data, g);
    if (!generated.complete)
      throw std::runtime_error(r.train_data.string() + ": not complete after generation");
    record("generate", r.train_data, t);
    log(1, "done: " + r.train_data.string());
  } else {
    log(1, "finished before: " + r.train_data.string());
  }

  // 2: the three stages of ROPES (they resume inside themselves)
  if (!finished("train")) {
    crl::TrainOptions t;
    t.seed = options.seed;
    t.threads = options.threads;
    t.progress_bar = options.progress_bar;
    if (options.on_training_record)
      t.on_metrics = [&options](const nlohmann::json&) { options.on_training_record(); };
    log(2, config.name + " (seed " + std::to_string(options.seed) + ") into " + r.run_dir.string());
    const auto at = Clock::now();
    crl::train(config, r.train_data, r.run_dir, t);
    record("train", r.run_dir, at);
    log(2, "done: " + r.run_dir.string());
  } else {
    log(2, "finished before: " + r.run_dir.string());
  }

  // 3: the suites, the supervised baseline and the report; evaluated again when asked for
  // with other evaluation arguments (it does not resume inside: its test sets are cached)
  const RunEvaluationOptions& eval = options.suites.evaluation;
  const nlohmann::json evaluation = {{"suites", options.suites.suites},
                                     {"repeats", eval.repeats},
                                     {"calibration_samples", eval.calibration_samples},
                                     {"test_samples", eval.test_samples},
                                     {"probe_steps", eval.probe_steps},
                                     {"seed", eval.seed},
                                     {"occlusion_sizes", options.suites.occlusion_sizes},
                                     {"supervised", options.suites.supervised},
                                     {"supervised_max_steps", options.suites.supervised_max_steps}};
  if (finished("evaluate") &&
      state["stages"]["evaluate"].value("arguments", nlohmann::json()) != evaluation) {
    log(3, "other evaluation arguments than last time: evaluating again");
    state["stages"].erase("evaluate");
  }
  if (!finished("evaluate")) {
    SuiteOptions suites = options.suites;
    suites.out = r.report_dir;
    suites.cache = r.dir / "test-data";
    suites.data.clear();
    suites.dataset_config = dataset_file;
    suites.test_seed.reset();
    suites.threads = options.threads;
    const auto at = Clock::now();
    const SuiteOutcome outcome =
        run_suites(r.run_dir, suites, [&](const std::string& line) { log(3, line); });
    r.table = outcome.report.table();
    r.evaluated = true;
    record("evaluate", r.report_dir, at, {{"arguments", evaluation}, {"table", r.table}});
  } else {
    log(3, "finished before: " + r.report_dir.string());
    r.table = state["stages"]["evaluate"].value("table", "");
  }
  return r;
}

}  // namespace ropes::eval
