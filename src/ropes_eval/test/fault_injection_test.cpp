// Fault injection through the executables a user runs (the hardening issue): SIGKILL at
// seeded random moments of ropes-generate, ropes-train and ropes-run (a line of their output
// and a delay after it), three times over, then
// the same command to the end; a file-size limit (RLIMIT_FSIZE, which fails a write the way
// a full disk does) while a shard, a checkpoint or a report is written; a byte changed in a
// finished shard, a checkpoint and a weights file. Each time the job either resumes to the
// bytes of an uninterrupted run or stops with a message naming the file, and a finished
// output is never damaged: after every fault, each file in the output directory is either
// byte-identical to the uninterrupted run's or one of the files a run rewrites as it goes
// (checkpoints, metrics.jsonl, run.json, ropes-run.json), and no temporary is left behind
// by a tool that stopped on its own.
//
// ROPES_FAULT_SEED (default 1) draws the kill moments and the size limits; the README's
// 20-run loop gives each run another seed. Every moment and limit is printed, so a failure
// is reproduced with the seed it prints.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "ropes_core/child_process.hpp"
#include "ropes_nn/safetensors.hpp"

namespace fs = std::filesystem;

namespace {

const std::string kGenerate = ROPES_GENERATE_EXE, kTrain = ROPES_TRAIN_EXE, kEval = ROPES_EVAL_EXE,
                  kRun = ROPES_RUN_EXE;

using Clock = std::chrono::steady_clock;

struct Job {
  int status = 0;
  std::string text;  // stdout and stderr together
  double seconds = 0;
  std::vector<double> line_times;  // when each line of `text` arrived, seconds after the start
  bool killed() const { return WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL; }
  int rc() const { return WIFEXITED(status) ? WEXITSTATUS(status) : -1; }
};

// where to SIGKILL a job: `delay` seconds after it has printed `lines` lines (0: after its
// start), or as soon as its output holds `text`; none when lines < 0 and text is empty. A
// moment tied to the job's progress, not to the clock, lands inside the job however fast
// this machine runs it
struct KillPoint {
  int lines = -1;
  double delay = 0;
  std::string text;
};

// runs args (args[0] the executable), output into a pipe, SIGKILLed at `kill` when it still
// runs then; with `file_limit` > 0, under RLIMIT_FSIZE of that many bytes with SIGXFSZ
// ignored, so that a write past it fails with EFBIG
Job run_job(const std::vector<std::string>& args, KillPoint kill = {},
            std::uint64_t file_limit = 0) {
  Job job;
  const Clock::time_point start = Clock::now();
  std::atomic<int> lines{0};
  std::atomic<bool> text_seen{false};
  ropes::core::ChildOptions options;
  options.file_size_limit = file_limit;
  options.on_line = [&](ropes::core::ChildProcess&, const std::string& line) {
    if (line.back() == '\n') {
      job.line_times.push_back(std::chrono::duration<double>(Clock::now() - start).count());
      ++lines;
    }
    if (!kill.text.empty() && line.find(kill.text) != std::string::npos)  // lines arrive whole
      text_seen = true;
  };
  ropes::core::ChildProcess child(args, options);
  if (kill.lines >= 0 || !kill.text.empty()) {
    Clock::time_point seen{};  // when the line count reached kill.lines
    const auto delay = std::chrono::microseconds(static_cast<std::int64_t>(kill.delay * 1e6));
    while (child.running()) {  // else it ended before the moment
      const Clock::time_point now = Clock::now();
      if (seen == Clock::time_point{} &&
          (kill.text.empty() ? lines >= kill.lines : text_seen.load()))
        seen = now;
      if (seen != Clock::time_point{} && now >= seen + delay) {
        child.signal(SIGKILL);
        break;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
  }
  child.wait();
  job.status = child.status();
  job.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  job.text = child.output();
  return job;
}

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// every regular file under `dir`, by path relative to it
std::map<std::string, std::string> tree_of(const fs::path& dir) {
  std::map<std::string, std::string> out;
  if (!fs::exists(dir))
    return out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file())
      out[fs::relative(e.path(), dir).string()] = bytes_of(e.path());
  return out;
}

bool is_temporary(const std::string& path) {
  return path.find(".tmp.") != std::string::npos;
}
bool is_checkpoint(const std::string& path) {
  return path.size() > 23 && path.compare(path.size() - 23, 23, ".checkpoint.safetensors") == 0;
}
// files a run rewrites or appends to as it goes: their final bytes hold wall times
bool is_running_record(const std::string& path) {
  const std::string leaf = fs::path(path).filename().string();
  return leaf == "metrics.jsonl" || leaf == "run.json" || leaf == "ropes-run.json";
}

// Finished outputs are never damaged: each file of `dir` is the reference's bytes, or a
// running record, or a checkpoint that the seal proves whole, or (when `temporaries_ok`,
// after a SIGKILL) a temporary of the killed process. Returns the problems found.
std::vector<std::string> damage(const fs::path& dir, const std::map<std::string, std::string>& ref,
                                bool temporaries_ok) {
  std::vector<std::string> problems;
  for (const auto& [path, bytes] : tree_of(dir)) {
    if (is_temporary(path)) {
      if (!temporaries_ok)
        problems.push_back(path + ": a temporary left behind");
      continue;
    }
    if (is_running_record(path))
      continue;
    if (is_checkpoint(path)) {
      try {
        const auto* data = reinterpret_cast<const std::uint8_t*>(bytes.data());
        if (!ropes::nn::is_sealed(ropes::nn::parse_safetensors(data, bytes.size(), path)))
          problems.push_back(path + ": a checkpoint without a seal");
      } catch (const std::exception& e) {
        problems.push_back(e.what());
      }
      continue;
    }
    const auto it = ref.find(path);
    if (it == ref.end())
      problems.push_back(path + ": not in the uninterrupted run");
    else if (it->second != bytes)
      problems.push_back(path + ": differs from the uninterrupted run (" +
                         std::to_string(bytes.size()) + " bytes, not " +
                         std::to_string(it->second.size()) + ")");
  }
  return problems;
}

// the same files as the reference, each with its bytes (running records: present)
std::vector<std::string> differences(const fs::path& dir,
                                     const std::map<std::string, std::string>& ref) {
  std::vector<std::string> problems = damage(dir, ref, false);
  const auto got = tree_of(dir);
  for (const auto& [path, bytes] : ref)
    if (!got.count(path))
      problems.push_back(path + ": missing");
  for (const auto& [path, bytes] : got)
    if (is_checkpoint(path))
      problems.push_back(path + ": a checkpoint left after the run finished");
  return problems;
}

std::string joined(const std::vector<std::string>& lines) {
  std::string out;
  for (const std::string& l : lines)
    out += "  " + l + "\n";
  return out;
}

std::string tail(const std::string& text) {
  return text.size() > 3000 ? "..." + text.substr(text.size() - 3000) : text;
}

std::uint64_t fault_seed() {
  const char* s = std::getenv("ROPES_FAULT_SEED");
  return s != nullptr ? std::strtoull(s, nullptr, 10) : 1;
}

// the largest file of a tree, in bytes
std::uint64_t largest(const std::map<std::string, std::string>& tree) {
  std::uint64_t n = 0;
  for (const auto& [path, bytes] : tree)
    n = std::max<std::uint64_t>(n, bytes.size());
  return n;
}

void flip_byte(const fs::path& file, std::uint64_t from_end) {
  std::string bytes = bytes_of(file);
  ASSERT_GT(bytes.size(), from_end) << file;
  bytes[bytes.size() - 1 - from_end] ^= 0x20;
  std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;
}

class FaultInjection : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("ropes_fault_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // the references: each tool once, uninterrupted, timed
    const Job g = run_job(generate_args(dir_ / "ref_data"));
    ASSERT_EQ(g.rc(), 0) << g.text;
    generate_ = {g.line_times, g.seconds};
    const Job t = run_job(train_args(dir_ / "ref_run"));
    ASSERT_EQ(t.rc(), 0) << t.text;
    train_ = {t.line_times, t.seconds};
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  // five shards of eight anchors: kills land between and inside shards
  static std::vector<std::string> generate_args(const fs::path& out) {
    return {kGenerate, "--config",  "tiny-1c", "--seed", "0", "--out", out, "--anchors-per-shard",
            "8",       "--threads", "2"};
  }
  static std::vector<std::string> train_args(const fs::path& out,
                                             const fs::path& data = dir_ / "ref_data") {
    return {kTrain, "--config",  "1c-tiny", "--data",     data,   "--out",
            out,    "--threads", "2",       "--progress", "lines"};
  }
  static std::vector<std::string> run_args(const fs::path& out) {
    return {kRun,
            "1c-tiny",
            "--out",
            out,
            "--threads",
            "2",
            "--progress",
            "lines",
            "--repeats",
            "1",
            "--calibration-samples",
            "20",
            "--test-samples",
            "20",
            "--supervised",
            "50",
            "--suite",
            "id"};
  }

  // an uninterrupted run: when each line of its output came, and how long it took
  struct Reference {
    std::vector<double> line_times;
    double seconds = 0;
  };

  // kills `args` at three seeded moments, checking for damage after each, then runs it to
  // the end and compares the whole tree with `ref`. A moment is drawn uniformly in 5-90 %
  // of the uninterrupted run's time and tied to its progress there: the line printed last
  // before it, and the time since that line (a machine that runs faster or slower now
  // still kills at the same stage). A resumed run has less to do, so a later kill may find
  // it finished
  static void kill_three_times_then_finish(const std::vector<std::string>& args,
                                           const fs::path& out, const Reference& whole,
                                           const std::map<std::string, std::string>& ref,
                                           std::uint64_t stream) {
    std::mt19937_64 rng(fault_seed() * 1000003 + stream);
    // the first kill, on a run from scratch, in its first half
    std::uniform_real_distribution<double> first(0.05, 0.5), moment(0.05, 0.9);
    int kills = 0;
    for (int i = 0; i < 3; ++i) {
      const double t = (i == 0 ? first(rng) : moment(rng)) * whole.seconds;
      KillPoint at{0, t, ""};
      for (std::size_t k = 0; k < whole.line_times.size() && whole.line_times[k] <= t; ++k)
        at = {static_cast<int>(k) + 1, t - whole.line_times[k], ""};
      // the first kill right as that line comes: tied to progress alone, it lands however much
      // faster than the reference this run is (a reference slowed by a cold start once left
      // ropes-run a 6 s silent phase that its rerun finished in under 2.4 s, so that no kill
      // of the three landed)
      if (i == 0 && at.lines > 0)
        at.delay = 0;
      const Job j = run_job(args, at);
      std::printf("[ fault    ] seed %llu: %s killed %.3f s after line %d (%.2f s of %.2f): %s\n",
                  static_cast<unsigned long long>(fault_seed()), args[0].c_str(), at.delay,
                  at.lines, t, whole.seconds, j.killed() ? "killed" : "it had finished");
      if (j.killed())
        ++kills;
      else
        ASSERT_EQ(j.rc(), 0) << tail(j.text);
      const auto problems = damage(out, ref, true);
      EXPECT_TRUE(problems.empty()) << "after the kill after line " << at.lines << ":\n"
                                    << joined(problems);
    }
    EXPECT_GE(kills, 1) << "no kill landed while the job ran";
    const Job last = run_job(args);
    ASSERT_EQ(last.rc(), 0) << tail(last.text);
    const auto problems = differences(out, ref);
    EXPECT_TRUE(problems.empty()) << "after the resumed run:\n" << joined(problems);
  }

  // runs `args` under a file-size limit drawn in [0, the largest reference file): it stops
  // with a message naming a file and the system's reason, damaging nothing; run again
  // without the limit it ends with the reference's bytes
  static void fill_the_disk_then_finish(const std::vector<std::string>& args, const fs::path& out,
                                        const std::map<std::string, std::string>& ref,
                                        std::uint64_t limit) {
    const Job full = run_job(args, {}, limit);
    std::printf("[ fault    ] seed %llu: %s under a %llu-byte file limit: exit %d\n",
                static_cast<unsigned long long>(fault_seed()), args[0].c_str(),
                static_cast<unsigned long long>(limit), full.rc());
    EXPECT_EQ(full.rc(), 1) << tail(full.text);
    EXPECT_NE(full.text.find("File too large"), std::string::npos) << tail(full.text);
    EXPECT_NE(full.text.find(dir_.string()), std::string::npos) << tail(full.text);  // a file
    const auto problems = damage(out, ref, false);
    EXPECT_TRUE(problems.empty()) << "after the full disk:\n" << joined(problems);
    const Job again = run_job(args);
    ASSERT_EQ(again.rc(), 0) << tail(again.text);
    const auto left = differences(out, ref);
    EXPECT_TRUE(left.empty()) << "after the run that followed:\n" << joined(left);
  }

  static std::uint64_t seeded_limit(const std::map<std::string, std::string>& ref,
                                    std::uint64_t stream) {
    std::mt19937_64 rng(fault_seed() * 1000003 + stream);
    return std::uniform_int_distribution<std::uint64_t>(0, largest(ref) - 1)(rng);
  }

  static fs::path dir_;
  static Reference generate_, train_;
};
fs::path FaultInjection::dir_;
FaultInjection::Reference FaultInjection::generate_, FaultInjection::train_;

}  // namespace

TEST_F(FaultInjection, GenerateKilledAtRandomMomentsResumesToTheSameBytes) {
  const fs::path out = dir_ / "gen_killed";
  kill_three_times_then_finish(generate_args(out), out, generate_, tree_of(dir_ / "ref_data"), 1);
}

TEST_F(FaultInjection, TrainKilledAtRandomMomentsResumesToTheSameBytes) {
  const fs::path out = dir_ / "train_killed";
  kill_three_times_then_finish(train_args(out), out, train_, tree_of(dir_ / "ref_run"), 2);
}

TEST_F(FaultInjection, RopesRunKilledAtRandomMomentsResumesToTheSameBytes) {
  // the reference in the same directory, since the report names its paths
  const fs::path out = dir_ / "ropes_run";
  const Job whole = run_job(run_args(out));
  ASSERT_EQ(whole.rc(), 0) << tail(whole.text);
  const auto ref = tree_of(out);
  fs::remove_all(out);
  kill_three_times_then_finish(run_args(out), out, {whole.line_times, whole.seconds}, ref, 3);
}

// A full disk while a shard, a checkpoint or a report is written (a limit below that file's
// size and above every file written before it), then at a seeded random size, for each tool
TEST_F(FaultInjection, AFullDiskStopsTheToolClearlyAndTheNextRunFinishes) {
  const auto data = tree_of(dir_ / "ref_data");
  const std::uint64_t shard = data.at("shards/images-00000.npy").size();
  fill_the_disk_then_finish(generate_args(dir_ / "full_gen"), dir_ / "full_gen", data, shard - 1);
  fill_the_disk_then_finish(generate_args(dir_ / "full_gen_seeded"), dir_ / "full_gen_seeded", data,
                            seeded_limit(data, 4));

  const auto run = tree_of(dir_ / "ref_run");
  // AE1's first checkpoint is its first file larger than its weights
  const std::uint64_t weights = run.at("ae1.safetensors").size();
  fill_the_disk_then_finish(train_args(dir_ / "full_train"), dir_ / "full_train", run, weights + 1);
  fill_the_disk_then_finish(train_args(dir_ / "full_train_seeded"), dir_ / "full_train_seeded", run,
                            seeded_limit(run, 5));
}

// A full disk while ropes-eval writes its report (a limit one byte below the largest of the
// report's files; the test set is generated into its cache before), then at a seeded size
TEST_F(FaultInjection, AFullDiskWhileTheReportIsWrittenStopsRopesEvalClearly) {
  const fs::path run = dir_ / "report_run", report = dir_ / "report";
  fs::copy(dir_ / "ref_run", run, fs::copy_options::recursive);
  const std::vector<std::string> args = {kEval,
                                         "--run",
                                         run.string(),
                                         "--suite",
                                         "id",
                                         "--data-cache",
                                         (dir_ / "report_cache").string(),
                                         "--out",
                                         report.string(),
                                         "--repeats",
                                         "1",
                                         "--calibration-samples",
                                         "20",
                                         "--test-samples",
                                         "20",
                                         "--supervised",
                                         "none",
                                         "--probe-steps",
                                         "0"};
  const Job whole = run_job(args);
  ASSERT_EQ(whole.rc(), 0) << tail(whole.text);
  const auto ref = tree_of(report);
  ASSERT_TRUE(ref.count("report.html")) << whole.text;
  for (const std::uint64_t limit : {largest(ref) - 1, seeded_limit(ref, 6)}) {
    fs::remove_all(report);
    fill_the_disk_then_finish(args, report, ref, limit);
  }
}

// A byte changed in a finished shard: ropes-train refuses the dataset naming the file, and
// so does ropes-generate, which says how to redo it; once manifest.json is gone it redoes
// that shard alone, to the reference's bytes
TEST_F(FaultInjection, ADamagedShardIsFoundByItsSha256) {
  const fs::path data = dir_ / "damaged_data";
  fs::copy(dir_ / "ref_data", data, fs::copy_options::recursive);
  const fs::path shard = data / "shards" / "images-00002.npy";
  flip_byte(shard, 100);

  const Job train = run_job(train_args(dir_ / "damaged_data_run", data));
  EXPECT_EQ(train.rc(), 1) << tail(train.text);
  EXPECT_NE(train.text.find(shard.string() + ": sha256 is "), std::string::npos) << train.text;
  EXPECT_NE(train.text.find("(the file changed after it was written)"), std::string::npos)
      << train.text;
  EXPECT_FALSE(fs::exists(dir_ / "damaged_data_run" / "ae1.safetensors"));

  const Job again = run_job(generate_args(data));
  EXPECT_EQ(again.rc(), 1) << tail(again.text);
  EXPECT_NE(again.text.find("remove " + (data / "manifest.json").string()), std::string::npos)
      << again.text;
  fs::remove(data / "manifest.json");
  const Job redo = run_job(generate_args(data));
  ASSERT_EQ(redo.rc(), 0) << tail(redo.text);
  EXPECT_NE(redo.text.find("shard 2 is redone: " + shard.string() + ": sha256 is "),
            std::string::npos)
      << redo.text;
  EXPECT_NE(redo.text.find("1 shards written, 4 already there"), std::string::npos) << redo.text;
  const auto problems = differences(data, tree_of(dir_ / "ref_data"));
  EXPECT_TRUE(problems.empty()) << joined(problems);
}

// A byte changed in a checkpoint or in finished weights: the resumed run refuses the file,
// naming it and (a checkpoint) what to do; done, the run ends with the reference's bytes
TEST_F(FaultInjection, ADamagedCheckpointOrWeightsFileIsFoundByItsSeal) {
  const fs::path out = dir_ / "damaged_run";
  const auto ref = tree_of(dir_ / "ref_run");
  // kill as soon as AE2's checkpoint of joint 4 at step 100 is written
  const Job first =
      run_job(train_args(out), KillPoint{-1, 0, "checkpoint ae2 panda_joint4 step 100"});
  ASSERT_TRUE(first.killed()) << tail(first.text);
  const fs::path checkpoint = out / "ae2.panda_joint4.checkpoint.safetensors";
  ASSERT_TRUE(fs::exists(checkpoint));
  flip_byte(checkpoint, 10);
  const Job refused = run_job(train_args(out));
  EXPECT_EQ(refused.rc(), 1) << tail(refused.text);
  EXPECT_NE(refused.text.find(checkpoint.string() + ": sha256 is "), std::string::npos)
      << refused.text;
  EXPECT_NE(refused.text.find("remove " + checkpoint.string() + " to train this model again"),
            std::string::npos)
      << refused.text;

  // finished weights damaged (an LDR, which AE2's stage loads): refused, named
  const fs::path ldr = out / "ldr.panda_joint2.safetensors";
  const std::string good_ldr = bytes_of(ldr);
  flip_byte(ldr, 10);
  fs::remove(checkpoint);
  const Job weights = run_job(train_args(out));
  EXPECT_EQ(weights.rc(), 1) << tail(weights.text);
  EXPECT_NE(weights.text.find(ldr.string() + ": sha256 is "), std::string::npos) << weights.text;
  std::ofstream(ldr, std::ios::binary | std::ios::trunc) << good_ldr;

  // the damaged checkpoint removed: that model trains from its first step, to the same bytes
  const Job done = run_job(train_args(out));
  ASSERT_EQ(done.rc(), 0) << tail(done.text);
  const auto problems = differences(out, ref);
  EXPECT_TRUE(problems.empty()) << joined(problems);
}

// A link inside ropes-run's output directory would take its writes elsewhere: refused
TEST_F(FaultInjection, RopesRunRefusesALinkInsideItsOutputDirectory) {
  const fs::path out = dir_ / "linked", elsewhere = dir_ / "elsewhere";
  fs::create_directories(out);
  fs::create_directories(elsewhere);
  fs::create_directory_symlink(elsewhere, out / "run");
  const Job j = run_job(run_args(out));
  EXPECT_EQ(j.rc(), 1) << tail(j.text);
  EXPECT_NE(j.text.find((out / "run").string() + " is a symbolic link; ropes-run writes only "
                                                 "inside"),
            std::string::npos)
      << j.text;
  EXPECT_TRUE(fs::is_empty(elsewhere));
}
