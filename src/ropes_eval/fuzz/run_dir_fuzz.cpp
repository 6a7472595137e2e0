// run_dir_fuzz: a run directory from arbitrary bytes, read as ropes-eval and ropes-stream
// read one: Estimator::load (run.json, its config, the weight files it names), the
// calibration ropes-eval writes (Calibration::from_json) and report.html's training curves
// and sparsity matrices (html_report, reading run.json and metrics.jsonl). The input's
// sections (ropes_core/fuzz_input.hpp): "" is run.json, "metrics" metrics.jsonl,
// "calibration" calibration.json. Each either works or is refused with FileFormatError or
// std::invalid_argument (the documented errors) naming the file. Corpus: the text files of
// a real 1c-tiny run (ropes-generate --config tiny-1c --seed 0, ropes-train --config 1c-tiny
// --seed 0, metrics.jsonl cut to 8 records), whose weight files fuzz/run_dir_weights/ holds:
// they are linked into every input's directory, so that a run.json that still describes
// them gets past the weights to the networks (the checkpoint harness fuzzes weight files).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>

#include "ropes_core/file_format_error.hpp"
#include "ropes_core/fuzz_input.hpp"
#include "ropes_crl/estimator.hpp"
#include "ropes_eval/evaluation_report.hpp"
#include "ropes_eval/html_report.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes;
  static const core::fuzz::ScratchDir scratch;
  static const std::map<std::string, std::string> files = {
      {"", "run.json"}, {"metrics", "metrics.jsonl"}, {"calibration", "calibration.json"}};
  scratch.clear();
  for (const auto& entry : std::filesystem::directory_iterator(ROPES_EVAL_FUZZ_WEIGHTS))
    std::filesystem::create_symlink(entry.path(), scratch.path() / entry.path().filename());
  std::string calibration;
  for (const core::fuzz::Section& section : core::fuzz::split_sections(data, size)) {
    const auto it = files.find(section.name);
    if (it != files.end())
      scratch.write(it->second, section.bytes);
    if (section.name == "calibration")
      calibration = section.bytes;
  }
  try {
    crl::Estimator::load(scratch.path());
  } catch (const core::FileFormatError&) {
  } catch (const std::invalid_argument&) {
  }
  const nlohmann::json j = nlohmann::json::parse(calibration, nullptr, false);
  if (!j.is_discarded()) {
    try {
      crl::Calibration::from_json(j);
    } catch (const std::invalid_argument&) {
    }
  }
  try {
    const std::string html = eval::html_report(eval::EvaluationReport{}, scratch.path(), {});
    if (html.empty())
      std::abort();
  } catch (const core::FileFormatError&) {
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
