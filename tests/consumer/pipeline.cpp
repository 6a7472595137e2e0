// Runs the ROPES pipeline from another workspace through ropes_eval's installed pipeline API
// (ropes_eval::pipeline): the main job on the installed 1c-tiny config (generate, train,
// evaluate, report) into the directory given, then the suites again on its run into a report
// of their own. Checks what a user would: the report's files, the table's joints, that the
// run directory was left as the job's training wrote it, and that the calibration the suites
// fitted is the run's latest and the same as the second evaluation's. consumer_test.sh runs it.
#include <ropes_core/sha256.hpp>
#include <ropes_crl/calibration.hpp>
#include <ropes_crl/run_directory.hpp>
#include <ropes_eval/main_job.hpp>
#include <ropes_eval/suites.hpp>

#include <cstdio>
#include <filesystem>
#include <map>
#include <string>

namespace fs = std::filesystem;

namespace {

// every file under `dir` with its SHA-256
std::map<std::string, std::string> listing(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file())
      out[fs::relative(e.path(), dir).string()] = ropes::core::sha256_file(e.path());
  return out;
}

int fail(const std::string& what) {
  std::fprintf(stderr, "pipeline consumer: FAIL: %s\n", what.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2)
    return fail("usage: ropes_pipeline_consumer OUT");
  const fs::path out = argv[1];
  ropes::eval::MainJobOptions job;
  job.config = "1c-tiny";
  job.out = out / "job";
  job.threads = 2;
  job.suites.suites = {"id"};
  job.suites.supervised = {1.0};
  job.suites.supervised_max_steps = 20;
  // the tiny test set holds 40 observational samples
  job.suites.evaluation.repeats = 2;
  job.suites.evaluation.calibration_samples = 20;
  job.suites.evaluation.test_samples = 20;
  job.suites.evaluation.probe_steps = 50;
  int lines = 0;
  const ropes::eval::MainJobResult r =
      ropes::eval::run_main_job(job, [&](int stage, const std::string& line) {
        ++lines;
        std::printf("job [%d/3] %s\n", stage, line.c_str());
      });
  for (const char* f : {"results.json", "results.md", "report.html", "calibration.json"})
    if (!fs::is_regular_file(r.report_dir / f))
      return fail("the main job wrote no " + (r.report_dir / f).string());
  if (r.table.find("| panda_joint6 |") == std::string::npos || !r.evaluated || lines < 6)
    return fail("the main job's table has no panda_joint6 row:\n" + r.table);
  const auto run = ropes::crl::RunDirectory::open(r.run_dir);
  if (!run.complete() || run.config().name != "1c-tiny")
    return fail(r.run_dir.string() + " is not a complete 1c-tiny run");

  // the suites again, on the same run, into a report of their own (the cached test set)
  ropes::eval::SuiteOptions suites = job.suites;
  suites.supervised.clear();
  suites.out = out / "suites";
  suites.cache = r.dir / "test-data";
  const std::map<std::string, std::string> before = listing(r.run_dir);
  const ropes::eval::SuiteOutcome again = ropes::eval::run_suites(r.run_dir, suites);
  if (listing(r.run_dir) != before)
    return fail("run_suites changed the run directory " + r.run_dir.string());
  if (again.report_dir != out / "suites" || !fs::is_regular_file(again.report_dir / "results.json"))
    return fail("run_suites wrote no " + (out / "suites" / "results.json").string());
  const ropes::eval::SuiteResult* id = again.report.find("id");
  if (id == nullptr || id->evaluation.joints != run.joints())
    return fail("run_suites gave no id suite of the run's joints");
  // the job's calibration (OUT/report, the run's latest) is the one the suites fit again:
  // the same run, test set and draws give the same numbers
  const auto latest = ropes::crl::latest_calibration(run);
  if (!latest || *latest != r.report_dir / "calibration.json")
    return fail("the run's latest calibration is not " +
                (r.report_dir / "calibration.json").string());
  const ropes::crl::Calibration fitted = ropes::crl::Calibration::read(*latest);
  if (fitted.scale != id->evaluation.calibration.scale ||
      fitted.offset != id->evaluation.calibration.offset)
    return fail("the suites' calibration differs from the job's on the same run and test set");
  std::printf("pipeline consumer: latest calibration %s\n", latest->string().c_str());
  std::printf("pipeline consumer: %s", again.report.table().c_str());
  std::printf("pipeline consumer: OK\n");
  return 0;
}
