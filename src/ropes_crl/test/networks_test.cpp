#include "ropes_crl/networks.hpp"

#include <ropes_nn/ops.hpp>

#include <gtest/gtest.h>

#include <stdexcept>

using namespace ropes::crl;
using ropes::nn::Shape;
using ropes::nn::Tensor;

namespace {
Tensor ramp(const Shape& s) {
  std::vector<float> v(static_cast<std::size_t>(s.numel()));
  for (std::size_t i = 0; i < v.size(); ++i)
    v[i] = static_cast<float>((i * 37) % 101) / 101.0f;
  return Tensor(s, v);
}
}  // namespace

TEST(Networks, SmallAe1MapsImagesToEightByEightCodesAndBack) {
  Ae1Spec s;
  s.stem = "patchify";
  s.widths = {32, 64};
  s.blocks_per_stage = 1;
  Ae1 net(s);
  net.initialize(1);
  EXPECT_EQ(s.code_size(), 8);
  const Tensor x = ramp(Shape{2, 1, 128, 128});
  const Tensor y = net.encode(x);
  EXPECT_EQ(y.shape(), (Shape{2, 1, 8, 8}));
  EXPECT_EQ(net.decode(y).shape(), (Shape{2, 1, 128, 128}));
}

TEST(Networks, PaperSpecsBuildTheAppendixShapes) {
  Ae1 ae1(Ae1Spec{});  // 128 -> 4 stride-2 stages of 64/128/256/512 -> 8x8x1
  EXPECT_EQ(Ae1Spec{}.code_size(), 8);
  // the appendix AE1: 4 stages of Conv + 2 ResBlockGN + stride-2 conv, mirrored
  EXPECT_GT(ae1.parameter_count(), 10'000'000);
  LdrSpec ls;
  ls.in_channels = 2;
  Ldr ldr(ls);
  ldr.initialize(2);
  EXPECT_EQ(ldr(ramp(Shape{3, 2, 8, 8})).shape(), (Shape{3}));
  Ae2Spec as;
  as.in_channels = 2;
  as.latent_dim = 6;
  Ae2 ae2(as);
  ae2.initialize(3);
  const Tensor z = ae2.encode(ramp(Shape{2, 2, 8, 8}));
  EXPECT_EQ(z.shape(), (Shape{2, 6}));
  EXPECT_EQ(ae2.decode(z).shape(), (Shape{2, 2, 8, 8}));
}

TEST(Networks, MlpAe2WithSiluIsTwiceDifferentiable) {
  Ae2Spec s;
  s.kind = "mlp";
  s.widths = {16};
  s.activation = "silu";
  s.latent_dim = 4;
  Ae2 net(s);
  net.initialize(4);
  const Tensor z = net.encode(ramp(Shape{3, 1, 8, 8}));
  EXPECT_EQ(z.shape(), (Shape{3, 4}));
  EXPECT_EQ(net.decode(z).shape(), (Shape{3, 1, 8, 8}));
}

TEST(Networks, SpecsSayWhatIsWrong) {
  Ae1Spec a;
  a.image_size = 100;
  EXPECT_NE(a.problem().find("ae1.image_size: 100 is not a multiple of 16"), std::string::npos)
      << a.problem();
  EXPECT_THROW(Ae1{a}, std::invalid_argument);
  Ae2Spec b;
  b.kind = "transformer";
  EXPECT_NE(b.problem().find("ae2.kind"), std::string::npos);
  Ae2Spec c;
  c.widths = {64, 128};  // two stride-2 stages cannot take 8x8 to 1x1
  c.decoder_widths = {256, 128};
  EXPECT_NE(c.problem().find("ae2.widths"), std::string::npos) << c.problem();
  EXPECT_THROW(Ae2Spec::from_json({{"kind", "mlp"}}), std::invalid_argument);
  // a spec survives its JSON
  Ae1Spec d;
  d.stem = "patchify";
  d.widths = {32, 64};
  EXPECT_EQ(Ae1Spec::from_json(d.to_json()).to_json(), d.to_json());
}
