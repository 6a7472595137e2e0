// experiment_config_fuzz: load_experiment_config on an arbitrary file, as ropes-train reads
// --config FILE. It either gives a config whose to_json() reads back to the same config, or
// is refused with std::invalid_argument naming the file and the field (the documented
// error of this reader). Corpus: three of the installed configs.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "ropes_core/fuzz_input.hpp"
#include "ropes_crl/experiment_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes;
  static const core::fuzz::ScratchDir scratch;
  const auto file =
      scratch.write("config.json", std::string(reinterpret_cast<const char*>(data), size));
  try {
    const crl::ExperimentConfig config = crl::load_experiment_config(file.string());
    const crl::ExperimentConfig again = crl::ExperimentConfig::from_json(config.to_json(), "again");
    if (again.to_json() != config.to_json())
      std::abort();
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
