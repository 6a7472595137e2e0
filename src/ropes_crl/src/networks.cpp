#include "ropes_crl/networks.hpp"

#include <ropes_nn/ops.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

#include "json_fields.hpp"

namespace ropes::crl {

namespace {

// every parameter but those of a CodeStandardization registered as "input"
std::vector<std::pair<std::string, Tensor>> without_input_map(
    std::vector<std::pair<std::string, Tensor>> all) {
  std::vector<std::pair<std::string, Tensor>> out;
  for (auto& entry : all)
    if (entry.first.rfind("input.", 0) != 0)
      out.push_back(std::move(entry));
  return out;
}

// set_input_map of network `who` ("Ldr", "Ae2") whose input map is `map`
void copy_input_map(CodeStandardization* map, const char* who, const char* field,
                    const std::string& normalization, const CodeStandardization& fitted) {
  if (!map)
    throw std::logic_error(std::string(who) + "::set_input_map: " + field + " is \"" +
                           normalization + "\", not \"standardize\"");
  map->copy_from(fitted, std::string(who) + "::set_input_map");
}

using nn::Conv2d;
using nn::ConvTranspose2d;
using nn::Dense;
using nn::Padding2d;
using nn::ResBlockGN;
using nn::Sequential;

std::string positive_list_problem(const std::string& name, const std::vector<std::int64_t>& v) {
  if (v.empty())
    return name + ": expected at least one width, got []";
  for (std::int64_t w : v)
    if (w < 1)
      return name + ": expected widths >= 1, got " + std::to_string(w);
  return "";
}

// GroupNorm in ResBlockGN needs min(32, w) to divide w
std::string group_norm_problem(const std::string& name, const std::vector<std::int64_t>& v) {
  for (std::int64_t w : v)
    if (w % std::min<std::int64_t>(32, w) != 0)
      return name + ": width " + std::to_string(w) +
             " is not a multiple of 32 (GroupNorm uses min(32, width) groups)";
  return "";
}

// Conv3x3(c -> w), blocks x ResBlockGN(w)
void add_stage(Sequential& s, std::int64_t c, std::int64_t w, int blocks) {
  s.add(std::make_shared<Conv2d>(c, w, 3));
  for (int b = 0; b < blocks; ++b)
    s.add(std::make_shared<ResBlockGN>(w));
}

}  // namespace

// --- AE1 ------------------------------------------------------------------------------------
std::int64_t Ae1Spec::code_size() const {
  std::int64_t s = stem == "patchify" ? image_size / stem_factor : image_size;
  for (std::size_t i = 0; i < widths.size(); ++i)
    s /= 2;
  return s;
}

std::string Ae1Spec::problem() const {
  if (stem != "none" && stem != "patchify")
    return "ae1.stem: expected \"none\" or \"patchify\", got \"" + stem + "\"";
  if (stem == "patchify" && (stem_factor < 2 || stem_channels < 1))
    return "ae1.stem_factor/stem_channels: expected >= 2 and >= 1, got " +
           std::to_string(stem_factor) + " and " + std::to_string(stem_channels);
  if (std::string p = positive_list_problem("ae1.widths", widths); !p.empty())
    return p;
  if (std::string p = group_norm_problem("ae1.widths", widths); !p.empty())
    return p;
  if (blocks_per_stage < 0)
    return "ae1.blocks_per_stage: expected >= 0, got " + std::to_string(blocks_per_stage);
  if (code_head != "conv_relu" && code_head != "linear" && code_head != "resblock_linear")
    return "ae1.code_head: expected \"conv_relu\", \"linear\" or \"resblock_linear\", got \"" +
           code_head + "\"";
  if (code_channels < 1)
    return "ae1.code_channels: expected >= 1, got " + std::to_string(code_channels);
  std::int64_t div = (stem == "patchify" ? stem_factor : 1) << widths.size();
  if (image_size < 1 || image_size % div != 0 || image_size / div < 1)
    return "ae1.image_size: " + std::to_string(image_size) + " is not a multiple of " +
           std::to_string(div) + " (the stem and " + std::to_string(widths.size()) +
           " stride-2 stages)";
  return "";
}

nlohmann::json Ae1Spec::to_json() const {
  nlohmann::json j = {
      {"image_size", image_size},       {"stem", stem},     {"stem_factor", stem_factor},
      {"stem_channels", stem_channels}, {"widths", widths}, {"blocks_per_stage", blocks_per_stage},
      {"code_channels", code_channels}};
  // absent means the paper's head: the weight files of the paper's AE1 keep their bytes
  if (code_head != "conv_relu")
    j["code_head"] = code_head;
  return j;
}

Ae1Spec Ae1Spec::from_json(const nlohmann::json& j) {
  using namespace detail;
  Ae1Spec s;
  s.image_size = get_int(j, "ae1", "image_size");
  s.stem = get_string(j, "ae1", "stem");
  s.stem_factor = static_cast<int>(get_int(j, "ae1", "stem_factor"));
  s.stem_channels = get_int(j, "ae1", "stem_channels");
  s.widths = get_ints(j, "ae1", "widths");
  s.blocks_per_stage = static_cast<int>(get_int(j, "ae1", "blocks_per_stage"));
  s.code_channels = get_int(j, "ae1", "code_channels");
  if (j.contains("code_head"))
    s.code_head = get_string(j, "ae1", "code_head");
  if (const std::string p = s.problem(); !p.empty())
    throw std::invalid_argument(p);
  return s;
}

Ae1::Ae1(const Ae1Spec& spec) : spec_(spec) {
  if (const std::string p = spec.problem(); !p.empty())
    throw std::invalid_argument("Ae1: " + p);
  encoder_ = register_module("encoder", std::make_shared<Sequential>());
  decoder_ = register_module("decoder", std::make_shared<Sequential>());
  const bool patchify = spec.stem == "patchify";
  const std::size_t n = spec.widths.size();
  // encoder: [stem], stages each ending in a stride-2 conv
  std::int64_t c = 1;
  if (patchify) {
    encoder_->add(std::make_shared<Conv2d>(1, spec.stem_channels, spec.stem_factor,
                                           spec.stem_factor, Padding2d::valid()));
    c = spec.stem_channels;
  }
  const bool head = spec.code_head == "resblock_linear";
  for (std::size_t s = 0; s < n; ++s) {
    const std::int64_t w = spec.widths[s];
    const bool last = s + 1 == n;
    add_stage(*encoder_, c, w, spec.blocks_per_stage);
    encoder_->add(std::make_shared<Conv2d>(w, last && !head ? spec.code_channels : w, 3, 2));
    if (!(last && spec.code_head == "linear"))
      encoder_->add(std::make_shared<nn::ReLU>());
    c = w;
  }
  const std::int64_t deepest = spec.widths.back();
  if (head) {
    encoder_->add(std::make_shared<ResBlockGN>(deepest));
    encoder_->add(std::make_shared<nn::GroupNorm>(deepest));
    encoder_->add(std::make_shared<nn::ReLU>());
    encoder_->add(std::make_shared<Conv2d>(deepest, spec.code_channels, 1));
  }
  // decoder: the mirror, each stage ending in a stride-2 transposed conv
  c = spec.code_channels;
  if (head) {
    add_stage(*decoder_, c, deepest, 1);
    c = deepest;
  }
  for (std::size_t s = n; s-- > 0;) {
    const std::int64_t w = spec.widths[s];
    add_stage(*decoder_, c, w, spec.blocks_per_stage);
    decoder_->add(std::make_shared<ConvTranspose2d>(w, w, 4, 2));
    decoder_->add(std::make_shared<nn::ReLU>());
    c = w;
  }
  if (patchify)
    decoder_->add(std::make_shared<ConvTranspose2d>(c, 1, spec.stem_factor, spec.stem_factor,
                                                    Padding2d::valid()));
  else
    decoder_->add(std::make_shared<Conv2d>(c, 1, 3));
  decoder_->add(std::make_shared<nn::ReLU>());
}

Tensor Ae1::encode(const Tensor& image) {
  return (*encoder_)(image);
}
Tensor Ae1::decode(const Tensor& code) {
  return (*decoder_)(code);
}

// --- CodeStandardization --------------------------------------------------------------------
CodeStandardization::CodeStandardization(std::int64_t channels, std::int64_t side) {
  shift_ = register_parameter("shift", nn::Shape{channels, side, side}, "zeros");
  scale_ = register_parameter("scale", nn::Shape{channels, side, side}, "ones");
}

Tensor CodeStandardization::forward(const Tensor& y) {
  return nn::mul(nn::sub(y, shift_), scale_);
}

void CodeStandardization::fit(const Tensor& codes, const std::string& who) {
  const nn::Shape& want = scale_.shape();
  if (codes.rank() != 4 || codes.shape()[0] < 1 || codes.shape()[1] != want[0] ||
      codes.shape()[2] != want[1] || codes.shape()[3] != want[2])
    throw std::invalid_argument(who + ": codes are " + codes.shape().str() +
                                ", expected [n >= 1, " + std::to_string(want[0]) + ", " +
                                std::to_string(want[1]) + ", " + std::to_string(want[2]) + "]");
  const std::int64_t n = codes.shape()[0], per = scale_.numel();
  const float* y = codes.data();
  std::vector<double> mean(static_cast<std::size_t>(per), 0.0), sd(mean.size(), 0.0);
  for (std::int64_t r = 0; r < n; ++r)
    for (std::int64_t k = 0; k < per; ++k) {
      const float v = y[r * per + k];
      if (!std::isfinite(v))
        throw std::invalid_argument(who + ": code " + std::to_string(r) + " holds " +
                                    std::to_string(v) + " at element " + std::to_string(k) +
                                    "; expected finite values");
      mean[static_cast<std::size_t>(k)] += v;
    }
  for (double& m : mean)
    m /= static_cast<double>(n);
  for (std::int64_t r = 0; r < n; ++r)
    for (std::int64_t k = 0; k < per; ++k) {
      const double d = y[r * per + k] - mean[static_cast<std::size_t>(k)];
      sd[static_cast<std::size_t>(k)] += d * d;
    }
  double largest = 0;
  for (double& v : sd) {
    v = std::sqrt(v / static_cast<double>(n));
    largest = std::max(largest, v);
  }
  if (!(largest > 0))
    throw std::invalid_argument(who + ": the " + std::to_string(n) +
                                " codes are all equal; AE1 encodes every image alike");
  float* shift = shift_.mutable_data();
  float* scale = scale_.mutable_data();
  for (std::int64_t k = 0; k < per; ++k) {
    const double v = sd[static_cast<std::size_t>(k)];
    shift[k] = static_cast<float>(mean[static_cast<std::size_t>(k)]);
    scale[k] = v <= 1e-3 * largest ? 0.0f : static_cast<float>(1.0 / std::max(v, 1e-2 * largest));
  }
  mark_initialized("shift");
  mark_initialized("scale");
}

void CodeStandardization::copy_from(const CodeStandardization& fitted, const std::string& who) {
  if (fitted.scale_.shape() != scale_.shape())
    throw std::invalid_argument(who + ": the fitted map is " + fitted.scale_.shape().str() +
                                ", expected " + scale_.shape().str());
  std::copy_n(fitted.shift_.data(), shift_.numel(), shift_.mutable_data());
  std::copy_n(fitted.scale_.data(), scale_.numel(), scale_.mutable_data());
  mark_initialized("shift");
  mark_initialized("scale");
}

Tensor CodeStandardization::to_mapped_gradient(const Tensor& g) const {
  const std::int64_t per = scale_.numel();
  const nn::Shape& want = scale_.shape();
  if (g.rank() != 4 || g.shape()[1] != want[0] || g.shape()[2] != want[1] ||
      g.shape()[3] != want[2])
    throw std::invalid_argument("CodeStandardization::to_mapped_gradient: gradient is " +
                                g.shape().str() + ", expected [n, " + scale_.shape().str() + "]");
  std::vector<float> out(g.data(), g.data() + g.numel());
  const float* scale = scale_.data();
  for (std::size_t i = 0; i < out.size(); ++i) {
    const float s = scale[static_cast<std::int64_t>(i) % per];
    out[i] = s == 0.0f ? 0.0f : out[i] / s;
  }
  return Tensor(g.shape(), out);
}

// --- LDR ------------------------------------------------------------------------------------
std::string LdrSpec::problem() const {
  if (in_channels < 1)
    return "ldr.in_channels: expected >= 1, got " + std::to_string(in_channels);
  if (std::string p = positive_list_problem("ldr.widths", widths); !p.empty())
    return p;
  if (input_size - 2 * static_cast<std::int64_t>(widths.size()) < 1)
    return "ldr.widths: " + std::to_string(widths.size()) +
           " valid 3x3 convolutions need an input wider than " + std::to_string(2 * widths.size()) +
           ", got " + std::to_string(input_size);
  if (hidden < 1)
    return "ldr.hidden: expected >= 1, got " + std::to_string(hidden);
  if (members < 1 || members > 16)
    return "ldr.members: expected 1 to 16 classifiers, got " + std::to_string(members);
  if (input_normalization != "none" && input_normalization != "standardize")
    return "ldr.input_normalization: expected \"none\" or \"standardize\", got \"" +
           input_normalization + "\"";
  return "";
}

nlohmann::json LdrSpec::to_json() const {
  nlohmann::json j = {{"in_channels", in_channels},
                      {"input_size", input_size},
                      {"widths", widths},
                      {"hidden", hidden},
                      {"input_normalization", input_normalization}};
  if (members != 1)  // a single classifier's metadata stays as before the option
    j["members"] = members;
  return j;
}

LdrSpec LdrSpec::from_json(const nlohmann::json& j) {
  using namespace detail;
  LdrSpec s;
  s.in_channels = get_int(j, "ldr", "in_channels");
  s.input_size = get_int(j, "ldr", "input_size");
  s.widths = get_ints(j, "ldr", "widths");
  s.hidden = get_int(j, "ldr", "hidden");
  // weight files written before the option existed have no input map
  if (j.contains("input_normalization"))
    s.input_normalization = get_string(j, "ldr", "input_normalization");
  if (j.contains("members"))  // absent: one classifier
    s.members = get_int(j, "ldr", "members");
  if (const std::string p = s.problem(); !p.empty())
    throw std::invalid_argument(p);
  return s;
}

Ldr::Ldr(const LdrSpec& spec) : spec_(spec) {
  if (const std::string p = spec.problem(); !p.empty())
    throw std::invalid_argument("Ldr: " + p);
  std::int64_t c = spec.in_channels, side = spec.input_size;
  if (spec.input_normalization == "standardize")
    input_ = register_module("input", std::make_shared<CodeStandardization>(c, side));
  const std::int64_t in = c;
  for (std::int64_t k = 0; k < spec.members; ++k) {
    const std::string prefix = k == 0 ? "" : "m" + std::to_string(k) + "_";
    Member m;
    m.features = register_module(prefix + "features", std::make_shared<Sequential>());
    c = in;
    side = spec.input_size;
    for (std::int64_t w : spec.widths) {
      m.features->add(std::make_shared<Conv2d>(c, w, 3, 1, Padding2d::valid()));
      m.features->add(std::make_shared<nn::ReLU>());
      c = w;
      side -= 2;
    }
    m.hidden =
        register_module(prefix + "hidden", std::make_shared<Dense>(c * side * side, spec.hidden));
    m.out = register_module(prefix + "out", std::make_shared<Dense>(spec.hidden, 1));
    members_.push_back(std::move(m));
  }
}

Tensor Ldr::member_logit(const Member& m, const Tensor& x) const {
  const Tensor logit = (*m.out)(nn::relu((*m.hidden)(nn::flatten((*m.features)(x)))));
  return nn::reshape(logit, nn::Shape{logit.shape()[0]});
}

std::vector<Tensor> Ldr::member_logits(const Tensor& y) {
  const Tensor x = input_ ? (*input_)(y) : y;
  std::vector<Tensor> out;
  for (const Member& m : members_)
    out.push_back(member_logit(m, x));
  return out;
}

Tensor Ldr::forward(const Tensor& y) {
  const std::vector<Tensor> logits = member_logits(y);
  if (logits.size() == 1)  // one classifier: its logit as it was before the option
    return logits[0];
  Tensor sum = logits[0];
  for (std::size_t k = 1; k < logits.size(); ++k)
    sum = nn::add(sum, logits[k]);
  return nn::mul_scalar(sum, 1.0f / static_cast<float>(logits.size()));
}

void Ldr::set_input_map(const CodeStandardization& fitted) {
  copy_input_map(input_.get(), "Ldr", "ldr.input_normalization", spec_.input_normalization, fitted);
}

std::vector<std::pair<std::string, Tensor>> Ldr::trained_parameters() const {
  return without_input_map(named_parameters());
}

// --- one classifier over every regime (ldr.all_regimes) ------------------------------------
RegimeClassifier::RegimeClassifier(const LdrSpec& spec, std::int64_t regimes)
    : spec_(spec), regimes_(regimes) {
  if (const std::string p = spec.problem(); !p.empty())
    throw std::invalid_argument("RegimeClassifier: " + p);
  if (spec.members != 1)
    throw std::invalid_argument("RegimeClassifier: ldr.members is " + std::to_string(spec.members) +
                                "; expected 1");
  if (regimes < 2)
    throw std::invalid_argument("RegimeClassifier: " + std::to_string(regimes) +
                                " regimes; expected at least 2");
  std::int64_t c = spec.in_channels, side = spec.input_size;
  if (spec.input_normalization == "standardize")
    input_ = register_module("input", std::make_shared<CodeStandardization>(c, side));
  features_ = register_module("features", std::make_shared<Sequential>());
  for (std::int64_t w : spec.widths) {
    features_->add(std::make_shared<Conv2d>(c, w, 3, 1, Padding2d::valid()));
    features_->add(std::make_shared<nn::ReLU>());
    c = w;
    side -= 2;
  }
  hidden_ = register_module("hidden", std::make_shared<Dense>(c * side * side, spec.hidden));
  out_ = register_module("out", std::make_shared<Dense>(spec.hidden, regimes));
}

Tensor RegimeClassifier::forward(const Tensor& y) {
  const Tensor x = input_ ? (*input_)(y) : y;
  return (*out_)(nn::relu((*hidden_)(nn::flatten((*features_)(x)))));
}

void RegimeClassifier::set_input_map(const CodeStandardization& fitted) {
  copy_input_map(input_.get(), "RegimeClassifier", "ldr.input_normalization",
                 spec_.input_normalization, fitted);
}

std::vector<std::pair<std::string, Tensor>> RegimeClassifier::trained_parameters() const {
  return without_input_map(named_parameters());
}

void RegimeClassifier::write_ratio(std::int64_t positive, std::int64_t negative, Ldr& ldr) const {
  for (const std::int64_t r : {positive, negative})
    if (r < 0 || r >= regimes_)
      throw std::invalid_argument("RegimeClassifier::write_ratio: regime " + std::to_string(r) +
                                  " of " + std::to_string(regimes_));
  if (ldr.spec().to_json() != spec_.to_json())
    throw std::invalid_argument("RegimeClassifier::write_ratio: the Ldr's spec " +
                                ldr.spec().to_json().dump() + " is not the classifier's " +
                                spec_.to_json().dump());
  std::map<std::string, Tensor> mine;
  for (const auto& [name, w] : named_parameters())
    mine[name] = w;
  const std::int64_t h = spec_.hidden;
  for (auto [name, w] : ldr.named_parameters()) {
    float* to = w.mutable_data();
    const float* from = mine.at(name).data();
    if (name == "out.weight") {  // [hidden, 1] <- column positive - column negative of [hidden, R]
      for (std::int64_t i = 0; i < h; ++i)
        to[i] = from[i * regimes_ + positive] - from[i * regimes_ + negative];
    } else if (name == "out.bias") {
      to[0] = from[positive] - from[negative];
    } else {
      std::copy(from, from + w.numel(), to);
    }
    ldr.mark_initialized(name);
  }
}

Tensor softmax_cross_entropy(const Tensor& outputs, const Tensor& one_hot) {
  if (outputs.rank() != 2 || one_hot.shape() != outputs.shape())
    throw std::invalid_argument("softmax_cross_entropy: outputs " + outputs.shape().str() +
                                " and one-hot rows " + one_hot.shape().str() +
                                "; expected two [N, R] of one shape");
  const std::int64_t n = outputs.shape()[0], r = outputs.shape()[1];
  std::vector<float> top(static_cast<std::size_t>(n));
  const float* f = outputs.data();
  for (std::int64_t i = 0; i < n; ++i)
    top[static_cast<std::size_t>(i)] = *std::max_element(f + i * r, f + (i + 1) * r);
  const Tensor m(nn::Shape{n, 1}, top);  // a constant: the result does not depend on it
  const Tensor lse = nn::add(nn::log(nn::sum(nn::exp(nn::sub(outputs, m)), {1}, true)), m);
  const Tensor picked = nn::sum(nn::mul(outputs, one_hot), {1}, true);
  return nn::reshape(nn::sub(lse, picked), nn::Shape{n});
}

// --- AE2 ------------------------------------------------------------------------------------
std::string Ae2Spec::problem() const {
  if (input_normalization != "none" && input_normalization != "standardize")
    return "ae2.input_normalization: expected \"none\" or \"standardize\", got \"" +
           input_normalization + "\"";
  if (kind != "conv" && kind != "mlp")
    return "ae2.kind: expected \"conv\" or \"mlp\", got \"" + kind + "\"";
  if (in_channels < 1)
    return "ae2.in_channels: expected >= 1, got " + std::to_string(in_channels);
  if (latent_dim < 1)
    return "ae2.latent_dim: expected >= 1, got " + std::to_string(latent_dim);
  if (std::string p = positive_list_problem("ae2.widths", widths); !p.empty())
    return p;
  if (kind == "mlp") {
    if (activation != "relu" && activation != "silu")
      return "ae2.activation: expected \"relu\" or \"silu\", got \"" + activation + "\"";
    return "";
  }
  if (std::string p = group_norm_problem("ae2.widths", widths); !p.empty())
    return p;
  if (decoder_widths.size() != widths.size())
    return "ae2.decoder_widths: expected " + std::to_string(widths.size()) +
           " widths (one per encoder stage), got " + std::to_string(decoder_widths.size());
  if (std::string p = positive_list_problem("ae2.decoder_widths", decoder_widths); !p.empty())
    return p;
  if (std::string p = group_norm_problem("ae2.decoder_widths", decoder_widths); !p.empty())
    return p;
  if ((std::int64_t{1} << widths.size()) != input_size)
    return "ae2.widths: " + std::to_string(widths.size()) +
           " stride-2 stages do not take an input of side " + std::to_string(input_size) + " to 1";
  if (blocks_per_stage < 0)
    return "ae2.blocks_per_stage: expected >= 0, got " + std::to_string(blocks_per_stage);
  return "";
}

nlohmann::json Ae2Spec::to_json() const {
  return {{"kind", kind},
          {"in_channels", in_channels},
          {"input_size", input_size},
          {"latent_dim", latent_dim},
          {"widths", widths},
          {"decoder_widths", decoder_widths},
          {"blocks_per_stage", blocks_per_stage},
          {"activation", activation},
          {"input_normalization", input_normalization}};
}

Ae2Spec Ae2Spec::from_json(const nlohmann::json& j) {
  using namespace detail;
  Ae2Spec s;
  s.kind = get_string(j, "ae2", "kind");
  s.in_channels = get_int(j, "ae2", "in_channels");
  s.input_size = get_int(j, "ae2", "input_size");
  s.latent_dim = get_int(j, "ae2", "latent_dim");
  s.widths = get_ints(j, "ae2", "widths");
  s.decoder_widths = get_ints(j, "ae2", "decoder_widths");
  s.blocks_per_stage = static_cast<int>(get_int(j, "ae2", "blocks_per_stage"));
  s.activation = get_string(j, "ae2", "activation");
  // weight files written before the option existed have no input map
  if (j.contains("input_normalization"))
    s.input_normalization = get_string(j, "ae2", "input_normalization");
  if (const std::string p = s.problem(); !p.empty())
    throw std::invalid_argument(p);
  return s;
}

Ae2::Ae2(const Ae2Spec& spec) : spec_(spec) {
  if (const std::string p = spec.problem(); !p.empty())
    throw std::invalid_argument("Ae2: " + p);
  if (spec.input_normalization == "standardize")
    input_ = register_module(
        "input", std::make_shared<CodeStandardization>(spec.in_channels, spec.input_size));
  const std::int64_t inputs = spec.in_channels * spec.input_size * spec.input_size;
  if (spec.kind == "mlp") {
    std::int64_t c = inputs;
    for (std::size_t i = 0; i < spec.widths.size(); ++i) {
      mlp_encoder_.push_back(register_module("encoder." + std::to_string(i),
                                             std::make_shared<Dense>(c, spec.widths[i])));
      c = spec.widths[i];
    }
    to_latent_ = register_module("to_latent", std::make_shared<Dense>(c, spec.latent_dim));
    c = spec.latent_dim;
    for (std::size_t i = spec.widths.size(); i-- > 0;) {
      mlp_decoder_.push_back(register_module("decoder." + std::to_string(mlp_decoder_.size()),
                                             std::make_shared<Dense>(c, spec.widths[i])));
      c = spec.widths[i];
    }
    from_latent_ = register_module("to_output", std::make_shared<Dense>(c, inputs));
    return;
  }
  encoder_ = register_module("encoder", std::make_shared<Sequential>());
  std::int64_t c = spec.in_channels;
  for (std::int64_t w : spec.widths) {
    add_stage(*encoder_, c, w, spec.blocks_per_stage);
    encoder_->add(std::make_shared<Conv2d>(w, w, 3, 2));
    encoder_->add(std::make_shared<nn::ReLU>());
    c = w;
  }
  to_latent_ = register_module("to_latent", std::make_shared<Dense>(c, spec.latent_dim));
  from_latent_ = register_module("from_latent", std::make_shared<Dense>(spec.latent_dim, c));
  decoder_ = register_module("decoder", std::make_shared<Sequential>());
  for (std::int64_t w : spec.decoder_widths) {
    add_stage(*decoder_, c, w, spec.blocks_per_stage);
    decoder_->add(std::make_shared<ConvTranspose2d>(w, w, 4, 2));
    decoder_->add(std::make_shared<nn::ReLU>());
    c = w;
  }
  decoder_->add(std::make_shared<Conv2d>(c, spec.in_channels, 3));
  decoder_->add(std::make_shared<nn::ReLU>());
}

Tensor Ae2::activate(const Tensor& x) const {
  return spec_.activation == "silu" ? nn::mul(x, nn::sigmoid(x)) : nn::relu(x);
}

Tensor Ae2::coordinates(const Tensor& y) {
  return input_ ? (*input_)(y) : y;
}

void Ae2::set_input_map(const CodeStandardization& fitted) {
  copy_input_map(input_.get(), "Ae2", "ae2.input_normalization", spec_.input_normalization, fitted);
}

std::vector<std::pair<std::string, Tensor>> Ae2::trained_parameters() const {
  return without_input_map(named_parameters());
}

Tensor Ae2::encode(const Tensor& y_in) {
  const Tensor y = coordinates(y_in);
  if (spec_.kind == "mlp") {
    Tensor h = nn::flatten(y);
    for (const auto& layer : mlp_encoder_)
      h = activate((*layer)(h));
    return (*to_latent_)(h);
  }
  return (*to_latent_)(nn::flatten((*encoder_)(y)));
}

Tensor Ae2::decode(const Tensor& z) {
  const std::int64_t n = z.shape()[0];
  if (spec_.kind == "mlp") {
    Tensor h = z;
    for (const auto& layer : mlp_decoder_)
      h = activate((*layer)(h));
    return nn::reshape((*from_latent_)(h),
                       nn::Shape{n, spec_.in_channels, spec_.input_size, spec_.input_size});
  }
  const Tensor h = nn::relu((*from_latent_)(z));
  return (*decoder_)(nn::reshape(h, nn::Shape{n, h.shape()[1], 1, 1}));
}

}  // namespace ropes::crl
