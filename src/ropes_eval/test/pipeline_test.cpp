// The whole pipeline on the `tiny` preset, through the executables a user runs:
// ropes-generate -> ropes-train (AE1, LDRs, AE2) -> ropes-eval. Determinism, golden values,
// the sparsity matrix moving toward the identity, a resume after SIGKILL that ends in the
// same bytes, and the bad-input cases of the ropes_crl issue.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <ropes_core/child_process.hpp>
#include <ropes_core/sha256.hpp>
#include <ropes_crl/calibration.hpp>
#include <ropes_crl/run_directory.hpp>
#include <ropes_eval/run_evaluation.hpp>
#include <ropes_eval/test_data.hpp>
#include <ropes_nn/build_info.hpp>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>

#include "expect_message.hpp"

namespace fs = std::filesystem;

namespace {

struct Output {
  int rc = -1;
  std::string text;
};

// runs `command` through the shell, stdout and stderr together
Output run(const std::string& command) {
  const ropes::core::ChildResult r = ropes::core::run_shell(command);
  return {r.rc, r.output};
}

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// where ropes-eval writes a run's evaluation by default: beside the run, never in it
fs::path eval_dir(const fs::path& run) {
  return ropes::crl::default_evaluation_dir(run);
}

// every entry under `dir`, a file with its SHA-256: what a directory holds, to compare
std::map<std::string, std::string> listing(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir))
    out[fs::relative(e.path(), dir).string()] =
        e.is_regular_file() ? ropes::core::sha256_file(e.path()) : "(directory)";
  return out;
}

nlohmann::json json_of(const fs::path& p) {
  return nlohmann::json::parse(bytes_of(p));
}

std::vector<nlohmann::json> metrics_of(const fs::path& run) {
  std::vector<nlohmann::json> out;
  std::ifstream in(run / "metrics.jsonl");
  std::string line;
  while (std::getline(in, line))
    out.push_back(nlohmann::json::parse(line));
  return out;
}

// runs argv (argv[0] the executable) with stdout and stderr into a pipe until a line holding
// `stop` appears, then SIGKILLs it; returns what it printed and whether the kill was sent
struct Killed {
  std::string seen;
  bool sent = false;
  int status = 0;
  // how the child ended, for a failure's message: a run that ends before the line it is
  // killed at has said why only here when it printed nothing (seen once in CI, 2026-12-07)
  std::string how() const {
    if (WIFSIGNALED(status))
      return "the child was killed by signal " + std::to_string(WTERMSIG(status));
    if (WIFEXITED(status))
      return "the child exited with status " + std::to_string(WEXITSTATUS(status));
    return "the child ended with wait status " + std::to_string(status);
  }
};
Killed run_until_killed(const std::vector<std::string>& args, const std::string& stop) {
  Killed k;
  ropes::core::ChildOptions options;
  options.on_line = [&](ropes::core::ChildProcess& child, const std::string& line) {
    if (!k.sent && line.find(stop) != std::string::npos) {  // lines arrive whole
      child.signal(SIGKILL);
      k.sent = true;
    }
  };
  ropes::core::ChildProcess child(args, options);
  child.wait();
  k.status = child.status();
  k.seen = child.output();
  return k;
}

// see TinyRunIsDeterministicPinnedAndLearnsTheSparsityPattern: results.json's
// methods[method][what][joint] of the tiny run, pins of this code (regenerate with
// ROPES_PRINT_GOLDEN=1). The measures behind them have their witnesses in the unit tests:
// scipy for the correlations and the assignment, numpy for the calibrations and the PCA.
struct GoldenMetric {
  const char* method;
  const char* what;
  std::size_t joint;
  double value;
};
// one instruction-set level's pins: AE1's loss at step 30, AE2 panda_joint4's at step 200,
// the SHA-256 of the weight files' SHA-256s (kWeights, in order), and every metric
struct LevelGolden {
  const char* level;  // build_info().isa_level
  double ae1_loss, ae2_loss;
  const char* weights;
  std::vector<GoldenMetric> metrics;
};
const LevelGolden kGoldenV4{"x86-64-v4",
                            0.113216221,
                            0.040101584,
                            "e8404d605bf50c9a4c6342c654ef3880ab9f756c93ad910b74ac70fb6eafa9b4",
                            {{"ropes", "mcc", 0, 0.456168652},
                             {"ropes", "mcc", 1, 0.227917646},
                             {"ropes", "mcc", 2, 0.107873766},
                             {"ropes", "mse", 0, 0.472833333},
                             {"ropes", "mse", 1, 0.449637728},
                             {"ropes", "mse", 2, 0.560052478},
                             {"lambda0_autoencoder", "mcc", 0, 0.264482183},
                             {"lambda0_autoencoder", "mcc", 1, 0.353710983},
                             {"lambda0_autoencoder", "mcc", 2, 0.0818856499},
                             {"lambda0_autoencoder", "mse", 0, 0.653940522},
                             {"lambda0_autoencoder", "mse", 1, 0.422424644},
                             {"lambda0_autoencoder", "mse", 2, 0.519403107},
                             {"ldr_logit", "mcc", 0, 0.272186584},
                             {"ldr_logit", "mcc", 1, 0.16398695},
                             {"ldr_logit", "mcc", 2, 0.129306763},
                             {"ldr_logit", "mse", 0, 0.657603481},
                             {"ldr_logit", "mse", 1, 0.446747958},
                             {"ldr_logit", "mse", 2, 0.510248015},
                             {"pca_of_code", "mcc", 0, 0.712476393},
                             {"pca_of_code", "mcc", 1, 0.0887425802},
                             {"pca_of_code", "mcc", 2, 0.0681295728},
                             {"pca_of_code", "mse", 0, 0.31019361},
                             {"pca_of_code", "mse", 1, 0.459280961},
                             {"pca_of_code", "mse", 2, 0.492934456}}};
const LevelGolden kGoldenV3{"x86-64-v3",
                            0.113216221,
                            0.0401015654,
                            "5a66d8b1f4cf78353fb44e0bf3144f39c185a8f770bdbc99d50b015cc1fb386c",
                            {{"ropes", "mcc", 0, 0.456168163},
                             {"ropes", "mcc", 1, 0.2279182},
                             {"ropes", "mcc", 2, 0.107874219},
                             {"ropes", "mse", 0, 0.47283385},
                             {"ropes", "mse", 1, 0.449638171},
                             {"ropes", "mse", 2, 0.560053059},
                             {"lambda0_autoencoder", "mcc", 0, 0.264483724},
                             {"lambda0_autoencoder", "mcc", 1, 0.353710995},
                             {"lambda0_autoencoder", "mcc", 2, 0.081886382},
                             {"lambda0_autoencoder", "mse", 0, 0.653939909},
                             {"lambda0_autoencoder", "mse", 1, 0.422424581},
                             {"lambda0_autoencoder", "mse", 2, 0.519403275},
                             {"ldr_logit", "mcc", 0, 0.272187077},
                             {"ldr_logit", "mcc", 1, 0.163986634},
                             {"ldr_logit", "mcc", 2, 0.129306633},
                             {"ldr_logit", "mse", 0, 0.657603251},
                             {"ldr_logit", "mse", 1, 0.44674796},
                             {"ldr_logit", "mse", 2, 0.510248046},
                             {"pca_of_code", "mcc", 0, 0.712476637},
                             {"pca_of_code", "mcc", 1, 0.0887423579},
                             {"pca_of_code", "mcc", 2, 0.0681295996},
                             {"pca_of_code", "mse", 0, 0.31019329},
                             {"pca_of_code", "mse", 1, 0.459280916},
                             {"pca_of_code", "mse", 2, 0.492934478}}};

const std::string kGenerate = ROPES_GENERATE_EXE, kTrain = ROPES_TRAIN_EXE, kEval = ROPES_EVAL_EXE,
                  kRun = ROPES_RUN_EXE;

class Pipeline : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("ropes_pipeline_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    for (const char* seed : {"0", "1"}) {
      const Output g = run(kGenerate + " --config tiny-1c --seed " + seed + " --out " +
                           (dir_ / ("data" + std::string(seed))).string());
      ASSERT_EQ(g.rc, 0) << g.text;
    }
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static Output train(const std::string& out, const std::string& extra = "") {
    return run(kTrain + " --config 1c-tiny --data " + (dir_ / "data0").string() + " --out " + out +
               " --threads 2 --progress lines " + extra);
  }
  static fs::path dir_;
};
fs::path Pipeline::dir_;

const char* const kWeights[] = {"ae1.safetensors",
                                "codes.npy",
                                "ldr.panda_joint2.safetensors",
                                "ldr.panda_joint4.safetensors",
                                "ldr.panda_joint6.safetensors",
                                "ae2.panda_joint2.safetensors",
                                "ae2.panda_joint4.safetensors",
                                "ae2.panda_joint6.safetensors",
                                "ae2.lambda0.safetensors"};

}  // namespace

// Two runs with the same seed and threads write the same bytes; the run evaluates; the
// losses and the first latents are the golden values below; the sparsity matrix row of
// each joint moves toward e_i during stage 3.
//
// The golden values are pins of this code's own training (regenerate: run this test with
// ROPES_PRINT_GOLDEN=1 and copy what it prints). No independent implementation trains the
// whole pipeline; its parts have witnesses: the sparsity loss gradient against finite
// differences (ropes_crl's SparsityObjective test), every ropes_nn operation against
// PyTorch and finite differences. Pinned per instruction-set level of the kernels (v4 and
// v3, with the weight files' hashes), exact in the build that made them, within
// tolerances elsewhere.
TEST_F(Pipeline, TinyRunIsDeterministicPinnedAndLearnsTheSparsityPattern) {
  const fs::path a = dir_ / "run_a", b = dir_ / "run_b";
  const Output ta = train(a.string());
  ASSERT_EQ(ta.rc, 0) << ta.text;
  const Output tb = train(b.string());
  ASSERT_EQ(tb.rc, 0) << tb.text;
  for (const char* f : kWeights)
    EXPECT_EQ(bytes_of(a / f), bytes_of(b / f)) << f << " differs between two identical runs";

  // the tiny test set has 40 observational samples: 3 repeats of 20 + 20; the evaluation
  // goes beside the run (RUN-eval), and the run directory is as it was, to the byte
  const std::map<std::string, std::string> before = listing(a);
  const Output e = run(kEval + " --run " + a.string() + " --data " + (dir_ / "data1").string() +
                       " --probe-steps 100 --repeats 3 --calibration-samples 20 --test-samples 20");
  ASSERT_EQ(e.rc, 0) << e.text;
  EXPECT_EQ(listing(a), before);
  EXPECT_NE(e.text.find("calibration: " + (eval_dir(a) / "calibration.json").string()),
            std::string::npos)
      << e.text;
  // an --out inside the run is refused before anything is computed or written
  const Output inside = run(kEval + " --run " + a.string() + " --data " +
                            (dir_ / "data1").string() + " --out " + (a / "x.json").string());
  EXPECT_EQ(inside.rc, 2) << inside.text;
  EXPECT_NE(inside.text.find("ropes-eval: error: --out " + (a / "x.json").string() +
                             " is inside the run directory " + a.string()),
            std::string::npos)
      << inside.text;
  EXPECT_EQ(listing(a), before);
  // results named calibration.json would be overwritten by the calibration beside them
  const fs::path clash = dir_ / "clash" / "calibration.json";
  const Output named = run(kEval + " --run " + a.string() + " --data " + (dir_ / "data1").string() +
                           " --out " + clash.string());
  EXPECT_EQ(named.rc, 2) << named.text;
  EXPECT_NE(named.text.find("the calibration is written beside the results as calibration.json"),
            std::string::npos)
      << named.text;
  EXPECT_FALSE(fs::exists(clash.parent_path()));
  EXPECT_NE(e.text.find("| panda_joint6 |"), std::string::npos) << e.text;
  EXPECT_NE(e.text.find("3 repeats of 20 calibration and 20 test samples (of 40 observational"),
            std::string::npos)
      << e.text;
  const nlohmann::json results = json_of(eval_dir(a) / "results.json");
  EXPECT_EQ(results["methods"]["ropes"]["mcc"].size(), 3u);
  // results.md: the paper's Table 1 layout (six joints, the ones not intervened on "--"),
  // the paper's row, the difference, the baselines
  const std::string md = bytes_of(eval_dir(a) / "results.md");
  EXPECT_NE(md.find("| setup | panda_joint1 MCC | MSE | panda_joint2 MCC |"), std::string::npos)
      << md;
  EXPECT_NE(md.find("| this run (1c) | -- | -- | "), std::string::npos) << md;
  EXPECT_NE(md.find("| the paper (1c) | -- | -- | 0.949 | 0.053 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| difference | -- | -- | "), std::string::npos) << md;
  EXPECT_NE(md.find("| PCA of AE1's code, best assignment |"), std::string::npos) << md;
  EXPECT_EQ(results["methods"]["ropes"]["repeats"].size(), 3u);
  EXPECT_EQ(results["protocol"]["repeats"], 3);
  // the reported MCC is the mean of the repeats'
  double sum = 0;
  for (const nlohmann::json& r : results["methods"]["ropes"]["repeats"])
    sum += r["mcc"][0].get<double>();
  EXPECT_NEAR(results["methods"]["ropes"]["mcc"][0].get<double>(), sum / 3, 1e-12);
  // the calibration records the run it was fitted for, and fits it
  const auto fit = ropes::crl::Calibration::read(eval_dir(a) / "calibration.json");
  ASSERT_TRUE(fit.run.has_value());
  EXPECT_EQ(fit.run->config, "1c-tiny");
  fit.check_fits(ropes::crl::RunDirectory::open(a));
  EXPECT_EQ(ropes::crl::latest_calibration(ropes::crl::RunDirectory::open(a)),
            eval_dir(a) / "calibration.json");
  // provenance: the build that trained and the one that evaluated, here the same
  const nlohmann::json run_json = json_of(a / "run.json");
  EXPECT_EQ(run_json["provenance"]["isa_level"], results["provenance"]["evaluation"]["isa_level"]);
  EXPECT_EQ(run_json["provenance"]["threads"], 2);
  EXPECT_TRUE(results["provenance_differences"].empty()) << results["provenance_differences"];
  EXPECT_EQ(e.text.find("trained under another build"), std::string::npos) << e.text;
  EXPECT_NE(md.find("- build: " + run_json["provenance"]["isa_level"].get<std::string>()),
            std::string::npos)
      << md;
  // a run trained under another level: evaluated all the same, and said so
  const fs::path c = dir_ / "run_other_level";
  fs::copy(a, c, fs::copy_options::recursive);
  nlohmann::json moved = run_json;
  const std::string other_level =
      run_json["provenance"]["isa_level"] == "x86-64-v3" ? "x86-64-v4" : "x86-64-v3";
  moved["provenance"]["isa_level"] = other_level;
  std::ofstream(c / "run.json") << moved.dump(2);
  const Output ec =
      run(kEval + " --run " + c.string() + " --data " + (dir_ / "data1").string() +
          " --probe-steps 100 --repeats 3 --calibration-samples 20 --test-samples 20");
  ASSERT_EQ(ec.rc, 0) << ec.text;
  EXPECT_NE(
      ec.text.find("note: trained under another build than this one (isa_level: " + other_level +
                   " vs " + run_json["provenance"]["isa_level"].get<std::string>() + ")"),
      std::string::npos)
      << ec.text;
  EXPECT_NE(
      bytes_of(eval_dir(c) / "results.md").find("- **trained under another build** (isa_level: "),
      std::string::npos);
  // opened again by this build, twice (the run is complete: nothing is trained): run.json
  // records this build once beside the first, whatever the number of resumes
  for (int i = 0; i < 2; ++i) {
    const Output again = train(c.string());
    ASSERT_EQ(again.rc, 0) << again.text;
  }
  const nlohmann::json reopened = json_of(c / "run.json");
  ASSERT_TRUE(reopened.contains("resumed_under")) << reopened.dump();
  ASSERT_EQ(reopened["resumed_under"].size(), 1u) << reopened["resumed_under"];
  EXPECT_EQ(reopened["resumed_under"][0]["isa_level"], run_json["provenance"]["isa_level"]);
  EXPECT_EQ(reopened["provenance"]["isa_level"], other_level);

  // golden values, per instruction-set level: the default level's run above, and in a
  // dispatch build on a CPU with AVX-512 also the v3 kernels' run (ROPES_ISA=v3), so that
  // this machine checks both levels' pins
  const ropes::nn::BuildInfo& build = ropes::nn::build_info();
  std::vector<std::pair<const LevelGolden*, fs::path>> levels;
  for (const LevelGolden* g : {&kGoldenV4, &kGoldenV3})
    if (build.isa_level.substr(0, build.isa_level.find(' ')) == g->level)
      levels.push_back({g, a});
  if (build.isa_build == "dispatch" && build.isa_level == "x86-64-v4" &&
      std::getenv("ROPES_ISA") == nullptr) {
    const fs::path a3 = dir_ / "run_a_v3";
    const Output t3 =
        run("ROPES_ISA=v3 " + kTrain + " --config 1c-tiny --data " + (dir_ / "data0").string() +
            " --out " + a3.string() + " --threads 2 --progress lines");
    ASSERT_EQ(t3.rc, 0) << t3.text;
    const Output e3 = run("ROPES_ISA=v3 " + kEval + " --run " + a3.string() + " --data " +
                          (dir_ / "data1").string() +
                          " --probe-steps 100 --repeats 3 --calibration-samples 20 "
                          "--test-samples 20");
    ASSERT_EQ(e3.rc, 0) << e3.text;
    EXPECT_EQ(json_of(a3 / "run.json")["provenance"]["isa_level"], "x86-64-v3");
    levels.push_back({&kGoldenV3, a3});
  }
  // exact where the pins were made: g++ 12.2 and Eigen 3.4.0, the dispatch build's x86-64-v3
  // baseline (a native build also tunes for its CPU, which may fuse other multiply-adds);
  // elsewhere
  // (another compiler, Eigen, a sanitizer build, a CPU of another level) tolerances that
  // still catch a broken learner: the unpinned level's run is checked against the v4 pins
  const bool pinned_build = build.isa_build == "dispatch" && build.compiler == "GNU 12.2.0" &&
                            build.eigen == "3.4.0" && build.flags.rfind("Release:", 0) == 0 &&
                            build.isa_baseline == "x86-64-v3";
  // no pins of this level (a CPU below v3, another architecture): the v4 pins, tolerantly
  const bool unpinned_level = levels.empty();
  if (unpinned_level)
    levels.push_back({&kGoldenV4, a});
  const std::vector<std::string> methods = {"ropes", "lambda0_autoencoder", "ldr_logit",
                                            "pca_of_code"};
  for (const auto& [golden, run_dir] : levels) {
    const bool exact = pinned_build && !unpinned_level;
    double ae1_loss = 0, ae2_loss = 0;
    for (const nlohmann::json& m : metrics_of(run_dir)) {
      if (m["stage"] == "ae1" && m["step"] == 30)
        ae1_loss = m["loss"];
      if (m["stage"] == "ae2" && m["model"] == "panda_joint4" && m["step"] == 200)
        ae2_loss = m["loss"];
    }
    std::string hashes;
    for (const char* f : kWeights)
      hashes += ropes::core::sha256_file(run_dir / f);
    const std::string weights = ropes::core::sha256_hex(hashes.data(), hashes.size());
    const nlohmann::json r = json_of(eval_dir(run_dir) / "results.json");
    if (std::getenv("ROPES_PRINT_GOLDEN") != nullptr) {
      std::printf("golden %s: ae1 %.9g ae2 %.9g weights %s\n", golden->level, ae1_loss, ae2_loss,
                  weights.c_str());
      for (const std::string& m : methods)
        for (const char* what : {"mcc", "mse"})
          for (std::size_t k = 0; k < 3; ++k)
            std::printf("golden metric %s: {\"%s\", \"%s\", %zu, %.9g},\n", golden->level,
                        m.c_str(), what, k, r["methods"][m][what][k].get<double>());
    }
    const std::string where = std::string(" (") + golden->level + (exact ? ", exact)" : ")");
    if (exact) {
      EXPECT_EQ(weights, golden->weights) << "the weight files' hashes" << where;
    }
    // the losses: 1e-8 relative where exact (the pins' nine digits), 5 % elsewhere (a learner
    // that does not learn ends far from them: AE1's loss starts near 0.3)
    const double rel = exact ? 1e-8 : 5e-2;
    EXPECT_NEAR(ae1_loss, golden->ae1_loss, rel * golden->ae1_loss) << "ae1 loss, step 30" << where;
    EXPECT_NEAR(ae2_loss, golden->ae2_loss, rel * golden->ae2_loss)
        << "ae2 panda_joint4 loss, step 200" << where;
    // every method and joint (means of the 3 repeats): exact (1e-8 relative), else within 0.1
    // (MCC) and 25 % (MSE), as the training bits differ there
    for (const GoldenMetric& g : golden->metrics) {
      const double v = r["methods"][g.method][g.what][g.joint].get<double>();
      const bool mcc = std::string(g.what) == "mcc";
      EXPECT_NEAR(v, g.value, exact ? 1e-8 * std::fabs(g.value) : (mcc ? 0.1 : 0.25 * g.value))
          << g.method << " " << g.what << " of joint column " << g.joint << where;
    }
  }

  std::map<std::string, std::vector<nlohmann::json>> rows;  // model -> logged sparsity rows
  for (const nlohmann::json& m : metrics_of(a))
    if (m["stage"] == "ae2" && m["model"] != "lambda0")
      rows[m["model"]].push_back(m["sparsity_rows"][m["model"].get<std::string>()]);
  // || E|J^T v_i| - e_i || shrinks between the first and the last logged step
  const std::vector<std::string> joints = {"panda_joint2", "panda_joint4", "panda_joint6"};
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const auto& r = rows[joints[i]];
    ASSERT_GE(r.size(), 2u);
    auto distance = [&](const nlohmann::json& row) {
      double d = 0;
      for (std::size_t k = 0; k < row.size(); ++k)
        d += std::pow(row[k].get<double>() - (k == i ? 1.0 : 0.0), 2);
      return d;
    };
    EXPECT_LT(distance(r.back()), 0.5 * distance(r.front()))
        << joints[i] << ": first row " << r.front().dump() << ", last " << r.back().dump();
  }
}

// What another machine of the same instruction-set level changes: the cache sizes Eigen
// queries from the CPU, emulated with ROPES_EMULATE_CPU_CACHES, and the thread count. Two
// machines: a Zen 3 core (32 KiB L1, 512 KiB L2) and one whose CPUID reports small caches
// (8 KiB, 64 KiB, as some virtual machines do), small enough that Eigen would split the tiny
// run's longest sums (256 pixels) differently. Neither may change a byte of any weight file or
// code cache, nor a number of results.json. Checked by mutation, each making this test fail:
// the reduction blocks sized by the thread count again (as before ropes_nn/parallel.hpp's
// reduction blocks), and separately Eigen's queried blocking again (src/gemm.hpp's and the
// process-wide pin undone).
TEST_F(Pipeline, SameBytesWhateverTheCpuReportsAndAtAnyThreadCount) {
  const std::string zen3 = "ROPES_EMULATE_CPU_CACHES=32768,524288,33554432 ";
  const std::string small_caches = "ROPES_EMULATE_CPU_CACHES=8192,65536,1048576 ";
  struct Variant {
    std::string name, env, threads;
  };
  const std::vector<Variant> variants = {
      {"here_2", "", "2"}, {"zen3_1", zen3, "1"}, {"small_caches_3", small_caches, "3"}};
  std::vector<nlohmann::json> methods;
  for (const Variant& v : variants) {
    const fs::path out = dir_ / ("machines_" + v.name);
    const Output t =
        run(v.env + kTrain + " --config 1c-tiny --data " + (dir_ / "data0").string() + " --out " +
            out.string() + " --threads " + v.threads + " --progress lines");
    ASSERT_EQ(t.rc, 0) << v.name << ": " << t.text;
    const Output e =
        run(v.env + kEval + " --run " + out.string() + " --data " + (dir_ / "data1").string() +
            " --probe-steps 100 --repeats 3 --calibration-samples 20 "
            "--test-samples 20 --threads " +
            v.threads);
    ASSERT_EQ(e.rc, 0) << v.name << ": " << e.text;
    methods.push_back(json_of(eval_dir(out) / "results.json")["methods"]);
    if (methods.size() == 1)
      continue;
    const fs::path here = dir_ / ("machines_" + variants[0].name);
    // hashes, so that a failure prints two lines instead of two weight files
    for (const char* f : kWeights)
      EXPECT_EQ(ropes::core::sha256_file(here / f), ropes::core::sha256_file(out / f))
          << f << " differs in " << v.name;
    EXPECT_EQ(methods.back(), methods.front()) << "results.json's methods in " << v.name;
  }
}

// SIGKILL right after a checkpoint inside stage 3, then the same command again at another
// thread count: the run resumes and every weight file is byte-identical to an uninterrupted
// run's (the thread count changes no bit, so run.json records no other build).
TEST_F(Pipeline, KilledRunResumesToTheSameBytes) {
  const fs::path whole = dir_ / "whole", killed = dir_ / "killed";
  ASSERT_EQ(train(whole.string()).rc, 0);

  const Killed k =
      run_until_killed({kTrain, "--config", "1c-tiny", "--data", (dir_ / "data0").string(), "--out",
                        killed.string(), "--threads", "2", "--progress", "lines"},
                       "checkpoint ae2 panda_joint4 step 100");
  const std::string& seen = k.seen;
  const bool sent = k.sent;
  const int status = k.status;
  ASSERT_TRUE(sent) << k.how() << ", having printed:\n" << seen;
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << seen;
  EXPECT_FALSE(fs::exists(killed / "ae2.panda_joint4.safetensors"));
  EXPECT_TRUE(fs::exists(killed / "ae2.panda_joint4.checkpoint.safetensors"));

  const Output resumed = run(kTrain + " --config 1c-tiny --data " + (dir_ / "data0").string() +
                             " --out " + killed.string() + " --threads 1 --progress lines");
  ASSERT_EQ(resumed.rc, 0) << resumed.text;
  EXPECT_EQ(resumed.text.find("ae1 step"), std::string::npos) << "AE1 was trained again";
  EXPECT_FALSE(json_of(killed / "run.json").contains("resumed_under"))
      << "another thread count recorded as another build";
  for (const char* f : kWeights)
    EXPECT_EQ(bytes_of(whole / f), bytes_of(killed / f)) << f << " differs after the resume";
  // metrics.jsonl holds each logged step once
  std::set<std::string> keys;
  for (const nlohmann::json& m : metrics_of(killed)) {
    const std::string key = m["stage"].get<std::string>() + m.value("model", "") +
                            m.value("joint", "") + std::to_string(m.value("step", 0)) +
                            std::to_string(m.value("epoch", 0));
    EXPECT_TRUE(keys.insert(key).second) << "logged twice: " << m.dump();
  }
  EXPECT_FALSE(fs::exists(killed / "ae2.panda_joint4.checkpoint.safetensors"));
}

// Bad input: one clear message, a non-zero exit, nothing lost.
TEST_F(Pipeline, BadInputIsRefusedClearly) {
  const fs::path good = dir_ / "good";
  ASSERT_EQ(train(good.string()).rc, 0);
  const std::string before = bytes_of(good / "ae2.panda_joint2.safetensors");

  // a dataset that does not match the config: two cameras expected, one given
  Output o = run(kTrain + " --config 2c-tiny --data " + (dir_ / "data0").string() + " --out " +
                 (dir_ / "mismatch").string());
  EXPECT_EQ(o.rc, 1);
  EXPECT_NE(o.text.find("manifest.json: images are [1, 32, 32]"), std::string::npos) << o.text;
  EXPECT_NE(o.text.find("expects [2, 32, 32]"), std::string::npos) << o.text;
  EXPECT_FALSE(fs::exists(dir_ / "mismatch"));

  // a run directory of another config
  o = train(good.string(), "--set ae2.lambda=2");
  EXPECT_EQ(o.rc, 1);
  EXPECT_NE(o.text.find("holds a run with another config"), std::string::npos) << o.text;
  // of another seed
  o = train(good.string(), "--seed 5");
  EXPECT_EQ(o.rc, 1);
  EXPECT_NE(o.text.find("holds a run with another seed"), std::string::npos) << o.text;
  EXPECT_EQ(bytes_of(good / "ae2.panda_joint2.safetensors"), before);

  // --set of a key the config lacks
  o = train((dir_ / "misspelt").string(), "--set ae2.lambada=2");
  EXPECT_EQ(o.rc, 2);
  EXPECT_NE(o.text.find("--set ae2.lambada: the config has no 'lambada' there"), std::string::npos)
      << o.text;
  EXPECT_FALSE(fs::exists(dir_ / "misspelt"));
  // an optional key the config lacks is set, and its value checked
  o = train((dir_ / "optional").string(), "--set ae1.code_head=tanh");
  EXPECT_NE(o.rc, 0);
  EXPECT_NE(o.text.find("config.ae1.code_head: expected \"conv_relu\", \"linear\" or "
                        "\"resblock_linear\", got \"tanh\""),
            std::string::npos)
      << o.text;
  EXPECT_FALSE(fs::exists(dir_ / "optional"));

  // a loss that is not finite: the stage and step are named, the checkpoint is kept. At
  // --threads 2 the AE2s of joints 2 and 4 train side by side and both diverge; the first to
  // fail is reported, and the run stops without training the next models
  const fs::path nan = dir_ / "nan";
  o = train(nan.string(), "--set ae2.optimizer.lr=1e30");
  EXPECT_EQ(o.rc, 1);
  EXPECT_TRUE(o.text.find("stage ae2 panda_joint2, step") != std::string::npos ||
              o.text.find("stage ae2 panda_joint4, step") != std::string::npos)
      << o.text;
  EXPECT_NE(o.text.find("the loss is nan"), std::string::npos) << o.text;
  EXPECT_TRUE(fs::exists(nan / "ae1.safetensors"));
  EXPECT_FALSE(fs::exists(nan / "ae2.panda_joint6.safetensors"));
  EXPECT_FALSE(fs::exists(nan / "ae2.panda_joint6.checkpoint.safetensors"));

  // a checkpoint whose tensors do not match the architecture
  const fs::path other = dir_ / "other";
  fs::create_directories(other);
  for (const auto& e : fs::directory_iterator(good))
    if (e.path().filename().string().rfind("ae2.", 0) != 0)
      fs::copy(e.path(), other / e.path().filename());
  nlohmann::json r = json_of(other / "run.json");
  r.erase("complete");
  std::ofstream(other / "run.json") << r.dump();
  fs::copy(good / "ldr.panda_joint2.safetensors",
           other / "ae2.panda_joint2.checkpoint.safetensors");
  o = train(other.string());
  EXPECT_EQ(o.rc, 1);
  EXPECT_NE(o.text.find("ae2.panda_joint2.checkpoint.safetensors"), std::string::npos) << o.text;

  // protocol counts out of range, ropes-eval's and ropes-run's flags alike: a usage error
  // that names the flag, nothing evaluated or written
  o = run(kEval + " --run " + good.string() + " --data " + (dir_ / "data1").string() +
          " --repeats 0");
  EXPECT_EQ(o.rc, 2);
  EXPECT_NE(o.text.find("ropes-eval: error: --repeats is 0; expected 1..10000"), std::string::npos)
      << o.text;
  o = run(kRun + " 1c-tiny --out " + (dir_ / "run_bad_flags").string() +
          " --calibration-samples 1");
  EXPECT_EQ(o.rc, 2);
  EXPECT_NE(o.text.find("ropes-run: error: --calibration-samples is 1; expected 2..1000000000"),
            std::string::npos)
      << o.text;
  o = run(kRun + " 1c-tiny 2c-tiny --out " + (dir_ / "run_bad_flags").string());
  EXPECT_EQ(o.rc, 2);
  EXPECT_NE(o.text.find("one CONFIG, got '1c-tiny' and '2c-tiny'"), std::string::npos) << o.text;
  EXPECT_FALSE(fs::exists(dir_ / "run_bad_flags"));
  EXPECT_FALSE(fs::exists(good.string() + "-eval"));

  // a test set too small for the protocol's default 1,000 + 500 samples
  o = run(kEval + " --run " + good.string() + " --data " + (dir_ / "data1").string());
  EXPECT_EQ(o.rc, 1);
  EXPECT_NE(o.text.find("40 observational samples; the protocol draws 1000 calibration and 500 "
                        "disjoint test samples a repeat"),
            std::string::npos)
      << o.text;

  // evaluating on the training set, and an unfinished run
  o = run(kEval + " --run " + good.string() + " --data " + (dir_ / "data0").string());
  EXPECT_EQ(o.rc, 1);
  EXPECT_NE(o.text.find("is the dataset the run trained on"), std::string::npos) << o.text;
  o = run(kEval + " --run " + other.string() + " --data " + (dir_ / "data1").string());
  EXPECT_EQ(o.rc, 1);
  EXPECT_NE(o.text.find("has not finished training"), std::string::npos) << o.text;
}

// A dataset of sim_dataset_version 2, when ropes-generate read the paper's TN(mean, x) as a
// standard deviation (the paper's x is a variance), is refused by every tool that would use
// it, each naming the file, the version and what to do, and writing nothing: ropes-train on
// it, ropes-eval on it as a test set, ropes-generate asked to resume or reuse it, and
// ropes-eval's suites for a run that was trained on it
TEST_F(Pipeline, DatasetsOfTheOldStandardDeviationReadingAreRefused) {
  const auto make_old = [](const fs::path& from, const fs::path& to) {
    fs::remove_all(to);
    fs::copy(from, to, fs::copy_options::recursive);
    nlohmann::json m = json_of(to / "manifest.json");
    ASSERT_EQ(m["metadata"]["sim_dataset_version"], 3);
    m["metadata"]["sim_dataset_version"] = 2;
    std::ofstream(to / "manifest.json") << m.dump(2) << "\n";
  };
  const fs::path old_train = dir_ / "old_data0", old_test = dir_ / "old_data1";
  make_old(dir_ / "data0", old_train);
  make_old(dir_ / "data1", old_test);
  const std::string why =
      "sim_dataset_version 2, made when ropes-generate read the paper's "
      "TN(mean, x) as a standard deviation";

  Output o = run(kTrain + " --config 1c-tiny --data " + old_train.string() + " --out " +
                 (dir_ / "old_run").string());
  EXPECT_EQ(o.rc, 1) << o.text;
  EXPECT_NE(o.text.find((old_train / "manifest.json").string() + ": " + why), std::string::npos)
      << o.text;
  EXPECT_NE(o.text.find("generate the dataset again"), std::string::npos) << o.text;
  EXPECT_FALSE(fs::exists(dir_ / "old_run"));

  o = run(kGenerate + " --config tiny-1c --seed 0 --out " + old_train.string());
  EXPECT_EQ(o.rc, 1) << o.text;
  EXPECT_NE(o.text.find((old_train / "manifest.json").string() + ": " + why), std::string::npos)
      << o.text;
  EXPECT_NE(o.text.find("remove " + old_train.string() + " and generate it again"),
            std::string::npos)
      << o.text;

  const fs::path good = dir_ / "old_reading_run";
  ASSERT_EQ(train(good.string()).rc, 0);
  o = run(kEval + " --run " + good.string() + " --data " + old_test.string() +
          " --repeats 1 --calibration-samples 20 --test-samples 20");
  EXPECT_EQ(o.rc, 1) << o.text;
  EXPECT_NE(o.text.find((old_test / "manifest.json").string() + ": " + why), std::string::npos)
      << o.text;
  EXPECT_FALSE(fs::exists(eval_dir(good) / "results.json"));

  // a run whose training set is of the old reading: not evaluated on a new test set, not
  // screened, and its suites get no test set
  nlohmann::json r = json_of(good / "run.json");
  r["data_dir"] = old_train.string();
  std::ofstream(good / "run.json") << r.dump(2) << "\n";
  o = run(kEval + " --run " + good.string() + " --data " + (dir_ / "data1").string() +
          " --repeats 1 --calibration-samples 20 --test-samples 20");
  EXPECT_EQ(o.rc, 1) << o.text;
  EXPECT_NE(o.text.find("run.json: the run was trained on an outdated dataset: " +
                        (old_train / "manifest.json").string() + ": " + why),
            std::string::npos)
      << o.text;
  o = run(kEval + " --run " + good.string() + " --screen --probe-steps 0");
  EXPECT_EQ(o.rc, 1) << o.text;
  EXPECT_NE(o.text.find((old_train / "manifest.json").string() + ": " + why), std::string::npos)
      << o.text;
  EXPECT_FALSE(fs::exists(eval_dir(good) / "screen.json"));
  o = run(kEval + " --run " + good.string() + " --data-cache " + (dir_ / "old_cache").string() +
          " --suite id --repeats 1 --calibration-samples 20 --test-samples 20 --out " +
          (dir_ / "old_report").string());
  EXPECT_EQ(o.rc, 1) << o.text;
  EXPECT_NE(o.text.find("run.json: the run was trained on an outdated dataset: " +
                        (old_train / "manifest.json").string() + ": " + why),
            std::string::npos)
      << o.text;
  EXPECT_FALSE(fs::exists(dir_ / "old_report" / "results.json"));
  EXPECT_FALSE(fs::exists(dir_ / "old_cache"));
}

// ropes-train --stages ae1,ldr stops before AE2 (the run is not complete); ropes-eval --screen
// screens it (probes from AE1's code, the LDRs against Bayes); the same ropes-train without
// --stages then finishes it, to the bytes of a run trained in one go
TEST_F(Pipeline, StagesStopBeforeAe2AndScreeningReadsTheCode) {
  const fs::path staged = dir_ / "staged", straight = dir_ / "straight";
  Output o = train(staged.string(), "--stages ae1,ldr");
  ASSERT_EQ(o.rc, 0) << o.text;
  EXPECT_NE(o.text.find("stages up to ldr done; run without --stages to go on"), std::string::npos)
      << o.text;
  EXPECT_TRUE(fs::exists(staged / "codes.npy"));
  EXPECT_TRUE(fs::exists(staged / "ldr.panda_joint6.safetensors"));
  EXPECT_FALSE(fs::exists(staged / "ae2.panda_joint2.safetensors"));
  EXPECT_FALSE(json_of(staged / "run.json").contains("complete"));

  o = run(kEval + " --run " + staged.string() + " --screen --probe-steps 200");
  ASSERT_EQ(o.rc, 0) << o.text;
  EXPECT_NE(o.text.find("AE1 screening of 1c-tiny: probes from AE1's code fitted on 32 training "
                        "anchors (224 rows), scored on 8 held-out anchors (56 rows)"),
            std::string::npos)
      << o.text;
  EXPECT_NE(o.text.find("| panda_joint6 | "), std::string::npos) << o.text;
  const nlohmann::json screen = json_of(eval_dir(staged) / "screen.json");
  EXPECT_EQ(screen["format"], "ropes-eval-screen");
  ASSERT_EQ(screen["probe_mlp_r2"].size(), 3u) << screen.dump();
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_TRUE(screen["ldr_accuracy"][k].is_number()) << screen.dump();
    EXPECT_NEAR(
        screen["probe_mlp_r2"][k].get<double>(),
        1 - screen["probe_mlp_mse"][k].get<double>() / screen["angle_variance"][k].get<double>(),
        1e-12);
  }
  EXPECT_NEAR(screen["bayes_accuracy"][0].get<double>(), 0.83191037, 1e-6);  // the paper's 1C
  EXPECT_TRUE(fs::exists(eval_dir(staged) / "screen.md"));

  // not a finished run: no evaluation by the protocol yet
  o = run(kEval + " --run " + staged.string() + " --data " + (dir_ / "data1").string());
  EXPECT_EQ(o.rc, 1) << o.text;
  EXPECT_NE(o.text.find("has not finished training"), std::string::npos) << o.text;

  // go on, and end where a run in one go ends
  o = train(staged.string());
  ASSERT_EQ(o.rc, 0) << o.text;
  ASSERT_EQ(train(straight.string()).rc, 0);
  EXPECT_TRUE(json_of(staged / "run.json").value("complete", false));
  for (const char* f : kWeights)
    EXPECT_EQ(bytes_of(staged / f), bytes_of(straight / f)) << f;

  // AE1 alone: codes, no LDR; the screening's LDR columns are empty
  const fs::path ae1_only = dir_ / "ae1_only";
  ASSERT_EQ(train(ae1_only.string(), "--stages ae1").rc, 0);
  EXPECT_TRUE(fs::exists(ae1_only / "codes.npy"));
  EXPECT_FALSE(fs::exists(ae1_only / "ldr.panda_joint2.safetensors"));
  o = run(kEval + " --run " + ae1_only.string() + " --screen --probe-steps 0");
  ASSERT_EQ(o.rc, 0) << o.text;
  const nlohmann::json only = json_of(eval_dir(ae1_only) / "screen.json");
  EXPECT_TRUE(only["ldr_accuracy"][0].is_null()) << only.dump();
  EXPECT_TRUE(only["probe_mlp_r2"].empty()) << only.dump();
  EXPECT_EQ(only["probe_linear_r2"], screen["probe_linear_r2"]);  // the same AE1 and split

  o = train((dir_ / "bad_stages").string(), "--stages ldr");
  EXPECT_EQ(o.rc, 2) << o.text;
  EXPECT_NE(o.text.find("--stages is 'ldr'; expected ae1, ae1,ldr or ae1,ldr,ae2"),
            std::string::npos)
      << o.text;
  EXPECT_FALSE(fs::exists(dir_ / "bad_stages"));
  o = run(kEval + " --run " + staged.string() + " --screen --data " + (dir_ / "data1").string());
  EXPECT_EQ(o.rc, 2) << o.text;
  EXPECT_NE(o.text.find("--screen takes no --data or --suite"), std::string::npos) << o.text;
}

// Each suite's test set: the names the training config's test_sets give, and for id without
// one the training config itself. small-plus-2c trains on 10,000 anchors and names the
// small preset's 1,000-anchor config (the same distribution and rig) as its id test set.
TEST(TestSets, EachSuiteTakesTheConfigTheTrainingConfigNames) {
  using ropes::eval::suite_config_name;
  EXPECT_EQ(suite_config_name("small-plus-2c", "id"), "small-2c");
  EXPECT_EQ(suite_config_name("small-plus-2c", "ood"), "small-2c_ood");
  EXPECT_EQ(suite_config_name("small-plus-2c_causal", "id"), "small-2c_causal");
  EXPECT_EQ(suite_config_name("small-2c", "id"), "small-2c");
  EXPECT_EQ(suite_config_name("small-1c", "id"), "small-1c");
  EXPECT_EQ(suite_config_name("small-1c", "ood"), "");
  // a config given as a file: its own test_sets
  const fs::path dir = fs::temp_directory_path() / ("ropes_test_sets_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path installed = ropes::eval::installed_dataset_config("tiny-2c");
  nlohmann::json c = json_of(installed);
  c["distribution"] = (installed.parent_path() / c["distribution"].get<std::string>()).string();
  c["robot"] = (installed.parent_path() / c["robot"].get<std::string>()).string();
  c["name"] = "mine";
  c["test_sets"] = {{"id", "tiny-2c"}};
  std::ofstream(dir / "mine.json") << c.dump();
  EXPECT_EQ(suite_config_name("mine", "id", dir / "mine.json"), "tiny-2c");
  EXPECT_EQ(suite_config_name("mine", "ood", dir / "mine.json"), "");
  c.erase("test_sets");
  std::ofstream(dir / "mine.json") << c.dump();
  EXPECT_EQ(suite_config_name("mine", "id", dir / "mine.json"), "mine");
  fs::remove_all(dir);
}

// --sweep-lambda x --sweep-seeds: one complete run per pair, each with its lambda and seed
TEST_F(Pipeline, SweepTrainsOneRunPerLambdaAndSeed) {
  const fs::path out = dir_ / "sweep";
  const Output o = train(out.string(), "--sweep-lambda 0.5,2 --sweep-seeds 3,4");
  ASSERT_EQ(o.rc, 0) << o.text;
  for (const char* lambda : {"0.5", "2"})
    for (const char* seed : {"3", "4"}) {
      const fs::path run_dir = out / ("lambda-" + std::string(lambda) + "_seed-" + seed);
      const nlohmann::json r = json_of(run_dir / "run.json");
      EXPECT_TRUE(r.value("complete", false)) << run_dir;
      EXPECT_EQ(r["seed"], std::stoi(seed));
      EXPECT_EQ(r["config"]["ae2"]["lambda"], std::stod(lambda));
    }
}

// The `paper` preset cannot finish on a CPU, but it starts, logs, checkpoints and resumes:
// AE1 at the appendix's full size on 128x128 images, batches of 2 (its micro-batch size
// here), one checkpoint a step, a SIGKILL after the first, a resume to the end of stage 1.
TEST_F(Pipeline, PaperPresetStartsCheckpointsAndResumes) {
  const fs::path data = dir_ / "paper-data", out = dir_ / "paper-run";
  ASSERT_EQ(run(kGenerate + " --config small-1c --anchors 4 --seed 0 --out " + data.string()).rc,
            0);
  const std::vector<std::string> args = {kTrain,
                                         "--config",
                                         "1c-paper",
                                         "--data",
                                         data.string(),
                                         "--out",
                                         out.string(),
                                         "--threads",
                                         "2",
                                         "--progress",
                                         "lines",
                                         "--set",
                                         "ae1.batch_size=2",
                                         "--set",
                                         "ae1.micro_batch=2",
                                         "--set",
                                         "ae1.epochs=0.1",
                                         "--set",
                                         "checkpoint_every=1",
                                         "--set",
                                         "log_every=1"};
  // runs ropes-train until a line holding `stop` appears, then SIGKILLs it; returns the log
  auto run_until = [&](const std::string& stop) { return run_until_killed(args, stop).seen; };
  const std::string first = run_until("checkpoint ae1 step 1");
  ASSERT_NE(first.find("checkpoint ae1 step 1"), std::string::npos) << first;
  EXPECT_TRUE(fs::exists(out / "ae1.checkpoint.safetensors"));
  const std::string second = run_until("ae1 done");
  ASSERT_NE(second.find("ae1 done"), std::string::npos) << second;
  EXPECT_EQ(second.find("ae1 step 1/"), std::string::npos) << "step 1 ran again:\n" << second;
  EXPECT_NE(second.find("ae1 step 2/2"), std::string::npos) << second;
  EXPECT_TRUE(fs::exists(out / "ae1.safetensors"));
  int logged = 0;
  for (const nlohmann::json& m : metrics_of(out))
    logged += m["stage"] == "ae1" ? 1 : 0;
  EXPECT_EQ(logged, 2) << "each AE1 step logged once";
}

// ropes-eval --suite: the id test set generated into the cache on the first run and found
// there on the second (which generates nothing and writes the same bytes), the occlusion
// suite at each size asked, OOD skipped with its reason for one camera and run for two (the
// tiny-2c_ood test set), the report's files
TEST_F(Pipeline, SuitesGenerateTheirTestDataOnceAndReportEverySuite) {
  const fs::path run_dir = dir_ / "suite_run", cache = dir_ / "cache";
  const Output t = train(run_dir.string());
  ASSERT_EQ(t.rc, 0) << t.text;
  const std::string eval = kEval + " --run " + run_dir.string() + " --data-cache " +
                           cache.string() +
                           " --suite id,ood,occlusion --occlusion-sizes 8,16 --probe-steps 50"
                           " --repeats 2 --calibration-samples 20 --test-samples 20 --out ";
  const Output first = run(eval + (dir_ / "report1").string());
  ASSERT_EQ(first.rc, 0) << first.text;
  EXPECT_NE(first.text.find("generating tiny-1c (seed 1)"), std::string::npos) << first.text;
  EXPECT_NE(first.text.find("ood: no ood test set is defined for 'tiny-1c'"), std::string::npos)
      << first.text;
  const Output second = run(eval + (dir_ / "report2").string());
  ASSERT_EQ(second.rc, 0) << second.text;
  EXPECT_EQ(second.text.find("generating"), std::string::npos) << second.text;
  EXPECT_NE(second.text.find("(from the cache)"), std::string::npos) << second.text;
  EXPECT_EQ(bytes_of(dir_ / "report1" / "results.md"), bytes_of(dir_ / "report2" / "results.md"));
  const nlohmann::json r = json_of(dir_ / "report1" / "results.json");
  EXPECT_EQ(r["format"], "ropes-eval-report");
  ASSERT_EQ(r["suites"].size(), 3u) << r.dump(1);
  EXPECT_EQ(r["suites"][0]["name"], "id");
  EXPECT_EQ(r["suites"][1]["name"], "id occlusion 8");
  EXPECT_EQ(r["suites"][2]["results"]["protocol"]["occlusion"], 16);
  EXPECT_EQ(r["notes"].size(), 1u);
  // the supervised baseline at the default 1, 5, 10, 100 % of the 280 training rows (40
  // anchors, 7 regimes): nested seeded subsets of round(f * rows) labels, at least 2, scored
  // on every suite; with every label it fits its training labels better than their mean does
  // (the loss is in standardised units, where the mean scores 1; the tiny run's AE1 trained
  // for 30 steps, so its codes carry little: 0.975 when this was written)
  ASSERT_EQ(r["supervised"].size(), 4u) << r["supervised"].dump();
  EXPECT_EQ(r["supervised"][0]["labels"], 3);
  EXPECT_EQ(r["supervised"][1]["labels"], 14);
  EXPECT_EQ(r["supervised"][3]["labels"], 280);
  EXPECT_LT(r["supervised"][3]["final_loss"].get<double>(), 1.0);
  for (const nlohmann::json& s : r["suites"])
    EXPECT_TRUE(s["results"]["methods"].contains("supervised_100%")) << s["name"];
  // the occluded suites see other latents: their MCC differs from the clean one's
  EXPECT_NE(r["suites"][0]["results"]["methods"]["ropes"]["mcc"],
            r["suites"][2]["results"]["methods"]["ropes"]["mcc"]);
  // the occlusion diagnostics: AE1's code moves, more under the bigger square; the samples
  // split by whether a square hides robot pixels (the share of the robot's pixels hidden is
  // at most the share of samples that hide any, and grows with the square)
  const nlohmann::json d8 = r["suites"][1]["results"]["occlusion_diagnostics"],
                       d16 = r["suites"][2]["results"]["occlusion_diagnostics"];
  EXPECT_TRUE(r["suites"][0]["results"]["occlusion_diagnostics"].is_null());
  ASSERT_TRUE(d8.is_object() && d16.is_object()) << d8.dump() << d16.dump();
  EXPECT_GT(d8["code_shift"].get<double>(), 0.0);
  EXPECT_GT(d16["code_shift"].get<double>(), d8["code_shift"].get<double>());
  for (const nlohmann::json* d : {&d8, &d16}) {
    const nlohmann::json& sp = (*d)["split"];
    ASSERT_TRUE(sp.is_object()) << d->dump();
    EXPECT_GT(sp["share_hiding_robot"].get<double>(), 0.0);
    EXPECT_LE(sp["robot_hidden"].get<double>(), sp["share_hiding_robot"].get<double>());
    for (const char* group : {"mcc_hiding_robot", "mcc_missing_robot"})
      EXPECT_EQ(sp[group]["ropes"].size(), 3u) << sp.dump();
  }
  EXPECT_GT(d16["split"]["robot_hidden"].get<double>(), d8["split"]["robot_hidden"].get<double>());
  EXPECT_TRUE(r["occlusion_diagnostics"].empty()) << "one camera: no one-camera diagnostic";
  const std::string md = bytes_of(dir_ / "report1" / "results.md");
  EXPECT_NE(md.find("| id | 16 | tiny-1c |"), std::string::npos) << md;
  EXPECT_NE(md.find("## Occlusion diagnostics: which stage breaks"), std::string::npos) << md;
  EXPECT_NE(md.find("| id occlusion 16 | ldr_logit | squares hide robot pixels |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| labels a supervised encoder needs to match ROPES |"), std::string::npos)
      << md;

  // the suites of one test set share the clean codes and silhouettes (EvaluationCache): an
  // evaluation with a cache another suite filled equals one that computes its own, and does
  // not render the silhouettes again. The silhouette here is a stand-in drawn from the angles.
  fs::path test_dir;
  for (const fs::directory_entry& e : fs::directory_iterator(cache))
    if (e.path().filename().string().rfind("tiny-1c-seed1-", 0) == 0)
      test_dir = e.path();
  ASSERT_FALSE(test_dir.empty()) << "no tiny-1c seed 1 test set in " << cache;
  std::int64_t drawn = 0;
  ropes::eval::RunEvaluationOptions o;
  o.repeats = 2;
  o.calibration_samples = 20;
  o.test_samples = 20;
  o.probe_steps = 0;
  o.robot_masks = [&drawn](const std::vector<double>& angles, std::uint8_t* masks) {
    ++drawn;
    const int shift = static_cast<int>(std::lround(std::fabs(angles.at(0)) * 40.0));
    for (int i = 0; i < 32 * 32; ++i)  // tiny-1c: one camera of 32 x 32
      masks[i] = ((i % 32) / 4 + shift) % 4 == 0;
  };
  o.occlusion = 16;
  const ropes::eval::RunEvaluation own = ropes::eval::evaluate_run(run_dir, test_dir, o);
  const std::int64_t drawn_alone = drawn;
  EXPECT_EQ(drawn_alone, own.observational_samples);
  o.cache = std::make_shared<ropes::eval::EvaluationCache>();
  o.occlusion = 8;
  ropes::eval::evaluate_run(run_dir, test_dir, o);  // fills the cache
  drawn = 0;
  o.occlusion = 16;
  const ropes::eval::RunEvaluation shared = ropes::eval::evaluate_run(run_dir, test_dir, o);
  EXPECT_EQ(drawn, 0) << "the silhouettes were drawn again";
  EXPECT_EQ(shared.to_json().dump(), own.to_json().dump());
  ASSERT_TRUE(own.occlusion_split.has_value());
  EXPECT_GT(own.occlusion_split->share_hiding, 0.0);
  // a cache holds one run and one test set; it is refused for another
  o.cache->run_dir = dir_ / "another_run";
  const auto evaluate = [&] { ropes::eval::evaluate_run(run_dir, test_dir, o); };
  ropes::eval::test_support::expect_message(evaluate, "expected one cache per run and test set");
  // cameras to occlude without a square to place
  o.cache = nullptr;
  o.occlusion = 0;
  o.occluded_cameras = {0};
  ropes::eval::test_support::expect_message(evaluate, "but the occlusion square is 0 px");
  // a test set given with --data has no config to render the silhouettes from: the occluded
  // suite runs without the split and a note says why
  const Output data = run(kEval + " --run " + run_dir.string() + " --data " + test_dir.string() +
                          " --suite id,occlusion --occlusion-sizes 8 --probe-steps 0"
                          " --supervised none --repeats 2 --calibration-samples 20"
                          " --test-samples 20 --out " +
                          (dir_ / "report_data").string());
  ASSERT_EQ(data.rc, 0) << data.text;
  const nlohmann::json rd = json_of(dir_ / "report_data" / "results.json");
  EXPECT_NE(rd["notes"].dump().find(
                "occlusion: no split by robot pixels: a test set passed with --data has no config"),
            std::string::npos)
      << rd["notes"].dump();
  ASSERT_EQ(rd["suites"].size(), 2u) << rd.dump(1);
  EXPECT_TRUE(rd["suites"][1]["results"]["occlusion_diagnostics"]["split"].is_null())
      << rd["suites"][1]["results"]["occlusion_diagnostics"].dump();

  // AE1 trained with the occlusion augmentation and AE2 with the logit term (extensions):
  // other AE1 weights than the clean run's, and the results say it is not the paper's method
  EXPECT_TRUE(r["suites"][0]["results"]["extensions"].empty());
  const fs::path aug = dir_ / "suite_run_augmented";
  const Output ta = train(aug.string(),
                          "--set 'ae1.occlusion_augmentation={\"probability\": 0.5, "
                          "\"min_size\": 4, \"max_size\": 16}' "
                          "--set 'ae2.logit_loss={\"weight\": 0.5}'");
  ASSERT_EQ(ta.rc, 0) << ta.text;
  EXPECT_NE(bytes_of(aug / "ae1.safetensors"), bytes_of(run_dir / "ae1.safetensors"));
  const Output ea = run(kEval + " --run " + aug.string() + " --data " + test_dir.string() +
                        " --suite id --probe-steps 0 --supervised none --repeats 2"
                        " --calibration-samples 20 --test-samples 20 --out " +
                        (dir_ / "report_augmented").string());
  ASSERT_EQ(ea.rc, 0) << ea.text;
  const std::string mda = bytes_of(dir_ / "report_augmented" / "results.md");
  EXPECT_NE(mda.find("- **extension, not the paper's method**: ae1.occlusion_augmentation: AE1 "
                     "trained to reconstruct clean images from images with white squares "
                     "(probability 0.50, 4 to 16 px)"),
            std::string::npos)
      << mda;
  EXPECT_NE(mda.find("- **extension, not the paper's method**: ae2.logit_loss: each joint's AE2 "
                     "latent also trained to follow its frozen LDR's logit (weight 0.500 on 1 - "
                     "their batch correlation; regimes only, no angle)"),
            std::string::npos)
      << mda;

  // AE1 trained with the difference loss (a variant of AE1's objective, a config option like
  // code_head), alone and with the occlusion augmentation: each AE1 differs from the others
  // and run.json records the option
  const fs::path diff = dir_ / "suite_run_difference", diff_aug = dir_ / "suite_run_difference_aug";
  const Output td =
      train(diff.string(), "--stages ae1 --set 'ae1.difference_loss={\"weight\": 4}'");
  ASSERT_EQ(td.rc, 0) << td.text;
  EXPECT_NE(bytes_of(diff / "ae1.safetensors"), bytes_of(run_dir / "ae1.safetensors"));
  EXPECT_EQ(json_of(diff / "run.json")["config"]["ae1"]["difference_loss"]["weight"], 4)
      << bytes_of(diff / "run.json");
  const Output tb = train(diff_aug.string(),
                          "--stages ae1 --set 'ae1.difference_loss={\"weight\": 4}' --set "
                          "'ae1.occlusion_augmentation={\"probability\": 0.5, \"min_size\": 4, "
                          "\"max_size\": 16}'");
  ASSERT_EQ(tb.rc, 0) << tb.text;
  EXPECT_NE(bytes_of(diff_aug / "ae1.safetensors"), bytes_of(diff / "ae1.safetensors"));
  EXPECT_NE(bytes_of(diff_aug / "ae1.safetensors"), bytes_of(aug / "ae1.safetensors"));

  // two cameras: the OOD test set of the paper's OOD table, its appendix row beside ours
  const Output g =
      run(kGenerate + " --config tiny-2c --seed 0 --out " + (dir_ / "data2c").string());
  ASSERT_EQ(g.rc, 0) << g.text;
  const fs::path run2c = dir_ / "suite_run_2c";
  const Output t2 = run(kTrain + " --config 2c-tiny --data " + (dir_ / "data2c").string() +
                        " --out " + run2c.string() + " --threads 2 --progress lines");
  ASSERT_EQ(t2.rc, 0) << t2.text;
  const Output ood = run(kEval + " --run " + run2c.string() + " --data-cache " + cache.string() +
                         " --suite id,ood,occlusion --occlusion-sizes 8 --probe-steps 0"
                         " --repeats 2 --calibration-samples 20 --test-samples 20 --out " +
                         (dir_ / "report2c").string());
  ASSERT_EQ(ood.rc, 0) << ood.text;
  EXPECT_NE(ood.text.find("generating tiny-2c_ood (seed 1)"), std::string::npos) << ood.text;
  // one camera occluded at a time, beside the suites: AE1 encodes each camera alone, so the
  // code shift of both cameras occluded is the sum of the two one-camera shifts
  const nlohmann::json r2 = json_of(dir_ / "report2c" / "results.json");
  ASSERT_EQ(r2["occlusion_diagnostics"].size(), 2u) << r2.dump(1);
  const nlohmann::json& one0 = r2["occlusion_diagnostics"][0];
  EXPECT_EQ(one0["name"], "id occlusion 8, yaw45 only");
  EXPECT_EQ(one0["results"]["protocol"]["occluded_cameras"], nlohmann::json::array({0}));
  ASSERT_EQ(r2["suites"][1]["name"], "id occlusion 8");
  const double both =
      r2["suites"][1]["results"]["occlusion_diagnostics"]["code_shift"].get<double>();
  const double c0 = one0["results"]["occlusion_diagnostics"]["code_shift"].get<double>(),
               c1 = r2["occlusion_diagnostics"][1]["results"]["occlusion_diagnostics"]["code_shift"]
                        .get<double>();
  EXPECT_GT(c0, 0.0);
  EXPECT_GT(c1, 0.0);
  EXPECT_NEAR(both, c0 + c1, 1e-6 * both);
  const std::string md2 = bytes_of(dir_ / "report2c" / "results.md");
  EXPECT_NE(md2.find("| id occlusion 8, yaw45 only | 0 |"), std::string::npos) << md2;
  EXPECT_NE(md2.find("| ood | -- | tiny-2c_ood |"), std::string::npos) << md2;
  EXPECT_NE(md2.find("| the paper | -- | | 0.084 | 0.017 | 0.239 | 0.048 | 0.199 | 0.120 |"),
            std::string::npos)
      << md2;
  // a 1C run asked for OOD alone: nothing can run, said before anything trains
  const Output none = run(kEval + " --run " + run_dir.string() + " --data-cache " + cache.string() +
                          " --suite ood --out " + (dir_ / "report_none").string());
  EXPECT_EQ(none.rc, 1) << none.text;
  EXPECT_NE(none.text.find("none of the suites asked for can run; ood: no ood test set"),
            std::string::npos)
      << none.text;
  EXPECT_EQ(none.text.find("supervised baseline on"), std::string::npos) << none.text;
  // the training set's own seed as the test seed
  const Output same = run(kEval + " --run " + run_dir.string() + " --data-cache " + cache.string() +
                          " --suite id --test-seed 0");
  EXPECT_EQ(same.rc, 1) << same.text;
  EXPECT_NE(same.text.find("ropes-eval: error: test seed 0 is the training set's seed"),
            std::string::npos)
      << same.text;
  // a suite that is not one
  const Output bad = run(kEval + " --run " + run2c.string() + " --suite id,odd");
  EXPECT_EQ(bad.rc, 2) << bad.text;
  EXPECT_NE(bad.text.find("--suite: 'odd' is not a suite; expected id, ood, causal or occlusion"),
            std::string::npos)
      << bad.text;
}

// report.html opens from a file in headless Chromium and its screenshot shows the plots:
// not blank, scatter points, curves, heat maps and images drawn (report_screenshot_check.py);
// the page with one kind of plot hidden fails that kind's check, so every check can fail. Skips
// when Chromium or Python's PIL is absent (ci/install-deps installs both).
TEST_F(Pipeline, ReportOpensInHeadlessChromiumAndShowsItsPlots) {
  const std::string chromium = ROPES_CHROMIUM_EXE;
  if (chromium.empty() || chromium.find("NOTFOUND") != std::string::npos)
    GTEST_SKIP() << "no chromium: apt-get install chromium (ci/install-deps does)";
  if (run("/usr/bin/python3 -c 'import PIL'").rc != 0)
    GTEST_SKIP() << "no python3-pil: apt-get install python3-pil (ci/install-deps does)";
  const fs::path run_dir = dir_ / "report_run", report = dir_ / "report_html";
  const Output t = train(run_dir.string());
  ASSERT_EQ(t.rc, 0) << t.text;
  const Output e =
      run(kEval + " --run " + run_dir.string() + " --data-cache " + (dir_ / "cache").string() +
          " --suite id,occlusion --occlusion-sizes 8 --probe-steps 0 --repeats 2"
          " --calibration-samples 100 --test-samples 200 --supervised 10,100 --out " +
          report.string());
  ASSERT_EQ(e.rc, 0) << e.text;
  const std::string html = bytes_of(report / "report.html");
  // self-contained: no script, and no address but SVG's namespace name
  EXPECT_EQ(html.find("<script"), std::string::npos) << "no JavaScript";
  for (std::size_t at = html.find("http"); at != std::string::npos; at = html.find("http", at + 1))
    EXPECT_EQ(html.compare(at, 26, "http://www.w3.org/2000/svg"), 0) << html.substr(at, 60);
  auto shoot = [&](const fs::path& page, const fs::path& png) {
    return run("timeout 120 " + chromium +
               " --headless --no-sandbox --disable-gpu --hide-scrollbars --user-data-dir=" +
               (dir_ / "chromium-profile").string() + " --window-size=1500,4200 --screenshot=" +
               png.string() + " file://" + page.string());
  };
  const Output shot = shoot(report / "report.html", dir_ / "shot.png");
  ASSERT_TRUE(fs::exists(dir_ / "shot.png")) << shot.text;
  const Output check = run("/usr/bin/python3 " + std::string(ROPES_EVAL_TEST_DIR) +
                           "/report_screenshot_check.py " + (dir_ / "shot.png").string());
  EXPECT_EQ(check.rc, 0) << check.text;
  // each kind of plot hidden alone fails its own check, so each check can fail
  struct Hidden {
    std::vector<std::string> tags;  // what gets style="display:none"
    const char* check;              // the check that must then fail
  };
  const Hidden hidden[] = {
      {{"<svg class=\"plot scatter\""}, "FAILED: scatter"},
      {{"<svg class=\"plot curve\"", "<svg class=\"plot label-efficiency\""}, "FAILED: curves"},
      {{"<svg class=\"plot heatmap\""}, "FAILED: heat-map"},
      {{"<img "}, "FAILED: images"},
  };
  for (const Hidden& h : hidden) {
    std::string page = html;
    std::size_t found = 0;
    for (const std::string& tag : h.tags)
      for (std::size_t at = page.find(tag); at != std::string::npos; at = page.find(tag, at + 1)) {
        page.insert(at + tag.find(' ') + 1, "style=\"display:none\" ");
        ++found;
      }
    ASSERT_GT(found, 0u) << h.check << ": the report has no " << h.tags[0];
    {
      std::ofstream out(dir_ / "hidden.html");
      out << page;
    }
    fs::remove(dir_ / "hidden.png");
    shoot(dir_ / "hidden.html", dir_ / "hidden.png");
    ASSERT_TRUE(fs::exists(dir_ / "hidden.png"));
    const Output bad = run("/usr/bin/python3 " + std::string(ROPES_EVAL_TEST_DIR) +
                           "/report_screenshot_check.py " + (dir_ / "hidden.png").string());
    EXPECT_NE(bad.rc, 0) << h.check << "\n" << bad.text;
    EXPECT_NE(bad.text.find(h.check), std::string::npos) << bad.text;
  }
}

// ropes-run: generate -> train -> evaluate -> report in one command. Killed inside stage 2,
// run again it keeps stage 1, resumes the training to the bytes of an uninterrupted
// ropes-train on the same data, evaluates and reports; a third run redoes nothing and prints
// the same table; the same directory with another seed is refused, naming the seed
TEST_F(Pipeline, RopesRunResumesInsideItsStagesAndEndsWithTheTable) {
  const fs::path out = dir_ / "ropes_run", whole = dir_ / "ropes_run_whole";
  ASSERT_EQ(train(whole.string()).rc, 0);  // tiny-1c seed 0 is ropes-run's training set
  const std::vector<std::string> args = {kRun,
                                         "1c-tiny",
                                         "--out",
                                         out.string(),
                                         "--threads",
                                         "2",
                                         "--progress",
                                         "lines",
                                         "--repeats",
                                         "2",
                                         "--calibration-samples",
                                         "20",
                                         "--test-samples",
                                         "20",
                                         "--supervised",
                                         "100",
                                         "--probe-steps",
                                         "50"};
  const Killed k = run_until_killed(args, "checkpoint ae2 panda_joint4 step 100");
  const std::string& seen = k.seen;
  const bool sent = k.sent;
  ASSERT_TRUE(sent) << k.how() << ", having printed:\n" << seen;
  EXPECT_NE(seen.find("ropes-run [1/3 generate"), std::string::npos) << seen;

  std::string command;
  for (const std::string& a : args)
    command += a + " ";
  const Output second = run(command);
  ASSERT_EQ(second.rc, 0) << second.text;
  EXPECT_NE(second.text.find("ropes-run [1/3 generate"), std::string::npos) << second.text;
  EXPECT_NE(second.text.find("finished before: " + (out / "train-data").string()),
            std::string::npos)
      << second.text;
  EXPECT_EQ(second.text.find("ae1 step"), std::string::npos) << "AE1 trained again";
  for (const char* f : kWeights)
    EXPECT_EQ(bytes_of(whole / f), bytes_of(out / "run" / f)) << f << " differs after the resume";
  // it ends with the per-joint table beside the paper's numbers and the report's path
  EXPECT_NE(second.text.find("| panda_joint6 |"), std::string::npos) << second.text;
  EXPECT_NE(second.text.find("paper MCC"), std::string::npos) << second.text;
  const std::string report_line = "report: " + (out / "report" / "report.html").string();
  EXPECT_NE(second.text.find(report_line), std::string::npos) << second.text;
  EXPECT_TRUE(fs::exists(out / "report" / "report.html"));
  EXPECT_TRUE(fs::exists(out / "report" / "results.md"));
  // the id suite's calibration is in the report; ropes-stream's default finds it for OUT/run
  EXPECT_EQ(ropes::crl::latest_calibration(ropes::crl::RunDirectory::open(out / "run")),
            out / "report" / "calibration.json");
  EXPECT_FALSE(fs::exists(out / "run" / "calibration.json"));

  const Output third = run(command);
  ASSERT_EQ(third.rc, 0) << third.text;
  EXPECT_NE(third.text.find("[3/3 evaluate"), std::string::npos) << third.text;
  EXPECT_EQ(third.text.find("evaluating"), std::string::npos) << "evaluated again:\n" << third.text;
  const std::size_t table_at = second.text.find("ropes-eval: 1c-tiny");
  ASSERT_NE(table_at, std::string::npos) << second.text;
  const std::string table = second.text.substr(table_at);
  EXPECT_NE(third.text.find(table), std::string::npos) << third.text;

  // other evaluation arguments evaluate again
  const Output fewer = run(command + "--repeats 3");
  ASSERT_EQ(fewer.rc, 0) << fewer.text;
  EXPECT_NE(fewer.text.find("other evaluation arguments than last time: evaluating again"),
            std::string::npos)
      << fewer.text;
  EXPECT_NE(fewer.text.find("3 repeats of 20 calibration"), std::string::npos) << fewer.text;
  // a dataset config that does not exist: refused before anything is written
  const Output typo = run(kRun + " 1c-tiny --out " + (dir_ / "ropes_run_typo").string() +
                          " --dataset-config tiny-1x");
  EXPECT_EQ(typo.rc, 1) << typo.text;
  EXPECT_NE(typo.text.find("dataset config 'tiny-1x' is neither a file nor an installed"),
            std::string::npos)
      << typo.text;
  EXPECT_FALSE(fs::exists(dir_ / "ropes_run_typo" / "ropes-run.json"));
  // a state file that is not one: named, nothing run
  fs::create_directories(dir_ / "ropes_run_damaged");
  {
    std::ofstream state(dir_ / "ropes_run_damaged" / "ropes-run.json");
    state << "[1, 2]";
  }
  const Output damaged =
      run(kRun + " 1c-tiny --out " + (dir_ / "ropes_run_damaged").string() + " --threads 2");
  EXPECT_EQ(damaged.rc, 1) << damaged.text;
  EXPECT_NE(damaged.text.find("ropes-run.json: not a ropes-run state file"), std::string::npos)
      << damaged.text;
  EXPECT_FALSE(fs::exists(dir_ / "ropes_run_damaged" / "train-data"));
  const Output other = run(command + "--seed 3");
  EXPECT_EQ(other.rc, 1) << other.text;
  EXPECT_NE(other.text.find("this directory holds a run with another seed (0, now 3)"),
            std::string::npos)
      << other.text;
}

// The `small` 1C preset end to end (label `preset`, about 6 minutes on 2 cores; out of
// ci/test's default run, `ROPES_WITH_PRESET=1 bash ci/test` runs it): `ropes-run
// 1c-small` with seed 0, the id suite by the paper's protocol. Where the values were measured
// (the default dispatch build's x86-64-v4 kernels, g++ 12.2, Eigen 3.4.0, Release) each
// joint's mean MCC is the measured one, exactly: 0.981028612 / 0.959723413 / 0.861254003.
// Elsewhere (the v3 kernels, a native build, another compiler) the bits differ as another
// seed's would, and each joint must reach the lowest value measured, rounded down: 0.978 /
// 0.944 / 0.861 (seeds 0, 1, 2 of the dispatch build above: joint 2 0.981 / 0.988 / 0.987,
// joint 4 0.960 / 0.958 / 0.968, joint 6 0.861 / 0.875 / 0.892; of 1b10de5's native build:
// 0.979 / 0.988 / 0.985, 0.957 / 0.970 / 0.969, 0.875 / 0.876 / 0.873; and of 86a5392's:
// 0.988 / 0.986 / 0.986, 0.945 / 0.958 / 0.972, 0.880 / 0.879 / 0.886). The targets
// (the paper's 0.949 / 0.975 / 0.957) are met on joint 2 only.
// Prints the values.
// Under AddressSanitizer the preset trains far slower (AE1 at 5.6 images/s: over 3 hours
// for its 2,000 steps alone), and clang's -O1 float arithmetic is not the Release build's
// that the floors were measured on. So a sanitizer build runs the same job at the same
// sizes (dataset, networks, evaluation protocol) with every stage cut short, and checks
// that it ends with a complete table; the floors are checked in the Release build.
#if defined(__SANITIZE_ADDRESS__)
#define ROPES_PIPELINE_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ROPES_PIPELINE_SANITIZED 1
#endif
#endif

TEST_F(Pipeline, SmallPresetOneCameraReachesTheMeasuredMcc) {
  const fs::path out = dir_ / "small_1c";
  std::string config = "1c-small";
#if defined(ROPES_PIPELINE_SANITIZED)
  nlohmann::json cut = json_of(ROPES_CRL_SMALL_CONFIG);
  ASSERT_EQ(cut["name"], "1c-small");
  cut["name"] = "1c-small-cut";
  cut["ae1"]["steps"] = 60;
  cut["ldr"]["max_epochs"] = 1;
  cut["ae2"]["steps"] = 200;
  config = (dir_ / "1c-small-cut.json").string();
  std::ofstream(config) << cut.dump(2);
#endif
  const Output r = run(kRun + " " + config + " --out " + out.string() +
                       " --threads 2 --progress lines --suite id --supervised none");
  ASSERT_EQ(r.rc, 0) << r.text.substr(r.text.size() > 4000 ? r.text.size() - 4000 : 0);
  const nlohmann::json results = json_of(out / "report" / "results.json");
  const nlohmann::json& ropes = results["suites"][0]["results"]["methods"]["ropes"];
  const std::vector<std::string> joints = {"panda_joint2", "panda_joint4", "panda_joint6"};
  const double floors[] = {0.978, 0.944, 0.861};
  // (unused in a sanitizer build, which checks only that the table is complete)
  [[maybe_unused]] const double measured_v4[] = {0.981028612, 0.959723413, 0.861254003};
  [[maybe_unused]] const ropes::nn::BuildInfo& build = ropes::nn::build_info();
  [[maybe_unused]] const bool pinned =
      build.isa_build == "dispatch" && build.isa_level == "x86-64-v4" &&
      build.isa_baseline == "x86-64-v3" && build.compiler == "GNU 12.2.0" &&
      build.eigen == "3.4.0" && build.flags.rfind("Release:", 0) == 0;
  ASSERT_EQ(ropes["mcc"].size(), joints.size()) << ropes.dump();
  for (std::size_t k = 0; k < joints.size(); ++k) {
    const double mcc = ropes["mcc"][k].get<double>();
    std::printf("small 1C seed 0: %s MCC %.9f ± %.3f (floor %.3f), MSE %.3f\n", joints[k].c_str(),
                mcc, ropes["mcc_std"][k].get<double>(), floors[k], ropes["mse"][k].get<double>());
#if defined(ROPES_PIPELINE_SANITIZED)
    EXPECT_TRUE(std::isfinite(mcc) && std::fabs(mcc) <= 1.0) << joints[k] << ": " << mcc;
#else
    if (pinned) {
      EXPECT_NEAR(mcc, measured_v4[k], 1e-9) << joints[k] << " (exact: " << build.isa_level << ")";
    } else {
      EXPECT_GE(mcc, floors[k]) << joints[k] << " (" << build.isa_level << ", not pinned)";
    }
#endif
  }
}

// the joints of the 2C settings, in results.json's order
[[maybe_unused]] const std::vector<std::string> kJoints2c = {
    "panda_joint1", "panda_joint2", "panda_joint3", "panda_joint4", "panda_joint5", "panda_joint6"};

struct SuitePin {
  std::string suite;                                     ///< results.json's name of the suite
  std::vector<double> floors, measured_v4, measured_v3;  ///< a level not measured: empty
};

// A small-plus preset end to end (seed 0) against the MCC measured for it, suite by suite
// (results.json's suite name, "id" or "id occlusion 32"): exactly on the builds that measured
// it (this compiler and Eigen, the dispatch build at the level measured: x86-64-v4 or -v3,
// which ROPES_ISA=v3 selects on a v4 CPU), elsewhere at least the lowest of the seeds measured
// (docs/results/). The witness is the paper's Table 1 (and its occlusion row) beside it in
// results.json, as for the preset above. A sanitizer build leaves these to the test above,
// which runs the same code cut short.
[[maybe_unused]] void expect_small_plus_mcc(const std::string& config, const fs::path& out,
                                            const std::vector<std::string>& joints,
                                            const std::string& suites,
                                            const std::vector<SuitePin>& pins) {
  const Output r = run(kRun + " " + config + " --out " + out.string() +
                       " --threads 2 --progress lines --suite " + suites + " --supervised none");
  ASSERT_EQ(r.rc, 0) << r.text.substr(r.text.size() > 4000 ? r.text.size() - 4000 : 0);
  const nlohmann::json results = json_of(out / "report" / "results.json");
  const ropes::nn::BuildInfo& build = ropes::nn::build_info();
  const bool pinned_build = build.isa_build == "dispatch" && build.isa_baseline == "x86-64-v3" &&
                            build.compiler == "GNU 12.2.0" && build.eigen == "3.4.0" &&
                            build.flags.rfind("Release:", 0) == 0;
  const std::string level = json_of(out / "run" / "run.json")["provenance"]["isa_level"];
  for (const SuitePin& pin : pins) {
    const std::vector<double>& measured = level == "x86-64-v4"   ? pin.measured_v4
                                          : level == "x86-64-v3" ? pin.measured_v3
                                                                 : std::vector<double>{};
    const bool pinned = pinned_build && !measured.empty();
    const nlohmann::json* found = nullptr;
    for (const nlohmann::json& s : results["suites"])
      if (s["name"] == pin.suite)
        found = &s;
    ASSERT_NE(found, nullptr) << "no suite '" << pin.suite << "' in results.json";
    const nlohmann::json& ropes = (*found)["results"]["methods"]["ropes"];
    ASSERT_EQ(ropes["mcc"].size(), joints.size()) << ropes.dump();
    for (std::size_t k = 0; k < joints.size(); ++k) {
      const double mcc = ropes["mcc"][k].get<double>();
      std::printf("%s seed 0, %s: %s MCC %.9f ± %.3f (floor %.3f), MSE %.3f\n", config.c_str(),
                  pin.suite.c_str(), joints[k].c_str(), mcc, ropes["mcc_std"][k].get<double>(),
                  pin.floors[k], ropes["mse"][k].get<double>());
      if (pinned)
        EXPECT_NEAR(mcc, measured[k], 1e-9)
            << pin.suite << ", " << joints[k] << " (exact: " << level << ")";
      else
        EXPECT_GE(mcc, pin.floors[k])
            << pin.suite << ", " << joints[k] << " (" << level << ", not pinned)";
    }
  }
}

// 1C: 10,000 training anchors and their own id test set. Since the LDRs' weight average,
// pinned at x86-64-v3 only (seed 0: the AE1 of a seed-0 main job, which reads no LDR field,
// the LDRs and AE2s trained on it under the preset; the floors the lowest of seeds 0, 1 and 2
// there, docs/results/2026-12-07-ldr-weight-average.md); at x86-64-v4 the floors. About 11
// minutes.
TEST_F(Pipeline, SmallPresetPlusOneCameraReachesTheMeasuredMcc) {
#if defined(ROPES_PIPELINE_SANITIZED)
  GTEST_SKIP() << "the cut-short small preset above covers this code under the sanitizers";
#else
  expect_small_plus_mcc(
      "1c-small-plus", dir_ / "small_plus_1c", {"panda_joint2", "panda_joint4", "panda_joint6"},
      "id", {{"id", {0.993, 0.984, 0.956}, {}, {0.995809610, 0.984280742, 0.956543618}}});
#endif
}

// 2C: 10,000 training anchors, the id suite on the small preset's test set (small-2c). Since
// AE2's batch of 256, pinned at x86-64-v3 only (seed 0: the AE1 and LDRs of a seed-0 main job,
// the AE2s trained on them under the preset); the floors the lowest of seeds 0, 1 and 2 there
// (docs/results/2026-12-07-ae2-logit-batch.md); at x86-64-v4 the floors. The witness is the
// paper's Table 1 beside it in results.json. 41 minutes at x86-64-v3 before the batch of 256
// (2,462 s, passed, 2026-12-07), which adds about 6 to AE2.
TEST_F(Pipeline, SmallPresetPlusTwoCamerasReachesTheMeasuredMcc) {
#if defined(ROPES_PIPELINE_SANITIZED)
  GTEST_SKIP() << "the cut-short small preset above covers this code under the sanitizers";
#else
  expect_small_plus_mcc(
      "2c-small-plus", dir_ / "small_plus_2c", kJoints2c, "id",
      {{"id",
        {0.923, 0.981, 0.773, 0.932, 0.586, 0.878},
        {},
        {0.923611672, 0.984324662, 0.788530854, 0.932241914, 0.589778437, 0.883082683}}});
#endif
}

// 2C with AE1's occlusion augmentation (2c-small-plus-occlusion): the id suite and the 32 px
// occlusion row, pinned like the preset above (seed 0 from scratch; floors the lowest of
// seeds 0, 1 and 2, docs/results/2026-12-06-occlusion-plus.md); the witness is the paper's
// Table 1 and its occlusion row beside them in results.json. About 21 minutes.
TEST_F(Pipeline, SmallPresetPlusOcclusionTwoCamerasReachesTheMeasuredMcc) {
#if defined(ROPES_PIPELINE_SANITIZED)
  GTEST_SKIP() << "the cut-short small preset above covers this code under the sanitizers";
#else
  expect_small_plus_mcc(
      "2c-small-plus-occlusion", dir_ / "small_plus_occlusion_2c", kJoints2c, "id,occlusion",
      {{"id",
        {0.904, 0.971, 0.714, 0.912, 0.498, 0.838},
        {0.905598573, 0.983352928, 0.739686089, 0.912349189, 0.509555538, 0.858724097},
        {}},
       {"id occlusion 32",
        {0.666, 0.912, 0.386, 0.761, 0.335, 0.592},
        {0.666470106, 0.924426624, 0.386526227, 0.761882814, 0.409510483, 0.644793649},
        {}}});
#endif
}
