// The command-line helpers every tool shares: number flags and run_main's one line and status.
#include "ropes_core/cli.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>

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
