// ropes-run: the whole job on one experiment config — generate the training set, train the
// three ROPES stages, evaluate the suites, write the report — with one progress display,
// resumable at and inside its stages (ropes_eval/main_job.hpp does the work).
#include <ropes_eval/main_job.hpp>
#include <ropes_sim/renderer.hpp>

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "cli.hpp"

namespace {

namespace fs = std::filesystem;
namespace tools = ropes::eval::tools;
using tools::parse_number;
using tools::UsageError;

const char* const kUsage = R"(usage: ropes-run CONFIG [options]

The ROPES main job on the experiment config CONFIG (a file or an installed name: 1c-small,
2c-small, 2c_causal-small, 1c-tiny, ...), into OUT:
  1 generate  the training set of the dataset config CONFIG names (1c-small: small-1c),
              seed --data-seed, in OUT/train-data (ropes-generate's generator)
  2 train     AE1, one LDR per joint, AE2 with the score-sparsity loss, in OUT/run
              (ropes-train's trainer)
  3 evaluate  the suites (ropes-eval --suite) on test sets generated into OUT/test-data,
              with the supervised baseline; OUT/report/results.json, results.md,
              report.html and calibration.json (ropes-stream --run OUT/run finds it)
It ends by printing the per-joint MCC / MSE table beside the paper's numbers and the path of
report.html. Run it again with the same arguments after an interruption: finished stages
are kept (OUT/ropes-run.json records them), generation and training resume inside
themselves (shards, checkpoints), and evaluation runs again on its cached test sets (also
when asked for with other evaluation arguments). Another config, seed, data seed or dataset
config in the same OUT is refused, naming it (another thread count is not: every count
gives the same bytes).

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

int run(int argc, char** argv) {
  ropes::eval::MainJobOptions job;
  std::string progress = "auto";
  ropes::eval::RunEvaluationOptions& eval = job.suites.evaluation;
  ropes::core::CommandLine command_line(kUsage);
  command_line
      .positional([&](const std::string& v) {
        if (!job.config.empty())
          throw UsageError("one CONFIG, got '" + job.config + "' and '" + v + "' (see --help)");
        job.config = v;
      })
      .option("--out", [&](const std::string& v) { job.out = v; })
      .option("--seed",
              [&](const std::string& v) { job.seed = parse_number<std::uint64_t>("--seed", v); })
      .option("--data-seed",
              [&](const std::string& v) {
                job.data_seed = parse_number<std::uint64_t>("--data-seed", v);
              })
      .option("--dataset-config", [&](const std::string& v) { job.dataset_config = v; })
      .option("--suite",
              [&](const std::string& v) { job.suites.suites = tools::parse_suites("--suite", v); })
      .option("--supervised",
              [&](const std::string& v) {
                job.suites.supervised = tools::parse_supervised("--supervised", v);
              })
      .option("--threads",
              [&](const std::string& v) { job.threads = parse_number<int>("--threads", v); })
      .option("--progress", [&](const std::string& v) {
        if (v != "bar" && v != "lines" && v != "auto")
          throw UsageError("--progress is '" + v + "'; expected bar, lines or auto");
        progress = v;
      });
  tools::add_protocol_options(command_line, eval);
  if (!command_line.parse(argc, argv))
    return 0;
  if (job.config.empty())
    throw UsageError("CONFIG is required (see --help)");
  if (job.threads < 1 || job.threads > 256)
    throw UsageError("--threads is " + std::to_string(job.threads) + "; expected 1..256");
  job.progress_bar = progress == "bar" || (progress == "auto" && ::isatty(2) != 0);

  const auto t0 = std::chrono::steady_clock::now();
  const auto say = [&](int stage, const std::string& line) {
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    char head[64];
    std::snprintf(head, sizeof head, "ropes-run [%d/3 %s %5.0f s] ", stage,
                  stage == 1   ? "generate"
                  : stage == 2 ? "train"
                               : "evaluate",
                  s);
    std::cout << head << line << std::endl;
  };
  const ropes::eval::MainJobResult r = ropes::eval::run_main_job(job, say);
  std::cout << r.table << "report: " << (r.report_dir / "report.html").string() << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ropes::sim::tune_malloc_for_rendering();
  return ropes::core::run_main("ropes-run", run, argc, argv);
}
