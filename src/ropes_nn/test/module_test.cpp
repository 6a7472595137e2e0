// Module: misuse that would be silent is refused — copies (compile errors), calls before
// initialisation, the wrong number of inputs — and modules of the same code get independent
// weights from their own seeds or scopes.
#include "ropes_nn/module.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "ropes_nn/layers.hpp"
#include "ropes_nn/ops.hpp"

namespace ropes::nn {
namespace {

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "in: " << (text)

// a copy would share the parameter tensors with the original: not a thing that compiles
static_assert(!std::is_copy_constructible_v<Module> && !std::is_copy_assignable_v<Module>);
static_assert(!std::is_copy_constructible_v<Conv2d> && !std::is_copy_assignable_v<Conv2d>);
static_assert(!std::is_copy_constructible_v<Sequential> && !std::is_move_constructible_v<Dense>);
static_assert(!std::is_copy_constructible_v<ResBlockGN> && !std::is_move_assignable_v<GroupNorm>);

std::shared_ptr<Sequential> nested() {
  auto net = std::make_shared<Sequential>();
  net->add(std::make_shared<Conv2d>(1, 4, 3, 2));
  auto inner = std::make_shared<Sequential>();
  inner->add(std::make_shared<ResBlockGN>(4, 2), "block");
  net->add(inner);
  return net;
}

TEST(Module, CallingBeforeInitialisationThrowsNamingTheParameter) {
  auto net = nested();
  const Tensor x = Tensor::ones(Shape{1, 1, 8, 8});
  try {
    (*net)(x);
    ADD_FAILURE() << "an uninitialised module ran";
  } catch (const std::logic_error& e) {
    EXPECT_CONTAINS(e.what(),
                    "parameter '0.weight' was never initialised; call "
                    "initialize(seed) or load weights");
  }
  EXPECT_EQ(net->uninitialized_parameters().size(), net->named_parameters().size());
  // weights set by hand count once declared; the first one still missing is named
  net->mark_initialized("0.weight");
  net->mark_initialized("0.bias");
  try {
    (*net)(x);
    ADD_FAILURE() << "a half-initialised module ran";
  } catch (const std::logic_error& e) {
    EXPECT_CONTAINS(e.what(), "parameter '1.block.norm1.scale' was never initialised");
  }
  EXPECT_THROW(net->mark_initialized("1.block.conv9.weight"), std::invalid_argument);
  net->initialize(1);
  EXPECT_TRUE(net->uninitialized_parameters().empty());
  EXPECT_EQ((*net)(x).shape(), (Shape{1, 4, 4, 4}));
}

TEST(Module, ModulesOfTheSameCodeGetIndependentWeightsFromSeedsOrScopes) {
  // one classifier per joint, built by the same code: the same names
  auto make = [] { return std::make_shared<Dense>(8, 2); };
  auto a = make(), b = make(), c = make(), d = make();
  a->initialize(7);
  b->initialize(7);
  EXPECT_EQ(a->parameters()[0].to_vector(), b->parameters()[0].to_vector())
      << "the values depend only on the seed and the name";
  c->initialize(8);
  EXPECT_NE(c->parameters()[0].to_vector(), a->parameters()[0].to_vector());
  // one seed for the run, a scope per joint (what the header shows)
  d->initialize(7, "ldr2");
  b->initialize(7, "ldr4");
  EXPECT_NE(d->parameters()[0].to_vector(), a->parameters()[0].to_vector());
  EXPECT_NE(d->parameters()[0].to_vector(), b->parameters()[0].to_vector());
  auto plain = make();
  plain->initialize(7);
  a->initialize(7, "");  // an empty scope is no scope
  EXPECT_EQ(a->parameters()[0].to_vector(), plain->parameters()[0].to_vector());
  auto again = make();
  again->initialize(7, "ldr2");
  EXPECT_EQ(again->parameters()[0].to_vector(), d->parameters()[0].to_vector());
}

// a classifier fed two cameras' codes: y = Dense(concat(a, b))
class TwoViews : public MultiInputModule {
 public:
  TwoViews() : MultiInputModule(2) {
    head_ = register_module("head", std::make_shared<Dense>(6, 1));
  }

 protected:
  Tensor forward_inputs(const std::vector<Tensor>& inputs) override {
    return (*head_)(concat({inputs[0], inputs[1]}, 1));
  }

 private:
  std::shared_ptr<Dense> head_;
};

TEST(Module, MultiInputModulesTakeTheirInputsAndRefuseOtherCounts) {
  TwoViews net;
  net.initialize(3);
  EXPECT_EQ(net.input_count(), 2u);
  const Tensor a = Tensor::ones(Shape{5, 2}), b = Tensor::ones(Shape{5, 4});
  EXPECT_EQ(net({a, b}).shape(), (Shape{5, 1}));
  try {
    net(a);
    ADD_FAILURE() << "one input accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_CONTAINS(e.what(), "called with 1 input(s); this module takes 2");
  }
  EXPECT_THROW(net({a, b, a}), std::invalid_argument);
  // a single-input module takes a list of one, and no more
  Dense d(2, 3);
  d.initialize(1);
  EXPECT_EQ(d({a}).to_vector(), d(a).to_vector());
  EXPECT_THROW(d({a, a}), std::invalid_argument);
  Sequential chain;
  EXPECT_THROW(chain.add(std::make_shared<TwoViews>()), std::invalid_argument);
  class NoInputs : public MultiInputModule {
   public:
    NoInputs() : MultiInputModule(0) {}

   protected:
    Tensor forward_inputs(const std::vector<Tensor>& inputs) override { return inputs[0]; }
  };
  EXPECT_THROW(NoInputs(), std::invalid_argument);
}

}  // namespace
}  // namespace ropes::nn
