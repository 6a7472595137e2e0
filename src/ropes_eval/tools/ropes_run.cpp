// ropes-run: the whole job on one experiment config — generate the training set, train the
// three ROPES stages, evaluate the suites, write the report — with one progress display,
// resumable at and inside its stages.
#include <ropes_core/file_io.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_crl/experiment_config.hpp>
#include <ropes_crl/trainer.hpp>
#include <ropes_nn/parallel.hpp>
#include <ropes_sim/dataset_config.hpp>
#include <ropes_sim/dataset_generator.hpp>
#include <ropes_sim/renderer.hpp>

#include <nlohmann/json.hpp>

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "suites.hpp"
#include "test_data.hpp"

namespace {

namespace fs = std::filesystem;
namespace tools = ropes::eval::tools;
using tools::parse_number;
using tools::split_list;
using tools::UsageError;

const char* const kUsage = R"(usage: ropes-run CONFIG [options]

The ROPES main job on the experiment config CONFIG (a file or an installed name: 1c-small,
2c-small, 2c_causal-small, 1c-tiny, ...), into OUT:
  1 generate  the training set of the dataset config CONFIG names (1c-small: small-1c),
              seed --data-seed, in OUT/train-data (ropes-generate's generator)
  2 train     AE1, one LDR per joint, AE2 with the score-sparsity loss, in OUT/run
              (ropes-train's trainer)
  3 evaluate  the suites (ropes-eval --suite) on test sets generated into OUT/test-data,
              with the supervised baseline; OUT/report/results.json, results.md and
              report.html
It ends by printing the per-joint MCC / MSE table beside the paper's numbers and the path of
report.html. Run it again with the same arguments after an interruption: finished stages
are kept (OUT/ropes-run.json records them), generation and training resume inside
themselves (shards, checkpoints), and evaluation runs again on its cached test sets (also
when asked for with other evaluation arguments). Another config, seed, data seed, dataset
config or thread count in the same OUT is refused, naming it.

options:
  --out DIR             where everything goes (default runs/<the config's name>)
  --seed S              the training seed (default 0)
  --data-seed S         the training set's seed (default 0; the test sets take S + 1)
  --dataset-config D    the dataset config to generate (default: CONFIG's dataset.config)
  --suite LIST          the suites (default id,ood,occlusion; ood is skipped with a note
                        for one camera)
  --repeats R, --calibration-samples C, --test-samples N, --supervised LIST,
  --probe-steps N       as ropes-eval's
  --threads T           compute threads (default 1; every T gives the same bytes, a run
                        may resume at another)
  --progress MODE       bar, lines or auto (a bar on a terminal; the default)
)";

void write_text(const fs::path& path, const std::string& text) {
  tools::write_text(path, text);
}

nlohmann::json read_state(const fs::path& p) {
  if (!fs::exists(p))
    return nlohmann::json::object();
  const nlohmann::json j = ropes::core::parse_json_or_discarded(
      ropes::core::read_text_file(p, ropes::core::kMaxJsonFileBytes));
  const bool shaped = j.is_object() && j.value("format", "") == "ropes-run" &&
                      (!j.contains("identity") || j["identity"].is_object()) &&
                      (!j.contains("stages") || j["stages"].is_object());
  if (!shaped)
    throw std::runtime_error(p.string() +
                             ": not a ropes-run state file (format \"ropes-run\" with objects "
                             "\"identity\" and \"stages\"); remove it to start over");
  return j;
}

int run(int argc, char** argv) {
  std::string config_arg, out, dataset_config, progress = "auto";
  std::uint64_t seed = 0, data_seed = 0;
  int threads = 1;
  tools::SuiteArgs suites;
  suites.suites = {"id", "ood", "occlusion"};
  ropes::eval::RunEvaluationOptions eval;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--help" || flag == "-h") {
      std::cout << kUsage;
      return 0;
    }
    if (flag.rfind("--", 0) != 0) {
      if (!config_arg.empty())
        throw UsageError("one CONFIG, got '" + config_arg + "' and '" + flag + "' (see --help)");
      config_arg = flag;
      continue;
    }
    if (i + 1 >= argc)
      throw UsageError("'" + flag + "' needs a value (see --help)");
    const std::string value = argv[++i];
    if (flag == "--out")
      out = value;
    else if (flag == "--seed")
      seed = parse_number<std::uint64_t>(flag, value);
    else if (flag == "--data-seed")
      data_seed = parse_number<std::uint64_t>(flag, value);
    else if (flag == "--dataset-config")
      dataset_config = value;
    else if (flag == "--suite") {
      suites.suites = split_list(flag, value);
      tools::check_suites(suites.suites);
    } else if (flag == "--repeats")
      eval.repeats = parse_number<std::int64_t>(flag, value);
    else if (flag == "--calibration-samples")
      eval.calibration_samples = parse_number<std::int64_t>(flag, value);
    else if (flag == "--test-samples")
      eval.test_samples = parse_number<std::int64_t>(flag, value);
    else if (flag == "--supervised")
      suites.supervised = tools::parse_supervised(flag, value);
    else if (flag == "--probe-steps")
      eval.probe_steps = parse_number<std::int64_t>(flag, value);
    else if (flag == "--threads")
      threads = parse_number<int>(flag, value);
    else if (flag == "--progress") {
      if (value != "bar" && value != "lines" && value != "auto")
        throw UsageError("--progress is '" + value + "'; expected bar, lines or auto");
      progress = value;
    } else
      throw UsageError("unknown option '" + flag + "' (see --help)");
  }
  if (config_arg.empty())
    throw UsageError("CONFIG is required (see --help)");
  if (threads < 1 || threads > 256)
    throw UsageError("--threads is " + std::to_string(threads) + "; expected 1..256");
  if (eval.probe_steps < 0)
    throw UsageError("--probe-steps is " + std::to_string(eval.probe_steps) +
                     "; expected 0 or more");
  if (eval.repeats < 1 || eval.repeats > 10000 || eval.calibration_samples < 2 ||
      eval.test_samples < 2)
    throw UsageError("--repeats must be 1..10000 and the sample counts at least 2 (they are " +
                     std::to_string(eval.repeats) + ", " +
                     std::to_string(eval.calibration_samples) + " and " +
                     std::to_string(eval.test_samples) + ")");

  const ropes::crl::ExperimentConfig config = ropes::crl::load_experiment_config(config_arg);
  // the dataset config the experiment config names (1c-small: small-1c)
  if (dataset_config.empty())
    dataset_config = config.dataset_config;
  // found before anything is written, so that a misspelt name leaves no state behind
  const fs::path dataset_file = tools::installed_dataset_config(dataset_config);
  const fs::path dir = out.empty() ? fs::path("runs") / config.name : fs::path(out);
  const fs::path train_data = dir / "train-data", run_dir = dir / "run",
                 report_dir = dir / "report", state_file = dir / "ropes-run.json";
  // the threads, and the kernels' level (a bad ROPES_ISA is refused before anything is written)
  ropes::nn::set_num_threads(threads);
  fs::create_directories(dir);
  // OUT is the user's; what ropes-run makes inside it stays inside it
  for (const fs::path& inside : {train_data, run_dir, report_dir, dir / "test-data", state_file}) {
    std::error_code ec;
    if (fs::is_symlink(inside, ec))
      throw std::runtime_error(inside.string() +
                               " is a symbolic link; ropes-run writes only inside " + dir.string() +
                               " (remove the link)");
  }
  // the state: what this directory is for, and the stages finished
  nlohmann::json state = read_state(state_file);
  // not the thread count: every count gives the same bytes (ropes_nn/parallel.hpp)
  const nlohmann::json identity = {{"config", config.raw},
                                   {"dataset_config", dataset_config},
                                   {"seed", seed},
                                   {"data_seed", data_seed}};
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
            state_file.string() + ": this directory holds a run with another " + it.key() + " (" +
            state["identity"][it.key()].dump().substr(0, 80) + ", now " +
            it.value().dump().substr(0, 80) + "); use another --out or the same arguments");
  }
  state["format"] = "ropes-run";
  state["identity"] = identity;
  if (!state.contains("stages"))
    state["stages"] = nlohmann::json::object();
  auto save = [&] { write_text(state_file, state.dump(2) + "\n"); };
  save();
  const auto t0 = std::chrono::steady_clock::now();
  auto say = [&](int stage, const std::string& line) {
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    char head[64];
    std::snprintf(head, sizeof head, "ropes-run [%d/3 %s %5.0f s] ", stage,
                  stage == 1   ? "generate"
                  : stage == 2 ? "train"
                               : "evaluate",
                  s);
    std::cout << head << line << std::endl;
  };
  // a stage finished: recorded with where its output is and how long it took
  auto record = [&](const char* stage, const fs::path& where,
                    std::chrono::steady_clock::time_point since,
                    const nlohmann::json& extra = nlohmann::json::object()) {
    nlohmann::json entry = {
        {"complete", true},
        {"dir", where.string()},
        {"wall_s",
         std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count()}};
    entry.update(extra);
    state["stages"][stage] = entry;
    save();
  };
  auto finished = [&](const char* stage) {
    return state["stages"].contains(stage) && state["stages"][stage].value("complete", false);
  };

  // 1: the training set
  if (!finished("generate")) {
    const ropes::sim::DatasetConfig data = ropes::sim::DatasetConfig::load(dataset_file);
    ropes::sim::GenerateOptions g;
    g.out = train_data;
    g.seed = data_seed;
    g.threads = threads;
    g.progress = [&](int done, int total, const std::string&) {
      say(1, dataset_config + " (seed " + std::to_string(data_seed) + "): shard " +
                 std::to_string(done) + "/" + std::to_string(total));
    };
    const auto t = std::chrono::steady_clock::now();
    const ropes::sim::GenerateResult r = ropes::sim::generate_dataset(data, g);
    if (!r.complete)
      throw std::runtime_error(train_data.string() + ": not complete after generation");
    record("generate", train_data, t);
    say(1, "done: " + train_data.string());
  } else {
    say(1, "finished before: " + train_data.string());
  }

  // 2: the three stages of ROPES (they resume inside themselves)
  if (!finished("train")) {
    ropes::crl::TrainOptions t;
    t.seed = seed;
    t.threads = threads;
    t.progress_bar = progress == "bar" || (progress == "auto" && ::isatty(2) != 0);
    say(2, config.name + " (seed " + std::to_string(seed) + ") into " + run_dir.string());
    const auto at = std::chrono::steady_clock::now();
    ropes::crl::train(config, train_data, run_dir, t);
    record("train", run_dir, at);
    say(2, "done: " + run_dir.string());
  } else {
    say(2, "finished before: " + run_dir.string());
  }

  // 3: the suites, the supervised baseline and the report; evaluated again when asked for
  // with other evaluation arguments (it does not resume inside: its test sets are cached)
  const nlohmann::json evaluation = {{"suites", suites.suites},
                                     {"repeats", eval.repeats},
                                     {"calibration_samples", eval.calibration_samples},
                                     {"test_samples", eval.test_samples},
                                     {"probe_steps", eval.probe_steps},
                                     {"supervised", suites.supervised}};
  if (finished("evaluate") &&
      state["stages"]["evaluate"].value("arguments", nlohmann::json()) != evaluation) {
    say(3, "other evaluation arguments than last time: evaluating again");
    state["stages"].erase("evaluate");
  }
  std::string table;
  if (!finished("evaluate")) {
    suites.cache = dir / "test-data";
    const auto at = std::chrono::steady_clock::now();
    const tools::SuiteOutcome outcome =
        tools::run_suites(run_dir.string(), "", report_dir.string(), threads, eval, suites,
                          [&](const std::string& line) { say(3, line); });
    table = outcome.report.table();
    record("evaluate", report_dir, at, {{"arguments", evaluation}, {"table", table}});
  } else {
    say(3, "finished before: " + report_dir.string());
    table = state["stages"]["evaluate"].value("table", "");
  }
  std::cout << table << "report: " << (report_dir / "report.html").string() << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ropes::sim::tune_malloc_for_rendering();
  return ropes::core::run_main("ropes-run", run, argc, argv);
}
