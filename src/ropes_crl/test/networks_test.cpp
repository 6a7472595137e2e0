#include "ropes_crl/networks.hpp"

#include <ropes_nn/adam.hpp>
#include <ropes_nn/ops.hpp>
#include <ropes_nn/train_step.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
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
// an MLP AE2 with one hidden layer of 16, SiLU, `latent` latents
Ae2Spec silu_mlp(std::int64_t latent) {
  Ae2Spec s;
  s.kind = "mlp";
  s.widths = {16};
  s.activation = "silu";
  s.latent_dim = latent;
  return s;
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

TEST(Networks, Ae1CodeHeadsEndTheEncoderAsNamed) {
  Ae1Spec paper;
  paper.stem = "patchify";
  paper.widths = {32, 64};
  paper.blocks_per_stage = 1;
  Ae1Spec linear = paper, resblock = paper;
  linear.code_head = "linear";
  resblock.code_head = "resblock_linear";
  Ae1 a(paper), b(linear), c(resblock);
  a.initialize(5);
  b.initialize(5);
  c.initialize(5);
  const Tensor x = ramp(Shape{2, 1, 128, 128});
  const Tensor ya = a.encode(x), yb = b.encode(x), yc = c.encode(x);
  for (const Tensor* y : {&ya, &yb, &yc})
    EXPECT_EQ(y->shape(), (Shape{2, 1, 8, 8}));
  EXPECT_EQ(c.decode(yc).shape(), (Shape{2, 1, 128, 128}));
  // the same weights: the linear head is the paper's before its ReLU
  EXPECT_EQ(a.parameter_count(), b.parameter_count());
  int negative = 0;
  for (std::int64_t i = 0; i < yb.numel(); ++i) {
    EXPECT_FLOAT_EQ(ya.data()[i], std::max(0.0f, yb.data()[i]));
    negative += yb.data()[i] < 0;
  }
  EXPECT_GT(negative, 0);
  // counted by hand: the last stride-2 conv 64 -> 64 instead of 64 -> 1 (+36,351), a
  // ResBlockGN(64) (2 x 36,928 + 2 x 128), GroupNorm(64) (128) and a 1x1 conv 64 -> 1 (65)
  // in the encoder; a Conv3x3 1 -> 64 (640) and a ResBlockGN(64) in front of the decoder,
  // whose first conv then reads 64 channels (+36,288)
  EXPECT_EQ(c.parameter_count() - a.parameter_count(), 110'656 + 111'040);
  // the field is written only when it is not the paper's, and read back
  EXPECT_FALSE(paper.to_json().contains("code_head"));
  EXPECT_EQ(Ae1Spec::from_json(resblock.to_json()).code_head, "resblock_linear");
  Ae1Spec wrong = paper;
  wrong.code_head = "tanh";
  EXPECT_NE(wrong.problem().find("ae1.code_head: expected \"conv_relu\", \"linear\" or "
                                 "\"resblock_linear\", got \"tanh\""),
            std::string::npos)
      << wrong.problem();
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
  const Ae2Spec s = silu_mlp(4);
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

TEST(Networks, LdrStandardizesItsInputWithTheStatisticsOfTheCodes) {
  // 40 codes [1, 8, 8]: element k has mean k/10 and a spread that grows with k; element 0
  // is constant, element 1 varies by 1e-5 of the widest (below 0.001: not seen), element 2
  // by 0.005 of it (between 0.001 and 0.01: scaled as if it were 0.01)
  const std::int64_t n = 40, per = 64;
  std::vector<float> v(static_cast<std::size_t>(n * per));
  for (std::int64_t r = 0; r < n; ++r)
    for (std::int64_t k = 0; k < per; ++k) {
      const double wave = std::sin(0.7 * static_cast<double>(r) + 1.3 * static_cast<double>(k));
      const double spread = k == 0 ? 0.0 : k == 1 ? 2e-5 : k == 2 ? 1e-2 : 0.05 * (k - 2);
      v[static_cast<std::size_t>(r * per + k)] = static_cast<float>(k / 10.0 + spread * wave);
    }
  const Tensor codes(Shape{n, 1, 8, 8}, v);
  LdrSpec s;
  s.input_normalization = "standardize";
  Ldr ldr(s);
  ldr.initialize(5);
  CodeStandardization fitted(1, 8);
  fitted.fit(codes, "test");
  ldr.set_input_map(fitted);

  // the witness: mean and population sd of each element in double, the rule of the header
  std::vector<double> mean(per, 0.0), sd(per, 0.0);
  for (std::int64_t r = 0; r < n; ++r)
    for (std::int64_t k = 0; k < per; ++k)
      mean[k] += v[static_cast<std::size_t>(r * per + k)] / static_cast<double>(n);
  for (std::int64_t r = 0; r < n; ++r)
    for (std::int64_t k = 0; k < per; ++k)
      sd[k] += std::pow(v[static_cast<std::size_t>(r * per + k)] - mean[k], 2) / n;
  double widest = 0;
  for (double& d : sd)
    widest = std::max(widest, d = std::sqrt(d));
  std::vector<float> shift, scale;
  for (const auto& [name, t] : ldr.named_parameters()) {
    if (name == "input.shift")
      shift = t.to_vector();
    if (name == "input.scale")
      scale = t.to_vector();
  }
  ASSERT_EQ(shift.size(), 64u);
  ASSERT_EQ(scale.size(), 64u);
  EXPECT_EQ(scale[0], 0.0f);
  EXPECT_EQ(scale[1], 0.0f);
  EXPECT_NEAR(scale[2], 1.0 / (0.01 * widest), 1e-4 / (0.01 * widest));
  for (std::int64_t k = 0; k < per; ++k) {
    EXPECT_NEAR(shift[k], mean[k], 1e-6) << k;
    if (k >= 3) {
      EXPECT_NEAR(scale[k], 1.0 / sd[k], 1e-4 / sd[k]) << k;
    }
  }

  // the logit is the plain LDR's (same seed, same parameter names) on (y - shift) * scale,
  // and the gradient in y is the plain one times the scale: exactly 0 where the scale is
  LdrSpec plain_spec;
  Ldr plain(plain_spec);
  plain.initialize(5);
  std::vector<float> mapped(v.size());
  for (std::size_t i = 0; i < v.size(); ++i)
    mapped[i] = (v[i] - shift[i % per]) * scale[i % per];
  Tensor y = codes, x(Shape{n, 1, 8, 8}, mapped);
  y.set_requires_grad(true);
  x.set_requires_grad(true);
  const Tensor a = ldr(y), b = plain(x);
  for (std::int64_t r = 0; r < n; ++r)
    EXPECT_NEAR(a.data()[r], b.data()[r], 1e-5) << r;
  const Tensor ga = ropes::nn::grad({ropes::nn::sum(a)}, {y})[0];
  const Tensor gb = ropes::nn::grad({ropes::nn::sum(b)}, {x})[0];
  for (std::int64_t i = 0; i < n * per; ++i) {
    if (scale[i % per] == 0.0f) {
      EXPECT_EQ(ga.data()[i], 0.0f) << i;
    } else {
      EXPECT_NEAR(ga.data()[i], gb.data()[i] * scale[i % per],
                  1e-4 * std::abs(gb.data()[i] * scale[i % per]) + 1e-6)
          << i;
    }
  }

  // the gradient moved to the map's coordinates is the plain LDR's gradient there (0 where
  // the map hides the element): d/ds = d/dy / scale
  const Tensor moved = ldr.input_map()->to_mapped_gradient(ga);
  for (std::int64_t i = 0; i < n * per; ++i) {
    const float want = scale[i % per] == 0.0f ? 0.0f : gb.data()[i];
    EXPECT_NEAR(moved.data()[i], want, 1e-4 * std::abs(want) + 1e-6) << i;
  }

  // an optimiser of trained_parameters() leaves the map as it was fitted
  EXPECT_EQ(ldr.trained_parameters().size() + 2, ldr.named_parameters().size());
  ropes::nn::Adam adam(ldr.trained_parameters());
  std::vector<float> ones(static_cast<std::size_t>(n), 1.0f);
  const Tensor labels(Shape{n}, ones);
  for (int step = 0; step < 3; ++step)
    ropes::nn::train_step(adam, ropes::nn::mean_loss([&](std::size_t) {
                            return ropes::nn::bce_with_logits_elementwise(ldr(codes), labels);
                          }));
  for (const auto& [name, t] : ldr.named_parameters()) {
    if (name == "input.shift") {
      EXPECT_EQ(t.to_vector(), shift);
    }
    if (name == "input.scale") {
      EXPECT_EQ(t.to_vector(), scale);
    }
  }
  EXPECT_NE(ldr(codes).to_vector(), a.to_vector());  // the rest did train
}

TEST(Networks, LdrStandardizationRefusesWhatItCannotUse) {
  LdrSpec s;
  s.input_normalization = "whiten";
  EXPECT_NE(s.problem().find("ldr.input_normalization: expected \"none\" or \"standardize\", got "
                             "\"whiten\""),
            std::string::npos)
      << s.problem();
  s.input_normalization = "standardize";
  CodeStandardization map(1, 8);
  auto message = [&](const Tensor& codes) {
    try {
      map.fit(codes, "test");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_NE(message(ramp(Shape{4, 2, 8, 8}))
                .find("codes are [4, 2, 8, 8], expected [n >= 1, 1, "
                      "8, 8]"),
            std::string::npos);
  const std::vector<float> same(2 * 64, 0.5f);
  EXPECT_NE(message(Tensor(Shape{2, 1, 8, 8}, same)).find("the 2 codes are all equal"),
            std::string::npos);
  std::vector<float> bad = ramp(Shape{2, 1, 8, 8}).to_vector();
  bad[70] = NAN;
  EXPECT_NE(message(Tensor(Shape{2, 1, 8, 8}, bad)).find("code 1 holds nan at element 6"),
            std::string::npos)
      << message(Tensor(Shape{2, 1, 8, 8}, bad));
  // a map for another code shape, a network without a map, a gradient of another shape
  Ldr ldr(s);
  CodeStandardization two(2, 8);
  two.fit(ramp(Shape{3, 2, 8, 8}), "test");
  try {
    ldr.set_input_map(two);
    ADD_FAILURE() << "took a [2, 8, 8] map for [1, 8, 8] codes";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "Ldr::set_input_map: the fitted map is [2, 8, 8], expected [1, 8, 8]"),
              std::string::npos)
        << e.what();
  }
  LdrSpec none;
  Ldr plain(none);
  try {
    plain.set_input_map(two);
    ADD_FAILURE() << "a network without a map took one";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("ldr.input_normalization is \"none\""), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(two.to_mapped_gradient(ramp(Shape{3, 1, 8, 8})), std::invalid_argument);
  // the spec survives its JSON; a weight file written before the option has no map
  EXPECT_EQ(LdrSpec::from_json(s.to_json()).to_json(), s.to_json());
  nlohmann::json old = none.to_json();
  old.erase("input_normalization");
  EXPECT_EQ(LdrSpec::from_json(old).input_normalization, "none");
}

TEST(Networks, Ae2WithStandardizedCodesEncodesTheMappedCodeAndReconstructsIt) {
  std::vector<float> v = ramp(Shape{6, 1, 8, 8}).to_vector();
  for (std::size_t i = 0; i < v.size(); ++i)
    v[i] = i % 64 == 5 ? 1.5f : v[i] * static_cast<float>(1 + i % 7);  // element 5: constant
  const Tensor codes(Shape{6, 1, 8, 8}, v);
  Ae2Spec s = silu_mlp(3);
  Ae2 plain(s);
  s.input_normalization = "standardize";
  Ae2 net(s);
  plain.initialize(7);
  net.initialize(7);  // the same names below the map: the same weights
  CodeStandardization fitted(1, 8);
  fitted.fit(codes, "test");
  EXPECT_THROW(plain.set_input_map(fitted), std::logic_error);
  net.set_input_map(fitted);
  const Tensor mapped = net.coordinates(codes);
  const std::vector<float> shift = net.input_map()->shift().to_vector();
  const std::vector<float> scale = net.input_map()->scale().to_vector();
  EXPECT_EQ(scale[5], 0.0f);
  for (std::size_t i = 0; i < v.size(); ++i)
    EXPECT_NEAR(mapped.data()[i], (v[i] - shift[i % 64]) * scale[i % 64], 1e-6) << i;
  EXPECT_EQ(net.encode(codes).to_vector(), plain.encode(mapped).to_vector());
  EXPECT_EQ(plain.coordinates(codes).to_vector(), v);
  EXPECT_EQ(net.trained_parameters().size() + 2, net.named_parameters().size());
  EXPECT_EQ(plain.trained_parameters().size(), plain.named_parameters().size());
  // the spec survives its JSON; a weight file written before the option has no map
  EXPECT_EQ(Ae2Spec::from_json(s.to_json()).to_json(), s.to_json());
  nlohmann::json old = s.to_json();
  old.erase("input_normalization");
  EXPECT_EQ(Ae2Spec::from_json(old).input_normalization, "none");
  s.input_normalization = "pca";
  EXPECT_NE(s.problem().find("ae2.input_normalization: expected \"none\" or \"standardize\", got "
                             "\"pca\""),
            std::string::npos)
      << s.problem();
}

TEST(Networks, AnLdrEnsembleIsTheMeanOfItsMembers) {
  LdrSpec s;
  s.members = 3;
  Ldr ensemble(s);
  ensemble.initialize(7);
  LdrSpec one_spec;
  // member 0 keeps the single classifier's parameter names, so the same seed gives it the
  // single classifier's weights; members 1 and 2 are the single classifier with the weights of
  // "mK_..." copied in
  std::vector<std::unique_ptr<Ldr>> singles;
  for (int k = 0; k < 3; ++k) {
    singles.push_back(std::make_unique<Ldr>(one_spec));
    singles.back()->initialize(7);
  }
  for (int k = 1; k < 3; ++k) {
    const std::string prefix = "m" + std::to_string(k) + "_";
    std::size_t copied = 0;
    for (auto& [name, t] : singles[static_cast<std::size_t>(k)]->named_parameters())
      for (const auto& [ename, et] : ensemble.named_parameters())
        if (ename == prefix + name) {
          std::copy_n(et.data(), et.numel(), t.mutable_data());
          ++copied;
        }
    ASSERT_EQ(copied, singles[0]->named_parameters().size()) << prefix;
  }
  EXPECT_EQ(ensemble.named_parameters().size(), 3 * singles[0]->named_parameters().size());

  Tensor y = ramp(Shape{5, 1, 8, 8});
  const std::vector<Tensor> members = ensemble.member_logits(y);
  ASSERT_EQ(members.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k)
    EXPECT_EQ(members[k].to_vector(), (*singles[k])(y).to_vector()) << "member " << k;
  EXPECT_NE(members[1].to_vector(), members[0].to_vector()) << "members initialised alike";
  // the logit and its input gradient (the score difference) are the members' means
  y.set_requires_grad(true);
  const Tensor logit = ensemble(y);
  const std::vector<float> g = ropes::nn::grad({ropes::nn::sum(logit)}, {y})[0].to_vector();
  std::vector<float> mean_logit(5, 0.0f), mean_grad(g.size(), 0.0f);
  for (std::size_t k = 0; k < 3; ++k) {
    Tensor yk = ramp(Shape{5, 1, 8, 8});
    yk.set_requires_grad(true);
    const Tensor l = (*singles[k])(yk);
    const std::vector<float> gk = ropes::nn::grad({ropes::nn::sum(l)}, {yk})[0].to_vector();
    for (std::size_t i = 0; i < 5; ++i)
      mean_logit[i] += l.to_vector()[i] / 3;
    for (std::size_t i = 0; i < g.size(); ++i)
      mean_grad[i] += gk[i] / 3;
  }
  for (std::size_t i = 0; i < 5; ++i)
    EXPECT_NEAR(logit.to_vector()[i], mean_logit[i], 1e-6) << i;
  for (std::size_t i = 0; i < g.size(); ++i)
    EXPECT_NEAR(g[i], mean_grad[i], 1e-6) << i;

  // the spec's JSON: "members" only for an ensemble, so a single classifier's weight files
  // read as before; 1 to 16 members
  EXPECT_FALSE(one_spec.to_json().contains("members"));
  EXPECT_EQ(LdrSpec::from_json(s.to_json()).members, 3);
  for (const std::int64_t bad : {0, 17}) {
    LdrSpec b;
    b.members = bad;
    EXPECT_EQ(b.problem(), "ldr.members: expected 1 to 16 classifiers, got " + std::to_string(bad));
    EXPECT_THROW(Ldr{b}, std::invalid_argument);
  }
}

// ldr.all_regimes: the LDR written from one classifier over R regimes is output p minus output
// n, and its input gradient (the score difference) is theirs; the witness is the classifier's
// own outputs and gradients, taken apart
TEST(Networks, ARegimeClassifiersRatioIsTheDifferenceOfTwoOutputs) {
  LdrSpec s;
  s.in_channels = 2;
  RegimeClassifier all(s, 5);
  all.initialize(11);
  Tensor y = ramp(Shape{4, 2, 8, 8});
  y.set_requires_grad(true);
  const Tensor f = all(y);
  ASSERT_EQ(f.shape(), (Shape{4, 5}));
  for (const auto& [p, n] :
       std::vector<std::pair<std::int64_t, std::int64_t>>{{1, 0}, {3, 2}, {0, 4}}) {
    Ldr ldr(s);
    all.write_ratio(p, n, ldr);
    Tensor x = ramp(Shape{4, 2, 8, 8});
    x.set_requires_grad(true);
    const Tensor logit = ldr(x);
    const std::vector<float> fv = f.to_vector(), lv = logit.to_vector();
    for (std::size_t i = 0; i < 4; ++i)
      EXPECT_NEAR(lv[i],
                  fv[i * 5 + static_cast<std::size_t>(p)] - fv[i * 5 + static_cast<std::size_t>(n)],
                  1e-5)
          << p << " - " << n << ", sample " << i;
    const Tensor fp = ropes::nn::slice(f, 1, p, p + 1), fn = ropes::nn::slice(f, 1, n, n + 1);
    const std::vector<float> gp = ropes::nn::grad({ropes::nn::sum(fp)}, {y})[0].to_vector();
    const std::vector<float> gn = ropes::nn::grad({ropes::nn::sum(fn)}, {y})[0].to_vector();
    const std::vector<float> g = ropes::nn::grad({ropes::nn::sum(logit)}, {x})[0].to_vector();
    for (std::size_t i = 0; i < g.size(); ++i)
      EXPECT_NEAR(g[i], gp[i] - gn[i], 1e-5) << i;
  }
  Ldr ldr(s);
  EXPECT_THROW(all.write_ratio(5, 0, ldr), std::invalid_argument);
  EXPECT_THROW(all.write_ratio(1, -1, ldr), std::invalid_argument);
  LdrSpec other = s;
  other.hidden = 64;
  Ldr wrong(other);
  EXPECT_THROW(all.write_ratio(1, 0, wrong), std::invalid_argument);
  EXPECT_THROW(RegimeClassifier(s, 1), std::invalid_argument);
  LdrSpec ensemble = s;
  ensemble.members = 2;
  EXPECT_THROW(RegimeClassifier(ensemble, 3), std::invalid_argument);
}

// the cross-entropy against the formula in double, and its gradient against central finite
// differences of that formula; outputs near 90 would overflow exp in float without the row
// maximum taken out
TEST(Networks, SoftmaxCrossEntropyIsTheFormulaAndItsGradientTheFiniteDifferences) {
  const std::vector<float> f = {0.3f, -1.2f, 2.0f, 90.0f, 89.5f, 70.0f, -3.0f, 0.0f, 0.5f};
  const std::vector<int> cls = {2, 1, 0};
  std::vector<float> t(9, 0.0f);
  for (std::size_t i = 0; i < 3; ++i)
    t[i * 3 + static_cast<std::size_t>(cls[i])] = 1.0f;
  const auto formula = [&](const std::vector<double>& x, std::size_t i) {
    double m = -INFINITY, s = 0;
    for (std::size_t j = 0; j < 3; ++j)
      m = std::max(m, x[i * 3 + j]);
    for (std::size_t j = 0; j < 3; ++j)
      s += std::exp(x[i * 3 + j] - m);
    return m + std::log(s) - x[i * 3 + static_cast<std::size_t>(cls[i])];
  };
  Tensor out(Shape{3, 3}, f);
  out.set_requires_grad(true);
  const Tensor ce = softmax_cross_entropy(out, Tensor(Shape{3, 3}, t));
  ASSERT_EQ(ce.shape(), (Shape{3}));
  const std::vector<double> x(f.begin(), f.end());
  for (std::size_t i = 0; i < 3; ++i)
    EXPECT_NEAR(ce.to_vector()[i], formula(x, i), 1e-5) << i;
  const std::vector<float> g = ropes::nn::grad({ropes::nn::sum(ce)}, {out})[0].to_vector();
  for (std::size_t e = 0; e < 9; ++e) {
    std::vector<double> up = x, down = x;
    up[e] += 1e-4;
    down[e] -= 1e-4;
    const double fd = (formula(up, e / 3) - formula(down, e / 3)) / 2e-4;
    EXPECT_NEAR(g[e], fd, 1e-4) << e;
  }
  EXPECT_THROW(softmax_cross_entropy(out, Tensor(Shape{3, 2}, std::vector<float>(6, 0.0f))),
               std::invalid_argument);
}
