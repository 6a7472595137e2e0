// ropes-generate: renders one of the paper's interventional datasets (see
// dataset_generator.hpp), or a preview contact sheet of one anchor.

#include <charconv>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "ropes_sim/dataset_generator.hpp"
#include "ropes_sim/renderer.hpp"
#include "tool_common.hpp"

namespace {

namespace fs = std::filesystem;
using namespace ropes::sim::tools;

const char* const kUsage = R"(usage: ropes-generate --config C --out DIR --seed S [options]
       ropes-generate --config C --preview PNG [--seed S] [--anchor A]
       ropes-generate --config C --preview-extremes PNG [--seed S] [--anchors N]
       ropes-generate --config C --check-framing [--seed S] [--anchors N]

Renders the dataset of config C (a file, or the name of an installed config such as 1c or
2c) into DIR: manifest.json + shards/*.npy. Identical bytes for any --threads and --shard;
a killed run resumes when run again with the same arguments.

options:
  --anchors N            override the config's number of anchors
  --anchors-per-shard M  override the config's anchors per shard file
  --threads T            render on T threads (default 1)
  --shard k/N            write only shards with index % N == k (0 <= k < N); the run that
                         finds every shard present writes manifest.json
  --preview PNG          write a contact sheet of one anchor instead of a dataset
  --anchor A             the anchor of --preview (default 0)
  --preview-extremes PNG write, per camera, the samples of all anchors whose links reach
                         furthest left, right, up and down: the rig's framing check
  --check-framing        print, per camera, how far the link origins reach over every
                         sample (1 is the image's edge) and fail, naming the link and the
                         pose, when one leaves the image (generation checks it too)
  --scale S              --preview tile scale, an integer 1..16 (default 2)
)";

int run(int argc, char** argv) {
  std::string config_arg, out, preview, extremes;
  bool framing = false;
  std::uint64_t seed = 0, anchor = 0;
  bool have_seed = false;
  std::int64_t anchors = -1, per_shard = -1;
  int scale = 2;
  ropes::sim::GenerateOptions options;
  ropes::core::CommandLine command_line(kUsage);
  command_line.option("--config", [&](const std::string& v) { config_arg = v; })
      .option("--out", [&](const std::string& v) { out = v; })
      .option("--seed",
              [&](const std::string& v) {
                seed = parse_number<std::uint64_t>("--seed", v, 0, UINT64_MAX);
                have_seed = true;
              })
      .option("--anchors",
              [&](const std::string& v) {
                anchors = parse_number<std::int64_t>("--anchors", v, 1, 1LL << 40);
              })
      .option("--anchors-per-shard",
              [&](const std::string& v) {
                per_shard = parse_number<std::int64_t>("--anchors-per-shard", v, 1, 1LL << 20);
              })
      .option("--threads",
              [&](const std::string& v) {
                options.threads = parse_number<int>("--threads", v, 1, 256);
              })
      .option("--shard",
              [&](const std::string& value) {
                const auto slash = value.find('/');
                if (slash == std::string::npos)
                  throw UsageError("--shard is '" + value + "'; expected k/N");
                const std::string expected =
                    "--shard is '" + value + "'; expected k/N with 0 <= k < N";
                int k = -1, n = 0;
                const char* text = value.c_str();
                const auto a = std::from_chars(text, text + slash, k);
                const auto b = std::from_chars(text + slash + 1, text + value.size(), n);
                if (a.ec != std::errc() || a.ptr != text + slash || b.ec != std::errc() ||
                    b.ptr != text + value.size() || k < 0 || n < 1 || k >= n)
                  throw UsageError(expected);
                options.shard_index = k;
                options.shard_count = n;
              })
      .option("--preview", [&](const std::string& v) { preview = v; })
      .option("--preview-extremes", [&](const std::string& v) { extremes = v; })
      .flag("--check-framing", [&] { framing = true; })
      .option("--anchor",
              [&](const std::string& v) {
                anchor = parse_number<std::uint64_t>("--anchor", v, 0, UINT64_MAX);
              })
      .option("--scale",
              [&](const std::string& v) { scale = parse_number<int>("--scale", v, 1, 16); });
  if (!command_line.parse(argc, argv))
    return 0;
  if (config_arg.empty())
    throw UsageError("--config is required (see --help)");
  auto config = ropes::sim::DatasetConfig::load(find_config(config_arg));
  if (anchors > 0)
    config.anchors = anchors;
  if (per_shard > 0)
    config.anchors_per_shard = per_shard;

  if (framing) {
    if (!out.empty() || options.threads != 1 || options.shard_count != 1 || !preview.empty() ||
        !extremes.empty())
      throw UsageError(
          "--check-framing writes nothing: --out, --threads, --shard, --preview "
          "and --preview-extremes do not apply");
    for (const ropes::sim::FramingReach& f : ropes::sim::framing_reach(config, seed)) {
      char line[512];
      std::snprintf(
          line, sizeof line,
          "camera '%s': furthest link origin %.3f of the way to the edge ('%s', anchor %lld, %s)",
          f.camera.c_str(), f.reach, f.link.c_str(), static_cast<long long>(f.anchor),
          f.regime.c_str());
      std::cout << "ropes-generate: " << line << "\n";
    }
    ropes::sim::check_framing(config, seed);
    std::cout << "ropes-generate: every link origin stays in view over " << config.anchors
              << " anchors (seed " << seed << "; within " << ropes::sim::kFramingTolerancePixels
              << " px of the edge)\n";
    return 0;
  }
  if (!extremes.empty()) {
    if (!out.empty() || options.threads != 1 || options.shard_count != 1 || !preview.empty())
      throw UsageError(
          "--preview-extremes writes one PNG: --out, --threads, --shard and "
          "--preview do not apply");
    ropes::sim::write_extremes_preview(config, seed, extremes, scale);
    std::cout << "ropes-generate: wrote " << extremes << " (the extremes of " << config.anchors
              << " anchors, seed " << seed << ")\n";
    return 0;
  }
  if (!preview.empty()) {
    if (!out.empty() || options.threads != 1 || options.shard_count != 1)
      throw UsageError("--preview writes one PNG: --out, --threads and --shard do not apply");
    ropes::sim::write_preview(config, seed, anchor, preview, scale);
    std::cout << "ropes-generate: wrote " << preview << " (anchor " << anchor << ", seed " << seed
              << ")\n";
    return 0;
  }
  if (out.empty())
    throw UsageError("--out is required (see --help)");
  if (!have_seed)
    throw UsageError("--seed is required: a dataset is a function of config and seed");
  options.out = out;
  options.seed = seed;
  options.progress = [](int done, int total, const std::string& message) {
    std::cout << "ropes-generate: [" << done << "/" << total << "] " << message << std::endl;
  };
  const auto result = ropes::sim::generate_dataset(config, options);
  for (const auto& w : result.warnings)
    std::cerr << "ropes-generate: warning: " << w << "\n";
  std::cout << "ropes-generate: " << out << ": " << result.shards_written << " shards written, "
            << result.shards_skipped << " already there; "
            << (result.complete ? "dataset complete (manifest.json)"
                                : "waiting for the other --shard runs")
            << std::endl;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ropes::sim::tune_malloc_for_rendering();
  return ropes::core::run_main("ropes-generate", run, argc, argv);
}
