// The command-line helpers every tool shares: number flags and run_main's one line and status.
#include "ropes_core/cli.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace ropes::core {
namespace {

std::string usage_message(const std::function<void()>& f) {
  try {
    f();
  } catch (const UsageError& e) {
    return e.what();
  }
  return "(no UsageError)";
}

TEST(Cli, ParsesWholeNumbersAndRefusesTheRestByFlag) {
  EXPECT_EQ(parse_number<int>("--threads", "2"), 2);
  EXPECT_EQ(parse_number<std::uint64_t>("--seed", "18446744073709551615"), UINT64_MAX);
  EXPECT_DOUBLE_EQ(parse_number<double>("--lambda", "2.5e-3"), 2.5e-3);
  EXPECT_EQ(usage_message([] { parse_number<int>("--threads", "2x"); }),
            "--threads is '2x'; expected an integer");
  EXPECT_EQ(usage_message([] { parse_number<int>("--threads", ""); }),
            "--threads is ''; expected an integer");
  EXPECT_EQ(usage_message([] { parse_number<std::uint64_t>("--seed", "-1"); }),
            "--seed is '-1'; expected an integer");
  EXPECT_EQ(usage_message([] { parse_number<int>("--threads", "99999999999"); }),
            "--threads is '99999999999'; expected an integer");
  EXPECT_EQ(usage_message([] { parse_number<double>("--lambda", "nan"); }),
            "--lambda is 'nan'; expected a number");
  EXPECT_EQ(usage_message([] { parse_number<double>("--lambda", "inf"); }),
            "--lambda is 'inf'; expected a number");
}

TEST(Cli, RangesAreInclusiveAndNamedInTheMessage) {
  EXPECT_EQ(parse_number<int>("--threads", "1", 1, 256), 1);
  EXPECT_EQ(parse_number<int>("--threads", "256", 1, 256), 256);
  EXPECT_EQ(usage_message([] { parse_number<int>("--threads", "0", 1, 256); }),
            "--threads is '0'; expected an integer in [1, 256]");
  EXPECT_EQ(usage_message([] { parse_number<double>("--rate", "x", 0.5, 120.0); }),
            "--rate is 'x'; expected a number in [0.5, 120]");
  EXPECT_EQ(usage_message([] { parse_number<double>("--rate", "121", 0.5, 120.0); }),
            "--rate is '121'; expected a number in [0.5, 120]");
}

int ok_run(int argc, char**) {
  return argc;
}
int usage_run(int, char**) {
  throw UsageError("--frobnicate is not a flag; see --help");
}
int failing_run(int, char**) {
  throw std::runtime_error("data/manifest.json: is not JSON");
}

TEST(Cli, ACommandLineTakesOptionsSwitchesAndPositionalArgumentsInOrder) {
  std::string run, topic;
  int threads = 1;
  bool screen = false;
  const auto line = [&](bool with_positional) {
    CommandLine c("usage: tool --run RUN\n");
    c.option("--run", [&](const std::string& v) { run = v; })
        .option("--threads",
                [&](const std::string& v) { threads = parse_number<int>("--threads", v); })
        .flag("--screen", [&] { screen = true; });
    if (with_positional)
      c.positional([&](const std::string& v) {
        if (!topic.empty())
          throw UsageError("one TOPIC only");
        topic = v;
      });
    return c;
  };
  const auto parse = [&](bool with_positional, std::vector<std::string> args) {
    args.insert(args.begin(), "tool");
    std::vector<char*> argv;
    for (std::string& a : args)
      argv.push_back(a.data());
    return line(with_positional).parse(static_cast<int>(argv.size()), argv.data());
  };
  const auto error = [&](bool with_positional, std::vector<std::string> args) -> std::string {
    try {
      parse(with_positional, std::move(args));
    } catch (const UsageError& e) {
      return e.what();
    }
    return "(parsed)";
  };
  EXPECT_TRUE(parse(false, {"--run", "r", "--screen", "--threads", "4"}));
  EXPECT_EQ(run, "r");
  EXPECT_EQ(threads, 4);
  EXPECT_TRUE(screen);
  EXPECT_TRUE(parse(true, {"pose_estimates", "--run", "s"}));
  EXPECT_EQ(topic, "pose_estimates");
  EXPECT_EQ(run, "s");
  EXPECT_EQ(error(false, {"--run"}), "'--run' needs a value (see --help)");
  EXPECT_EQ(error(false, {"--runs", "x"}), "unknown option '--runs' (see --help)");
  EXPECT_EQ(error(false, {"loose"}), "unknown option 'loose' (see --help)");
  EXPECT_EQ(error(true, {"another"}), "one TOPIC only");  // topic is set already
  EXPECT_EQ(error(true, {"--x"}), "unknown option '--x' (see --help)");
  EXPECT_EQ(error(false, {"--threads", "many"}), "--threads is 'many'; expected an integer");
  // --help stops the parse before anything after it is looked at
  testing::internal::CaptureStdout();
  EXPECT_FALSE(parse(false, {"--help", "--nonsense"}));
  EXPECT_EQ(testing::internal::GetCapturedStdout(), "usage: tool --run RUN\n");
  CommandLine live("usage\n", "see ropes-eval --live --help");
  char* argv[] = {const_cast<char*>("ropes-eval"), const_cast<char*>("--live"),
                  const_cast<char*>("--window")};
  live.option("--window", [](const std::string&) {});
  try {
    live.parse(3, argv, 2);
    ADD_FAILURE() << "parsed a flag without its value";
  } catch (const UsageError& e) {
    EXPECT_STREQ(e.what(), "'--window' needs a value (see ropes-eval --live --help)");
  }
}

TEST(Cli, RunMainPrintsOneLineAndReturnsTheStatusOfItsKind) {
  char arg0[] = "ropes-test";
  char* argv[] = {arg0, nullptr};
  EXPECT_EQ(run_main("ropes-test", ok_run, 1, argv), 1);

  testing::internal::CaptureStderr();
  EXPECT_EQ(run_main("ropes-test", usage_run, 1, argv), 2);
  EXPECT_EQ(testing::internal::GetCapturedStderr(),
            "ropes-test: error: --frobnicate is not a flag; see --help\n");

  testing::internal::CaptureStderr();
  EXPECT_EQ(run_main("ropes-test", failing_run, 1, argv), 1);
  EXPECT_EQ(testing::internal::GetCapturedStderr(),
            "ropes-test: error: data/manifest.json: is not JSON\n");
}

}  // namespace
}  // namespace ropes::core
