// checkpoint_fuzz: load_checkpoint and load_module (strict, and not strict under "model.")
// of arbitrary file contents into the network of fuzz_module.hpp. Each either loads or is
// refused with a FileFormatError naming the file; a loaded checkpoint saves and loads back
// to the same step and progress. Corpus: checkpoints and weight files of that network
// (made by ropes_nn_fuzz_make_corpus).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_module.hpp"
#include "ropes_core/file_format_error.hpp"
#include "ropes_core/fuzz_input.hpp"
#include "ropes_nn/checkpoint.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes::nn;
  static const ropes::core::fuzz::ScratchDir scratch;
  scratch.clear();
  const auto file = scratch.write("checkpoint.safetensors",
                                  std::string(reinterpret_cast<const char*>(data), size));

  auto net = fuzz::fuzz_module();
  Adam adam(net->named_parameters());
  try {
    const LoadedCheckpoint loaded = load_checkpoint(file, *net, adam);
    const auto again = scratch.path() / "again.safetensors";
    save_checkpoint(again, *net, adam, loaded.schedule, loaded.progress, loaded.metadata);
    auto net2 = fuzz::fuzz_module();
    Adam adam2(net2->named_parameters());
    const LoadedCheckpoint reloaded = load_checkpoint(again, *net2, adam2);
    if (reloaded.step != loaded.step || reloaded.progress.epoch != loaded.progress.epoch ||
        reloaded.progress.position != loaded.progress.position ||
        reloaded.progress.seed != loaded.progress.seed || reloaded.metadata != loaded.metadata)
      std::abort();
  } catch (const ropes::core::FileFormatError&) {
  }
  for (const bool strict : {true, false}) {
    auto module = fuzz::fuzz_module();
    LoadOptions options;
    options.strict = strict;
    options.prefix = strict ? "" : "model.";
    try {
      load_module(*module, file, options);
    } catch (const ropes::core::FileFormatError&) {
    }
  }
  return 0;
}
