#include "ropes_eval/suites.hpp"

#include <ropes_core/dataset.hpp>
#include <ropes_core/file_io.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_crl/calibration.hpp>
#include <ropes_crl/dataset_version.hpp>
#include <ropes_crl/run_directory.hpp>
#include <ropes_eval/html_report.hpp>
#include <ropes_eval/screening.hpp>
#include <ropes_eval/supervised.hpp>
#include <ropes_sim/dataset_config.hpp>
#include <ropes_sim/rig_renderer.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>

#include "ropes_eval/test_data.hpp"

namespace ropes::eval {

namespace fs = std::filesystem;

void check_suites(const std::vector<std::string>& suites) {
  for (const std::string& s : suites)
    if (s != "id" && s != "ood" && s != "causal" && s != "occlusion")
      throw std::invalid_argument("'" + s +
                                  "' is not a suite; expected id, ood, causal or occlusion");
}

fs::path default_test_data_cache() {
  if (const char* c = std::getenv("ROPES_DATA_CACHE"); c != nullptr && *c != 0)
    return c;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x != nullptr && *x != 0)
    return fs::path(x) / "ropes" / "test-data";
  if (const char* h = std::getenv("HOME"); h != nullptr && *h != 0)
    return fs::path(h) / ".cache" / "ropes" / "test-data";
  throw std::invalid_argument(
      "no test data cache given, and neither ROPES_DATA_CACHE, XDG_CACHE_HOME nor HOME is set");
}

namespace {

// run.json's image side and the training set's seed, each checked
struct RunFacts {
  std::int64_t image_side = 0, cameras = 1;
  std::uint64_t train_seed = 0;
  bool have_train_seed = false;
};

RunFacts run_facts(const crl::RunDirectory& run) {
  RunFacts f;
  f.image_side = run.config().image_size;
  f.cameras = run.config().cameras;
  const fs::path manifest = run.data_dir() / "manifest.json";
  const nlohmann::json j = core::read_json_file_if_present(manifest, core::kMaxManifestBytes);
  const nlohmann::json::json_pointer seed("/metadata/seed");
  if (j.is_object() && j.contains(seed)) {
    if (!j[seed].is_number_unsigned())
      throw std::invalid_argument(manifest.string() + ": metadata.seed is " +
                                  core::describe(j[seed]) + "; expected a non-negative integer");
    f.train_seed = j[seed].get<std::uint64_t>();
    f.have_train_seed = true;
  }
  return f;
}

// The robot's silhouettes of a test set's samples, rendered with the rig of the config it was
// made from: RunEvaluationOptions::robot_masks. Null, with the reason in `why`, for a test
// set passed with --data (no config) or one whose angles columns are not the rig's joints.
struct RobotMasks {
  std::unique_ptr<ropes::sim::RigRenderer> rig;
  std::vector<std::size_t> column_of_joint;  // the rig's joint i is the dataset's column
  std::string why;
};

std::shared_ptr<RobotMasks> robot_masks_of(const TestData& test) {
  auto out = std::make_shared<RobotMasks>();
  if (test.config_file.empty()) {
    out->why = "a test set passed with --data has no config to render the robot's silhouette";
    return out;
  }
  const fs::path manifest = test.dir / "manifest.json";
  const nlohmann::json j =
      core::parse_json_or_discarded(core::read_text_file(manifest, core::kMaxJsonFileBytes));
  const nlohmann::json::json_pointer names("/metadata/joint_names");
  if (!j.is_object() || !j.contains(names) || !j[names].is_array()) {
    out->why = manifest.string() + " has no metadata.joint_names";
    return out;
  }
  const std::vector<std::string> columns = j[names].get<std::vector<std::string>>();
  auto rig =
      std::make_unique<ropes::sim::RigRenderer>(ropes::sim::DatasetConfig::load(test.config_file));
  for (const std::string& joint : rig->joint_names()) {
    const auto at = std::find(columns.begin(), columns.end(), joint);
    if (at == columns.end()) {
      out->why = manifest.string() + ": the rig's joint " + joint + " is not an angles column";
      return out;
    }
    out->column_of_joint.push_back(static_cast<std::size_t>(at - columns.begin()));
  }
  // the silhouettes are laid out as the test set's images: the same cameras and size
  const std::vector<std::int64_t> shape =
      core::DatasetReader::open(test.dir).column("images").row_shape;
  if (shape != std::vector<std::int64_t>{rig->cameras(), rig->height(), rig->width()}) {
    out->why = manifest.string() + ": its images are not the rig's cameras and size";
    return out;
  }
  out->rig = std::move(rig);
  return out;
}

}  // namespace

SuiteOutcome run_suites(const fs::path& run_dir, const SuiteOptions& args,
                        const std::function<void(const std::string&)>& log_to) {
  check_suites(args.suites);
  check_protocol(args.evaluation);  // before anything is read or generated
  const auto log = [&log_to](const std::string& line) {
    if (log_to)
      log_to(line);
  };
  RunEvaluationOptions options = args.evaluation;
  const fs::path& data = args.data;
  const int threads = args.threads;
  const std::set<std::string> wanted(args.suites.begin(), args.suites.end());
  const fs::path report_dir = crl::evaluation_output(run_dir, args.out, "report");
  const crl::RunDirectory run = crl::RunDirectory::open(run_dir);
  const RunFacts facts = run_facts(run);
  // a run trained on a dataset of the old TN(mean, x) reading: refused before anything runs
  ropes::crl::require_run_of_current_sim_dataset(run);
  EvaluationReport report;
  const bool occlusion = wanted.count("occlusion") != 0;
  // occlusion squares larger than the image are left out with a note
  std::vector<std::int64_t> occlusion_sizes;
  for (std::int64_t size : occlusion ? args.occlusion_sizes : std::vector<std::int64_t>{}) {
    if (facts.image_side > 0 && size > facts.image_side)
      report.notes.push_back("occlusion " + std::to_string(size) + ": larger than the run's " +
                             std::to_string(facts.image_side) + " px images");
    else
      occlusion_sizes.push_back(size);
  }
  // the test sets take the training set's seed + 1 unless told; the training seed itself
  // would give the training set's own anchors
  const std::uint64_t test_seed = args.test_seed ? *args.test_seed : facts.train_seed + 1;
  if (facts.have_train_seed && test_seed == facts.train_seed)
    throw std::invalid_argument(
        "test seed " + std::to_string(test_seed) +
        " is the training set's seed: its test sets would hold the training "
        "anchors; pick another");

  // every test set first, so that a suite that cannot run is known before anything trains
  std::vector<std::string> distributions;
  for (const char* d : {"id", "ood", "causal"})
    if (wanted.count(d) != 0)
      distributions.push_back(d);
  if (distributions.empty())
    distributions.push_back("id");
  std::vector<std::pair<std::string, TestData>> tests;
  for (const std::string& d : distributions) {
    TestData test;
    if (d == "id" && !data.empty()) {
      test.dir = data;
      test.config_name = "--data";
    } else {
      TestDataRequest request;
      request.run_dir = run_dir;
      request.distribution = d;
      request.min_observational = options.calibration_samples + options.test_samples;
      request.seed = test_seed;
      request.cache = args.cache.empty() ? default_test_data_cache() : args.cache;
      request.train_config_file = args.dataset_config;
      request.threads = threads;
      request.log = log;
      try {
        test = ensure_test_data(request);
      } catch (const std::invalid_argument& e) {
        if (d == "id")
          throw;
        report.notes.push_back(d + ": " + e.what());
        log(report.notes.back());
        continue;
      }
      log(d + " test set " + test.dir.string() + " (" +
          (test.shards_written == 0 ? std::string("from the cache")
                                    : std::to_string(test.shards_written) + " shards generated") +
          ")");
    }
    tests.emplace_back(d, test);
  }
  if (tests.empty()) {
    std::string why;
    for (const std::string& n : report.notes)
      why += "; " + n;
    throw std::invalid_argument("none of the suites asked for can run" + why);
  }

  // the supervised baselines, trained once and scored on every suite
  std::vector<SupervisedEncoder> supervised;
  for (double f : args.supervised) {
    SupervisedOptions so;
    so.seed = options.seed;
    so.max_steps = args.supervised_max_steps;
    supervised.push_back(SupervisedEncoder::train(run_dir, f, so));
    const SupervisedEncoder& e = supervised.back();
    report.supervised.push_back({f, e.labels(), e.steps(), e.final_loss()});
    std::ostringstream line;
    line << "supervised baseline on " << e.labels() << " labelled samples (" << 100.0 * f
         << " %): " << e.steps() << " steps, last epoch's loss " << e.final_loss();
    log(line.str());
  }
  for (const SupervisedEncoder& e : supervised)
    options.supervised.push_back(&e);

  // the one-camera diagnostic: Table 1's 32 px, else the middle size asked
  std::int64_t one_camera_size = 0;
  if (!occlusion_sizes.empty())
    one_camera_size =
        std::find(occlusion_sizes.begin(), occlusion_sizes.end(), 32) != occlusion_sizes.end()
            ? 32
            : occlusion_sizes[occlusion_sizes.size() / 2];
  for (const auto& [d, test] : tests) {
    std::vector<std::int64_t> sizes = {0};
    sizes.insert(sizes.end(), occlusion_sizes.begin(), occlusion_sizes.end());
    // the robot's silhouettes split the occluded suites' samples (rendered on this thread)
    std::shared_ptr<RobotMasks> masks;
    if (!occlusion_sizes.empty()) {
      masks = robot_masks_of(test);
      if (!masks->rig) {
        report.notes.push_back(d + " occlusion: no split by robot pixels: " + masks->why);
        log(report.notes.back());
      }
    }
    // the clean codes and silhouettes, computed by the first occluded suite, reused by the rest
    const auto cache = std::make_shared<EvaluationCache>();
    auto evaluate = [&, d = d, test = test](std::int64_t size, std::vector<std::int64_t> cameras,
                                            const std::string& name) {
      RunEvaluationOptions o = options;
      o.cache = cache;
      o.occlusion = size;
      o.occlusion_seed = options.seed;
      o.occluded_cameras = std::move(cameras);
      if (size > 0 && masks && masks->rig)
        o.robot_masks = [m = masks](const std::vector<double>& angles, std::uint8_t* silhouettes) {
          std::vector<double> q;
          for (std::size_t c : m->column_of_joint)
            q.push_back(angles.at(c));
          m->rig->robot_masks(q, silhouettes);
        };
      // the diagnostics' MLP probe: on the clean id suite only
      if (!(d == "id" && size == 0))
        o.probe_steps = 0;
      SuiteResult s;
      s.name = name;
      s.distribution = d;
      s.occlusion = size;
      s.data_config = test.config_name;
      log("evaluating " + s.name);
      s.evaluation = evaluate_run(run_dir, test.dir, o);
      return s;
    };
    for (std::int64_t size : sizes)
      report.suites.push_back(
          evaluate(size, {}, d + (size > 0 ? " occlusion " + std::to_string(size) : "")));
    // with two cameras or more, the id suite again with the squares in one camera only: does
    // the clean view carry the pose?
    std::vector<std::string> cameras;
    if (masks && masks->rig)
      cameras = masks->rig->camera_names();
    for (std::int64_t c = static_cast<std::int64_t>(cameras.size()); c < facts.cameras; ++c)
      cameras.push_back("camera " + std::to_string(c));
    if (d == "id" && one_camera_size > 0 && cameras.size() > 1)
      for (std::size_t c = 0; c < cameras.size(); ++c)
        report.occlusion_diagnostics.push_back(evaluate(
            one_camera_size, {static_cast<std::int64_t>(c)},
            "id occlusion " + std::to_string(one_camera_size) + ", " + cameras[c] + " only"));
  }
  // AE1's information bound beside the suites: what its code holds of each joint (it needs
  // the training set, which a run evaluated on a --data test set may no longer have)
  log("screening AE1's code and the LDRs");
  ScreeningOptions screening;
  screening.probe_steps = options.probe_steps;
  screening.seed = options.seed;
  try {
    report.screen = screen_run(run_dir, screening);
  } catch (const std::exception& e) {
    report.notes.push_back(std::string("screening: ") + e.what());
    log(report.notes.back());
  }
  const std::string setting = report.suites.front().evaluation.setting;
  const nlohmann::json paper = paper_suite_numbers(setting, options.paper_results);
  report.paper_appendix = paper["appendix"];
  report.paper_table1_occlusion = paper["table1_occlusion"];
  report.paper_robopepp = paper["robopepp"];
  fs::create_directories(report_dir);
  core::write_text_file_atomically(report_dir / "results.json", report.to_json().dump(2) + "\n");
  core::write_text_file_atomically(report_dir / "results.md", report.markdown());
  // report.html: images from the first suite's test set; the occlusion figure at the middle
  // size asked (the paper's 32 px by default), at most half the image
  std::int64_t figure = 32;
  if (!occlusion_sizes.empty())
    figure = occlusion_sizes[occlusion_sizes.size() / 2];
  if (facts.image_side > 0)
    figure = std::min(figure, facts.image_side / 2);
  const ReportImages images =
      collect_report_images(run_dir, tests.front().second.dir, figure, options.seed);
  core::write_text_file_atomically(report_dir / "report.html",
                                   html_report(report, run_dir, images));
  const SuiteResult* id = report.find("id");
  if (id != nullptr)
    id->evaluation.calibration.write(report_dir / "calibration.json");
  SuiteOutcome outcome;
  outcome.report_dir = report_dir;
  outcome.report = std::move(report);
  return outcome;
}

}  // namespace ropes::eval
