// experiment_config_fuzz: load_experiment_config on an arbitrary file, as ropes-train reads
// --config FILE. It either gives a config whose to_json() reads back to the same config, or
// is refused with core::ConfigError naming the file and the field, or core::FileFormatError
// for a file that is not JSON (the documented errors of this reader). Corpus: three of the
// installed configs.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "ropes_core/file_format_error.hpp"
#include "ropes_core/fuzz_input.hpp"
#include "ropes_crl/experiment_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes;
  static const core::fuzz::ScratchDir scratch;
  const auto file =
      scratch.write("config.json", std::string(reinterpret_cast<const char*>(data), size));
  crl::ExperimentConfig config;
  try {
    config = crl::load_experiment_config(file.string());
  } catch (const ropes::core::FileFormatError&) {  // ConfigError among them
    return 0;
  }
  // a config that loaded reads back: any exception here escapes as a finding
  const crl::ExperimentConfig again = crl::ExperimentConfig::from_json(config.to_json(), "again");
  if (again.to_json() != config.to_json())
    std::abort();
  return 0;
}
