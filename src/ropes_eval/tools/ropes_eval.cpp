// ropes-eval: how good is a trained run? Per-joint MCC and calibrated MSE on a held-out
// dataset, beside the paper's numbers and the baselines.
#include <ropes_eval/evaluation_report.hpp>
#include <ropes_eval/html_report.hpp>
#include <ropes_eval/run_evaluation.hpp>
#include <ropes_eval/supervised.hpp>
#include <ropes_nn/npy.hpp>
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

#include "test_data.hpp"

namespace {

namespace fs = std::filesystem;

const char* const kUsage = R"(usage: ropes-eval --run RUN --data DIR [options]
       ropes-eval --run RUN --suite id,ood,causal,occlusion [--out REPORT] [options]

Evaluates the trained run in RUN on the observational samples of the dataset in DIR (one
the run did not train on: generate it with another --seed), by the paper's protocol: each
of R repeats draws C labelled calibration samples and N disjoint test samples. Prints per
joint the mean and standard deviation over the repeats of the MCC (|Pearson| of latent k
and joint k) and of the MSE in rad^2 of the affine calibration of joint k from latent k,
beside the paper's numbers, the best-assignment MCC, Spearman, the calibration from every
latent, the lambda = 0 autoencoder, the LDR logit and supervised probes from AE1's code.
Writes RUN/results.json (or --out FILE), results.md beside it (the tables laid out like the
paper's), and RUN/calibration.json (repeat 0's affine fit, for the Estimator).

With --suite, evaluates the run on each suite named (comma-separated) and writes
REPORT/results.json, REPORT/results.md and REPORT/report.html (default REPORT: RUN/report):
  id         a test set of the training config with another seed (--test-seed)
  ood        the paper's OOD test set (its OOD observational table; two cameras only)
  causal     the causal SEM's test set (two cameras only)
  occlusion  each of id / ood / causal asked for (id when none is) again, with a white square
             of each --occlusion-sizes side painted into every camera image at seeded places
The test sets are generated with ropes_sim's generator (as ropes-generate does) into
--data-cache, one directory per config and seed; a second run generates nothing.
--data DIR, given with --suite, is the id test set instead of a generated one.

options:
  --out FILE                results file (default RUN/results.json; the .md beside it);
                            with --suite the report directory (default RUN/report)
  --suite LIST              the suites (see above)
  --data-cache DIR          where test sets are generated (default $ROPES_DATA_CACHE, else
                            $XDG_CACHE_HOME/ropes/test-data, else ~/.cache/ropes/test-data)
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

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

template <class T>
T parse_number(const std::string& flag, const std::string& text) {
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size())
    throw UsageError(flag + " is '" + text + "'; expected a number");
  return value;
}

void write_text(const fs::path& path, const std::string& text) {
  ropes::nn::write_file_atomically(path, reinterpret_cast<const std::uint8_t*>(text.data()),
                                   text.size());
}

std::vector<std::string> split_list(const std::string& flag, const std::string& text) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = text.find(',', start);
    const std::string item =
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (item.empty())
      throw UsageError(flag + " is '" + text + "'; expected a comma-separated list");
    out.push_back(item);
    if (comma == std::string::npos)
      break;
    start = comma + 1;
  }
  return out;
}

fs::path default_cache() {
  if (const char* c = std::getenv("ROPES_DATA_CACHE"); c != nullptr && *c != 0)
    return c;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x != nullptr && *x != 0)
    return fs::path(x) / "ropes" / "test-data";
  if (const char* h = std::getenv("HOME"); h != nullptr && *h != 0)
    return fs::path(h) / ".cache" / "ropes" / "test-data";
  throw UsageError("no --data-cache, and neither ROPES_DATA_CACHE, XDG_CACHE_HOME nor HOME is set");
}

struct SuiteArgs {
  std::vector<std::string> suites;
  fs::path cache;
  bool have_test_seed = false;
  std::uint64_t test_seed = 0;
  std::vector<std::int64_t> occlusion_sizes = {16, 32, 64};
  std::vector<double> supervised = {0.01, 0.05, 0.10, 1.0};  // fractions of labelled rows
  std::int64_t supervised_max_steps = 0;
};

// --suite: every suite asked for, its test set generated or found in the cache
int run_suites(const std::string& run_dir, const std::string& data, const std::string& out,
               int threads, ropes::eval::RunEvaluationOptions options, const SuiteArgs& args) {
  namespace tools = ropes::eval::tools;
  std::set<std::string> wanted;
  for (const std::string& s : args.suites) {
    if (s != "id" && s != "ood" && s != "causal" && s != "occlusion")
      throw UsageError("--suite names '" + s + "'; expected id, ood, causal or occlusion");
    wanted.insert(s);
  }
  const fs::path report_dir = out.empty() ? fs::path(run_dir) / "report" : fs::path(out);
  const fs::path cache = args.cache.empty() ? default_cache() : args.cache;
  // the training set's seed: the test sets default to the next one
  std::uint64_t test_seed = args.test_seed;
  if (!args.have_test_seed) {
    std::ifstream in(fs::path(run_dir) / "run.json");
    const nlohmann::json run = nlohmann::json::parse(in, nullptr, false);
    const fs::path manifest =
        fs::path(run.is_object() ? run.value("data_dir", "") : "") / "manifest.json";
    std::ifstream m(manifest);
    const nlohmann::json j = nlohmann::json::parse(m, nullptr, false);
    test_seed = (j.is_object() && j.contains("/metadata/seed"_json_pointer)
                     ? j["/metadata/seed"_json_pointer].get<std::uint64_t>()
                     : 0) +
                1;
  }
  ropes::eval::EvaluationReport report;
  // the supervised baselines, trained once and scored on every suite
  std::vector<ropes::eval::SupervisedEncoder> supervised;
  for (double f : args.supervised) {
    ropes::eval::SupervisedOptions so;
    so.seed = options.seed;
    so.max_steps = args.supervised_max_steps;
    supervised.push_back(ropes::eval::SupervisedEncoder::train(run_dir, f, so));
    const ropes::eval::SupervisedEncoder& e = supervised.back();
    report.supervised.push_back({f, e.labels(), e.steps(), e.final_loss()});
    std::cout << "ropes-eval: supervised baseline on " << e.labels() << " labelled samples ("
              << 100.0 * f << " %): " << e.steps() << " steps, last epoch's loss " << e.final_loss()
              << std::endl;
  }
  for (const ropes::eval::SupervisedEncoder& e : supervised)
    options.supervised.push_back(&e);
  std::vector<std::string> distributions;
  for (const char* d : {"id", "ood", "causal"})
    if (wanted.count(d) != 0)
      distributions.push_back(d);
  const bool occlusion = wanted.count("occlusion") != 0;
  if (distributions.empty())
    distributions.push_back("id");
  fs::path id_data;
  for (const std::string& d : distributions) {
    tools::TestData test;
    if (d == "id" && !data.empty()) {
      test.dir = data;
      test.config_name = "--data";
    } else {
      tools::TestDataRequest request;
      request.run_dir = run_dir;
      request.distribution = d;
      request.min_observational = options.calibration_samples + options.test_samples;
      request.seed = test_seed;
      request.cache = cache;
      request.threads = threads;
      request.log = [](const std::string& line) {
        std::cout << "ropes-eval: " << line << std::endl;
      };
      try {
        test = tools::ensure_test_data(request);
      } catch (const std::invalid_argument& e) {
        if (d == "id")
          throw;
        report.notes.push_back(d + ": " + e.what() +
                               " (the paper defines OOD and causal test sets for two cameras)");
        std::cout << "ropes-eval: " << report.notes.back() << std::endl;
        continue;
      }
      std::cout << "ropes-eval: " << d << " test set " << test.dir.string() << " ("
                << (test.shards_written == 0
                        ? "from the cache"
                        : std::to_string(test.shards_written) + " shards generated")
                << ")" << std::endl;
    }
    if (d == "id")
      id_data = test.dir;
    std::vector<std::int64_t> sizes = {0};
    if (occlusion)
      sizes.insert(sizes.end(), args.occlusion_sizes.begin(), args.occlusion_sizes.end());
    for (std::int64_t size : sizes) {
      ropes::eval::RunEvaluationOptions o = options;
      o.occlusion = size;
      o.occlusion_seed = options.seed;
      // the diagnostics' MLP probe: on the clean id suite only
      if (!(d == "id" && size == 0))
        o.probe_steps = 0;
      ropes::eval::SuiteResult s;
      s.name = d + (size > 0 ? " occlusion " + std::to_string(size) : "");
      s.distribution = d;
      s.occlusion = size;
      s.data_config = test.config_name;
      std::cout << "ropes-eval: evaluating " << s.name << std::endl;
      s.evaluation = ropes::eval::evaluate_run(run_dir, test.dir, o);
      report.suites.push_back(std::move(s));
    }
  }
  const std::string setting = report.suites.front().evaluation.setting;
  const nlohmann::json paper = ropes::eval::paper_suite_numbers(setting, options.paper_results);
  report.paper_appendix = paper["appendix"];
  report.paper_table1_occlusion = paper["table1_occlusion"];
  report.paper_robopepp = paper["robopepp"];
  fs::create_directories(report_dir);
  write_text(report_dir / "results.json", report.to_json().dump(2) + "\n");
  write_text(report_dir / "results.md", report.markdown());
  // report.html: the occlusion figure at the middle size asked (the paper's 32 px by default)
  if (!id_data.empty()) {
    std::int64_t figure = 32;
    if (occlusion && !args.occlusion_sizes.empty())
      figure = args.occlusion_sizes[args.occlusion_sizes.size() / 2];
    const ropes::eval::ReportImages images =
        ropes::eval::collect_report_images(run_dir, id_data, figure, options.seed);
    write_text(report_dir / "report.html", ropes::eval::html_report(report, run_dir, images));
  }
  const ropes::eval::SuiteResult* id = report.find("id");
  if (id != nullptr)
    write_text(fs::path(run_dir) / "calibration.json", id->evaluation.calibration.dump(2) + "\n");
  std::cout << report.table() << "results: " << (report_dir / "results.json").string() << " and "
            << (report_dir / "results.md").string()
            << "\nreport: " << (report_dir / "report.html").string() << "\n";
  return 0;
}

int run(int argc, char** argv) {
  std::string run_dir, data, out;
  int threads = 1;
  ropes::eval::RunEvaluationOptions options;
  SuiteArgs suite_args;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--help" || flag == "-h") {
      std::cout << kUsage;
      return 0;
    }
    if (i + 1 >= argc)
      throw UsageError("'" + flag + "' needs a value (see --help)");
    const std::string value = argv[++i];
    if (flag == "--run")
      run_dir = value;
    else if (flag == "--data")
      data = value;
    else if (flag == "--out")
      out = value;
    else if (flag == "--repeats")
      options.repeats = parse_number<std::int64_t>(flag, value);
    else if (flag == "--calibration-samples")
      options.calibration_samples = parse_number<std::int64_t>(flag, value);
    else if (flag == "--test-samples")
      options.test_samples = parse_number<std::int64_t>(flag, value);
    else if (flag == "--seed")
      options.seed = parse_number<std::uint64_t>(flag, value);
    else if (flag == "--probe-steps")
      options.probe_steps = parse_number<std::int64_t>(flag, value);
    else if (flag == "--threads")
      threads = parse_number<int>(flag, value);
    else if (flag == "--suite")
      suite_args.suites = split_list(flag, value);
    else if (flag == "--data-cache")
      suite_args.cache = value;
    else if (flag == "--test-seed") {
      suite_args.test_seed = parse_number<std::uint64_t>(flag, value);
      suite_args.have_test_seed = true;
    } else if (flag == "--occlusion-sizes") {
      suite_args.occlusion_sizes.clear();
      for (const std::string& v : split_list(flag, value)) {
        const auto size = parse_number<std::int64_t>(flag, v);
        if (size < 1)
          throw UsageError("--occlusion-sizes has " + v + "; expected sides of at least 1 px");
        suite_args.occlusion_sizes.push_back(size);
      }
    } else if (flag == "--supervised") {
      suite_args.supervised.clear();
      if (value != "none")
        for (const std::string& v : split_list(flag, value)) {
          const auto pct = parse_number<double>(flag, v);
          if (!(pct > 0 && pct <= 100))
            throw UsageError("--supervised has " + v + "; expected percentages in (0, 100]");
          suite_args.supervised.push_back(pct / 100.0);
        }
    } else if (flag == "--supervised-max-steps") {
      suite_args.supervised_max_steps = parse_number<std::int64_t>(flag, value);
    } else
      throw UsageError("unknown option '" + flag + "' (see --help)");
  }
  if (run_dir.empty() || (data.empty() && suite_args.suites.empty()))
    throw UsageError("--run and either --data or --suite are required (see --help)");
  if (options.repeats < 1 || options.repeats > 10000)
    throw UsageError("--repeats is " + std::to_string(options.repeats) + "; expected 1..10000");
  if (options.calibration_samples < 2 || options.test_samples < 2)
    throw UsageError("--calibration-samples and --test-samples must be at least 2 (they are " +
                     std::to_string(options.calibration_samples) + " and " +
                     std::to_string(options.test_samples) + ")");
  if (threads < 1 || threads > 256)
    throw UsageError("--threads is " + std::to_string(threads) + "; expected 1..256");
  ropes::nn::set_num_threads(threads);
  if (!suite_args.suites.empty())
    return run_suites(run_dir, data, out, threads, options, suite_args);
  const ropes::eval::RunEvaluation ev = ropes::eval::evaluate_run(run_dir, data, options);
  const fs::path results = out.empty() ? fs::path(run_dir) / "results.json" : fs::path(out);
  write_text(results, ev.to_json().dump(2) + "\n");
  fs::path markdown = results;
  markdown.replace_extension(".md");
  if (markdown == results)  // --out something.md: keep both
    markdown += ".md";
  write_text(markdown, ev.markdown());
  write_text(fs::path(run_dir) / "calibration.json", ev.calibration.dump(2) + "\n");
  std::cout << ev.table() << "results: " << results.string() << " and " << markdown.string()
            << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ropes::sim::tune_malloc_for_rendering();
  try {
    return run(argc, argv);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "ropes-eval: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ropes-eval: %s\n", e.what());
    return 1;
  }
}
