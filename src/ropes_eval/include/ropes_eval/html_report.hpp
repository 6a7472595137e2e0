#pragma once
/// @file html_report.hpp
/// report.html: one self-contained file (inline SVG plots, images as data: URIs, no
/// JavaScript, nothing fetched) that shows an EvaluationReport the way papers in this field
/// do: per-joint scatter plots of the estimate against the ground truth on each suite's best
/// repeat (as the paper's scatter figures), the suites' MSE beside the paper's, the occlusion
/// figure (input, occluded input, AE1's reconstruction, AE2's reconstruction decoded through
/// AE1), an intervention image grid (one anchor in every regime and camera), the training
/// curves from metrics.jsonl, the sparsity matrices as heat maps, and the label-efficiency
/// curve of the supervised baseline when the report has one.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "ropes_eval/evaluation_report.hpp"

namespace ropes::eval {

/// A grey image: [height, width] bytes, row-major.
struct ReportImage {
  std::string label;
  int width = 0, height = 0;
  std::vector<std::uint8_t> grey;
};

/// The report's images, gathered from a run and a test set.
struct ReportImages {
  std::int64_t occlusion = 0;  ///< the square's side in the occlusion figure
  std::vector<std::string> occlusion_columns;
  std::vector<std::vector<ReportImage>> occlusion_rows;  ///< one row per sample and camera
  std::vector<std::string> regime_names;
  std::vector<std::vector<ReportImage>> intervention_rows;  ///< one row per camera
};

/// The occlusion figure for the first `samples` observational samples of the dataset in
/// `data_dir` (squares of `occlusion` px placed by `seed` as the occlusion suite places them;
/// the AE2 is that of the run's first joint) and the intervention grid of anchor 0. Throws
/// as evaluate_run does for a dataset that does not fit the run.
ReportImages collect_report_images(const std::filesystem::path& run_dir,
                                   const std::filesystem::path& data_dir, std::int64_t occlusion,
                                   std::uint64_t seed, std::int64_t samples = 3);

/// report.html's text. `run_dir` holds run.json (sparsity matrices) and metrics.jsonl
/// (training curves); a missing metrics.jsonl, or one without losses, leaves its section
/// saying so.
std::string html_report(const EvaluationReport& report, const std::filesystem::path& run_dir,
                        const ReportImages& images);

}  // namespace ropes::eval
