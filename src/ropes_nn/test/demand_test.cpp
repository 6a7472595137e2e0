// ROPES_DEMAND: broken invariants abort with the file, the line and the message instead of
// reading out of bounds (Shape::operator[], a Node whose backward returns the wrong number of
// gradients, parallel_for given more chunks than items).
#include "ropes_nn/demand.hpp"

#include <gtest/gtest.h>

#include "ropes_nn/ops.hpp"
#include "ropes_nn/parallel.hpp"
#include "ropes_nn/tensor.hpp"

namespace ropes::nn {
namespace {

// a broken operation: one input, no gradients
class ForgetfulNode : public Node {
 public:
  const char* name() const override { return "forgetful"; }
  std::vector<Tensor> backward(const Tensor&) override { return {}; }
};

class DemandDeathTest : public ::testing::Test {
 protected:
  void SetUp() override { GTEST_FLAG_SET(death_test_style, "threadsafe"); }
};

TEST_F(DemandDeathTest, ShapeIndexOutsideTheRankAborts) {
  const Shape s{2, 3};
  EXPECT_EQ(s[1], 3);
  EXPECT_DEATH((void)s[2],
               "tensor.hpp:[0-9]+: ROPES_DEMAND\\(axis >= 0 && axis < rank_\\) "
               "failed: Shape\\[2, 3\\]\\[2\\]: axis outside the rank 2");
  EXPECT_DEATH((void)s[-1], "ROPES_DEMAND");
}

TEST_F(DemandDeathTest, ABackwardReturningTheWrongNumberOfGradientsAborts) {
  const Tensor x = Tensor::ones(Shape{2}, true);
  const Tensor y =
      make_op_result(Shape{2}, Buffer(2, 1.0f), std::make_shared<ForgetfulNode>(), {x});
  EXPECT_DEATH(grad({sum(y)}, {x}), "forgetful::backward returned 0 gradients for 1 inputs");
}

TEST_F(DemandDeathTest, ParallelForWithMoreChunksThanItemsAborts) {
  EXPECT_DEATH(parallel_for(2, 3, [](int, std::int64_t, std::int64_t) {}),
               "parallel_for: 3 chunks for 2 items");
  EXPECT_DEATH(parallel_for(2, 0, [](int, std::int64_t, std::int64_t) {}), "0 chunks");
}

}  // namespace
}  // namespace ropes::nn
