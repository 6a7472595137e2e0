// ropes-eval: how good is a trained run? Per-joint MCC and calibrated MSE on a held-out
// dataset, beside the paper's numbers and the baselines.
#include <ropes_eval/run_evaluation.hpp>
#include <ropes_nn/npy.hpp>
#include <ropes_nn/parallel.hpp>

#include <charconv>
#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <string>

namespace {

namespace fs = std::filesystem;

const char* const kUsage = R"(usage: ropes-eval --run RUN --data DIR [options]

Evaluates the trained run in RUN on the observational samples of the dataset in DIR (one
the run did not train on: generate it with another --seed), by the paper's protocol: each
of R repeats draws C labelled calibration samples and N disjoint test samples. Prints per
joint the mean and standard deviation over the repeats of the MCC (|Pearson| of latent k
and joint k) and of the MSE in rad^2 of the affine calibration of joint k from latent k,
beside the paper's numbers, the best-assignment MCC, Spearman, the calibration from every
latent, the lambda = 0 autoencoder, the LDR logit and supervised probes from AE1's code.
Writes RUN/results.json (or --out FILE), results.md beside it (the tables laid out like the
paper's), and RUN/calibration.json (repeat 0's affine fit, for the Estimator).

options:
  --out FILE                results file (default RUN/results.json; the .md beside it)
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

int run(int argc, char** argv) {
  std::string run_dir, data, out;
  int threads = 1;
  ropes::eval::RunEvaluationOptions options;
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
    else
      throw UsageError("unknown option '" + flag + "' (see --help)");
  }
  if (run_dir.empty() || data.empty())
    throw UsageError("--run and --data are required (see --help)");
  if (options.repeats < 1 || options.repeats > 10000)
    throw UsageError("--repeats is " + std::to_string(options.repeats) + "; expected 1..10000");
  if (options.calibration_samples < 2 || options.test_samples < 2)
    throw UsageError("--calibration-samples and --test-samples must be at least 2 (they are " +
                     std::to_string(options.calibration_samples) + " and " +
                     std::to_string(options.test_samples) + ")");
  if (threads < 1 || threads > 256)
    throw UsageError("--threads is " + std::to_string(threads) + "; expected 1..256");
  ropes::nn::set_num_threads(threads);
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
