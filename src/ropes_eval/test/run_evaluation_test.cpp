#include "ropes_eval/run_evaluation.hpp"

#include <gtest/gtest.h>

#include <algorithm>
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
}

}  // namespace
}  // namespace ropes::eval
