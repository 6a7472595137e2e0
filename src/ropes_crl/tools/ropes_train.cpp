// ropes-train: the three stages of ROPES on a dataset, into a run directory; resumable.
#include <ropes_crl/trainer.hpp>

#include <unistd.h>

#include <charconv>
#include <cstdio>
#include <iostream>
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
                     ae2.latent_dim=12), VALUE JSON; repeatable
  --sweep-lambda L   comma-separated lambdas: one run per lambda and seed, in
                     RUN/lambda-<L>_seed-<S>
  --sweep-seeds S    comma-separated seeds for the sweep (default: --seed)
  --progress MODE    bar, lines or auto (a bar on a terminal; the default)
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

// KEY=VALUE into the config's JSON; the key must exist (a misspelt key is an error)
void apply_override(nlohmann::json& config, const std::string& assignment) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw UsageError("--set '" + assignment + "': expected KEY=VALUE");
  const std::string key = assignment.substr(0, eq), text = assignment.substr(eq + 1);
  nlohmann::json value = nlohmann::json::parse(text, nullptr, false);
  if (value.is_discarded())
    value = text;  // a bare word is a string
  nlohmann::json* at = &config;
  std::size_t start = 0;
  while (true) {
    const std::size_t dot = key.find('.', start);
    const std::string part =
        key.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
    if (!at->is_object() || !at->contains(part))
      throw UsageError("--set " + key + ": the config has no '" + part + "' there");
    at = &(*at)[part];
    if (dot == std::string::npos)
      break;
    start = dot + 1;
  }
  *at = value;
}

int run(int argc, char** argv) {
  std::string config_arg, data, out, progress = "auto", sweep_lambda, sweep_seeds;
  std::vector<std::string> sets;
  ropes::crl::TrainOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--help" || flag == "-h") {
      std::cout << kUsage;
      return 0;
    }
    if (i + 1 >= argc)
      throw UsageError("'" + flag + "' needs a value (see --help)");
    const std::string value = argv[++i];
    if (flag == "--config")
      config_arg = value;
    else if (flag == "--data")
      data = value;
    else if (flag == "--out")
      out = value;
    else if (flag == "--threads")
      options.threads = parse_number<int>(flag, value);
    else if (flag == "--seed")
      options.seed = parse_number<std::uint64_t>(flag, value);
    else if (flag == "--set")
      sets.push_back(value);
    else if (flag == "--sweep-lambda")
      sweep_lambda = value;
    else if (flag == "--sweep-seeds")
      sweep_seeds = value;
    else if (flag == "--progress")
      progress = value;
    else
      throw UsageError("unknown option '" + flag + "' (see --help)");
  }
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
  if (sweep_lambda.empty()) {
    const auto config = ropes::crl::ExperimentConfig::from_json(raw, config_arg + " (with --set)");
    ropes::crl::train(config, data, out, options);
    std::fprintf(stderr, "ropes-train: %s complete\n", out.c_str());
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
  try {
    return run(argc, argv);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "ropes-train: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "\nropes-train: %s\n", e.what());
    return 1;
  }
}
