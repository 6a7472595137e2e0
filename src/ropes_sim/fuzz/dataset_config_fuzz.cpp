// dataset_config_fuzz: a dataset config and its sampling distribution from arbitrary JSON,
// checked as ropes-generate checks them: DatasetConfig::load, InterventionSampler::load of
// the distribution, and one anchor drawn from it. The input's sections
// (ropes_core/fuzz_input.hpp): "" is configs/config.json, "distribution" is
// distributions/distribution.json; urdf/panda.urdf is the workspace's own Panda. Each either
// loads or is refused with a ConfigError naming the file, the field and the value.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>

#include "ropes_core/fuzz_input.hpp"
#include "ropes_sim/dataset_config.hpp"
#include "ropes_sim/intervention_sampler.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes;
  static const core::fuzz::ScratchDir scratch;
  static const std::string panda = [] {
    std::ifstream in(std::string(ROPES_SIM_URDF_DIR) + "/panda.urdf", std::ios::binary);
    if (!in)
      std::abort();
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }();
  static const std::map<std::string, std::string> files = {
      {"", "configs/config.json"}, {"distribution", "distributions/distribution.json"}};
  scratch.clear();
  scratch.write("urdf/panda.urdf", panda);
  for (const core::fuzz::Section& section : core::fuzz::split_sections(data, size)) {
    const auto it = files.find(section.name);
    if (it != files.end())
      scratch.write(it->second, section.bytes);
  }
  try {
    const sim::DatasetConfig config =
        sim::DatasetConfig::load(scratch.path() / "configs/config.json");
    if (config.anchors < 1 || config.anchors_per_shard < 1)
      std::abort();
    config.to_json();
  } catch (const sim::ConfigError&) {
  }
  try {
    const sim::InterventionSampler sampler =
        sim::InterventionSampler::load(scratch.path() / "distributions/distribution.json");
    const auto anchor = sampler.sample_anchor(1, 0);
    if (anchor.size() != sampler.regime_names().size())
      std::abort();
  } catch (const sim::ConfigError&) {
  }
  return 0;
}
