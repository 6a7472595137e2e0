// ropes-eval: how good is a trained run? Per-joint MCC and calibrated MSE on a held-out
// dataset, beside the paper's numbers and the baselines.
#include <ropes_core/npy.hpp>
#include <ropes_eval/evaluation_report.hpp>
#include <ropes_eval/html_report.hpp>
#include <ropes_eval/run_evaluation.hpp>
#include <ropes_eval/screening.hpp>
#include <ropes_eval/suites.hpp>
#include <ropes_eval/supervised.hpp>
#include <ropes_nn/parallel.hpp>
#include <ropes_sim/renderer.hpp>

#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli.hpp"
#ifdef ROPES_EVAL_LIVE
#include "live.hpp"
#endif

namespace {

namespace fs = std::filesystem;

const char* const kUsage = R"(usage: ropes-eval --run RUN --data DIR [options]
       ropes-eval --run RUN --suite id,ood,causal,occlusion [--out REPORT] [options]
       ropes-eval --run RUN --screen [--out FILE] [--probe-steps N] [--seed S] [--threads T]
       ropes-eval --live [options]   (streamed estimates over DDS: ropes-eval --live --help)

Evaluates the trained run in RUN on the observational samples of the dataset in DIR (one
the run did not train on: generate it with another --seed), by the paper's protocol: each
of R repeats draws C labelled calibration samples and N disjoint test samples. Prints per
joint the mean and standard deviation over the repeats of the MCC (|Pearson| of latent k
and joint k) and of the MSE in rad^2 of the affine calibration of joint k from latent k,
beside the paper's numbers, the best-assignment MCC, Spearman, the calibration from every
latent, the lambda = 0 autoencoder, the LDR logit and supervised probes from AE1's code.
Writes RUN-eval/results.json (or --out FILE), results.md beside it (the tables laid out like
the paper's) and calibration.json beside it (repeat 0's affine fit, for the Estimator and
ropes-stream). Nothing is written into RUN: RUN-eval is the directory beside it, named after
it (runs/a -> runs/a-eval), and an --out inside RUN is refused.

With --suite, evaluates the run on each suite named (comma-separated) and writes
REPORT/results.json, results.md, report.html and, with the id suite, calibration.json
(default REPORT: RUN-eval/report):
  id         a test set of the training config with another seed (--test-seed)
  ood        the paper's OOD test set (its OOD observational table; two cameras only)
  causal     the causal SEM's test set (two cameras only)
  occlusion  each of id / ood / causal asked for (id when none is) again, with a white square
             of each --occlusion-sizes side painted into every camera image at seeded places
The test sets are generated with ropes_sim's generator (as ropes-generate does) into
--data-cache, one directory per config and seed; a second run generates nothing.
--data DIR, given with --suite, is the id test set instead of a generated one.

With --screen, screens AE1 before any AE2 trains (a run of `ropes-train --stages ae1,ldr`
will do; a finished run too): per joint, the share of the angle's variance (R^2) that a
supervised probe from AE1's code explains, fitted on 80 % of the training set's anchors and
scored on the rest (a linear and an MLP probe; these labels serve the diagnostic only), and
the LDR's held-out accuracy against the Bayes accuracy of its interventions. Prints the
table and writes RUN-eval/screen.json (or --out FILE) and screen.md beside it.

options:
  --out FILE                results file (default RUN-eval/results.json; the .md and
                            calibration.json beside it); with --suite the report directory
                            (default RUN-eval/report); with --screen the screening's file
                            (default RUN-eval/screen.json)
  --screen                  screen AE1 and the LDRs (see above)
  --suite LIST              the suites (see above)
  --data-cache DIR          where test sets are generated (default $ROPES_DATA_CACHE, else
                            $XDG_CACHE_HOME/ropes/test-data, else ~/.cache/ropes/test-data)
  --dataset-config FILE     the training set's dataset config, when it is not installed
                            (a robot of your own): the suites generate from it
  --test-seed S             the generated test sets' seed (default: the training set's + 1)
  --occlusion-sizes LIST    the occlusion squares' sides in pixels (default 16,32,64)
  --supervised LIST         the supervised baseline's labelled percentages of the training
                            set (default 1,5,10,100; none: no baseline)
  --supervised-max-steps N  cap its optimiser steps (default: none; for quick looks)
  --repeats R               draws of a calibration and a test set (default 15)
  --calibration-samples C   labelled samples a repeat fits on (default 1000)
  --test-samples N          samples a repeat scores on, disjoint from those (default 500)
  --seed S                  the draws' and the probe's seed (default 0)
  --probe-steps N           MLP probe training steps (default 3000; 0: none)
  --threads T               compute threads (default 1)
)";

using ropes::eval::tools::parse_number;
using ropes::eval::tools::split_list;
using ropes::eval::tools::UsageError;
using ropes::eval::tools::write_text;
namespace tools = ropes::eval::tools;

int run(int argc, char** argv) {
  std::string run_dir, data, out;
  int threads = 1;
  ropes::eval::RunEvaluationOptions options;
  ropes::eval::SuiteOptions suite_args;
  suite_args.suites.clear();
  bool screen = false;
  if (argc > 1 && std::string(argv[1]) == "--live") {
#ifdef ROPES_EVAL_LIVE
    return tools::run_live(argc, argv);
#else
    throw UsageError("--live: this ropes-eval was built without Fast DDS (ROPES_WITH_DDS)");
#endif
  }
  ropes::core::CommandLine command_line(kUsage);
  command_line.flag("--screen", [&] { screen = true; })
      .option("--run", [&](const std::string& v) { run_dir = v; })
      .option("--data", [&](const std::string& v) { data = v; })
      .option("--out", [&](const std::string& v) { out = v; })
      .option(
          "--seed",
          [&](const std::string& v) { options.seed = parse_number<std::uint64_t>("--seed", v); })
      .option("--threads",
              [&](const std::string& v) { threads = parse_number<int>("--threads", v); })
      .option("--suite",
              [&](const std::string& v) { suite_args.suites = tools::parse_suites("--suite", v); })
      .option("--data-cache", [&](const std::string& v) { suite_args.cache = v; })
      .option("--dataset-config", [&](const std::string& v) { suite_args.dataset_config = v; })
      .option("--test-seed",
              [&](const std::string& v) {
                suite_args.test_seed = parse_number<std::uint64_t>("--test-seed", v);
              })
      .option("--occlusion-sizes",
              [&](const std::string& value) {
                const std::string flag = "--occlusion-sizes";
                suite_args.occlusion_sizes.clear();
                for (const std::string& v : split_list(flag, value)) {
                  const auto size = parse_number<std::int64_t>(flag, v);
                  if (size < 1)
                    throw UsageError(flag + " has " + v + "; expected sides of at least 1 px");
                  suite_args.occlusion_sizes.push_back(size);
                }
              })
      .option("--supervised",
              [&](const std::string& v) {
                suite_args.supervised = tools::parse_supervised("--supervised", v);
              })
      .option("--supervised-max-steps", [&](const std::string& v) {
        suite_args.supervised_max_steps = parse_number<std::int64_t>("--supervised-max-steps", v);
        if (suite_args.supervised_max_steps < 1)
          throw UsageError("--supervised-max-steps is " + v + "; expected at least 1");
      });
  tools::add_protocol_options(command_line, options);
  if (!command_line.parse(argc, argv))
    return 0;
  if (screen && (!data.empty() || !suite_args.suites.empty()))
    throw UsageError("--screen takes no --data or --suite: it reads the run's training set");
  if (run_dir.empty() || (data.empty() && suite_args.suites.empty() && !screen))
    throw UsageError("--run and either --data, --suite or --screen are required (see --help)");
  if (threads < 1 || threads > 256)
    throw UsageError("--threads is " + std::to_string(threads) + "; expected 1..256");
  ropes::nn::set_num_threads(threads);
  if (screen) {
    ropes::eval::ScreeningOptions so;
    so.probe_steps = options.probe_steps;
    so.seed = options.seed;
    const fs::path results = tools::evaluation_output(run_dir, out, "screen.json");
    const ropes::eval::Screening sc = ropes::eval::screen_run(run_dir, so);
    if (results.has_parent_path())
      fs::create_directories(results.parent_path());
    write_text(results, sc.to_json().dump(2) + "\n");
    fs::path markdown = results;
    markdown.replace_extension(".md");
    if (markdown == results)
      markdown += ".md";
    write_text(markdown, sc.markdown());
    std::cout << sc.table() << "screening: " << results.string() << " and " << markdown.string()
              << "\n";
    return 0;
  }
  if (!suite_args.suites.empty()) {
    suite_args.data = data;
    suite_args.out = tools::evaluation_output(run_dir, out, "report");
    suite_args.threads = threads;
    suite_args.evaluation = options;
    const ropes::eval::SuiteOutcome outcome = ropes::eval::run_suites(
        run_dir, suite_args,
        [](const std::string& line) { std::cout << "ropes-eval: " << line << std::endl; });
    std::cout << outcome.report.table()
              << "results: " << (outcome.report_dir / "results.json").string() << " and "
              << (outcome.report_dir / "results.md").string()
              << "\nreport: " << (outcome.report_dir / "report.html").string() << "\n";
    return 0;
  }
  const fs::path results = tools::evaluation_output(run_dir, out, "results.json");
  if (results.filename() == "calibration.json")
    throw UsageError("--out " + out +
                     ": the calibration is written beside the results as calibration.json; "
                     "name the results file otherwise");
  const ropes::eval::RunEvaluation ev = ropes::eval::evaluate_run(run_dir, data, options);
  const ropes::eval::EvaluationFiles files = ropes::eval::write_evaluation(ev, results);
  std::cout << ev.table() << "results: " << files.results.string() << " and "
            << files.markdown.string() << "\ncalibration: " << files.calibration.string() << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ropes::sim::tune_malloc_for_rendering();
  return ropes::core::run_main("ropes-eval", run, argc, argv);
}
