#include "ropes_eval/run_evaluation.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "expect_message.hpp"

namespace ropes::eval {
namespace {

using test_support::expect_message;

// The paper's protocol draws: the sizes asked, calibration and test disjoint, every index in
// range, the same draws for a seed, other draws for another seed and for each repeat
TEST(Protocol, SplitsAreSeededDisjointAndOfTheRequestedSizes) {
  const std::vector<ProtocolSplit> a = protocol_splits(2000, 15, 1000, 500, 0);
  ASSERT_EQ(a.size(), 15u);
  for (const ProtocolSplit& s : a) {
    ASSERT_EQ(s.calibration.size(), 1000u);
    ASSERT_EQ(s.test.size(), 500u);
    std::set<Eigen::Index> cal(s.calibration.begin(), s.calibration.end());
    EXPECT_EQ(cal.size(), 1000u) << "an index twice in one calibration set";
    for (Eigen::Index i : s.test) {
      EXPECT_EQ(cal.count(i), 0u) << "sample " << i << " in both sets";
      EXPECT_GE(i, 0);
      EXPECT_LT(i, 2000);
    }
    EXPECT_EQ(std::set<Eigen::Index>(s.test.begin(), s.test.end()).size(), 500u);
  }
  const std::vector<ProtocolSplit> again = protocol_splits(2000, 15, 1000, 500, 0);
  const std::vector<ProtocolSplit> other = protocol_splits(2000, 15, 1000, 500, 1);
  for (std::size_t r = 0; r < a.size(); ++r) {
    EXPECT_EQ(a[r].calibration, again[r].calibration);
    EXPECT_EQ(a[r].test, again[r].test);
    EXPECT_NE(a[r].test, other[r].test) << "repeat " << r << " is the same for seeds 0 and 1";
  }
  EXPECT_NE(a[0].test, a[1].test) << "two repeats drew the same test set";
  // a repeat's draw does not depend on how many repeats are asked for
  EXPECT_EQ(protocol_splits(2000, 3, 1000, 500, 0)[2].test, a[2].test);
}

TEST(Protocol, RefusesSizesItCannotDraw) {
  expect_message([] { protocol_splits(1000, 15, 1000, 500, 0); },
                 "1000 calibration and 500 test samples from 1000 observational samples");
  expect_message([] { protocol_splits(100, 0, 10, 10, 0); }, "0 repeats");
  expect_message([] { protocol_splits(100, 1, 1, 10, 0); }, "at least 2 samples in each set");
  // the whole of the samples may be used
  EXPECT_EQ(protocol_splits(20, 1, 10, 10, 0)[0].test.size(), 10u);
  // counts whose sum would overflow are refused, not wrapped into a small number
  expect_message([] { protocol_splits(100, 1, INT64_MAX, 2, 0); }, "calibration and 2 test");
}

// the protocol's counts, each at both ends of its range and just outside: the one check that
// evaluate_run, run_suites and run_main_job (and, by the same ranges, the tools' flags) apply
TEST(Protocol, CountsAreCheckedAtBothEndsOfTheirRanges) {
  const RunEvaluationOptions defaults;
  EXPECT_NO_THROW(check_protocol(defaults));
  struct Field {
    std::int64_t RunEvaluationOptions::*member;
    const char* name;
    ProtocolRange range;
  };
  for (const Field& f :
       {Field{&RunEvaluationOptions::repeats, "repeats", kRepeatsRange},
        Field{&RunEvaluationOptions::calibration_samples, "calibration_samples", kSamplesRange},
        Field{&RunEvaluationOptions::test_samples, "test_samples", kSamplesRange},
        Field{&RunEvaluationOptions::probe_steps, "probe_steps", kProbeStepsRange}}) {
    RunEvaluationOptions o;
    for (std::int64_t v : {f.range.low, f.range.high}) {
      o.*f.member = v;
      EXPECT_NO_THROW(check_protocol(o)) << f.name << " " << v;
    }
    for (std::int64_t v : {f.range.low - 1, f.range.high + 1, std::int64_t{INT64_MIN}}) {
      o.*f.member = v;
      expect_message([&] { check_protocol(o); }, std::string(f.name) + " is " + std::to_string(v) +
                                                     "; expected " + f.range.text());
    }
  }
  EXPECT_EQ(kRepeatsRange.text(), "1..10000");
  EXPECT_EQ(kSamplesRange.low, 2);
}

}  // namespace
}  // namespace ropes::eval
