#include "ropes_crl/networks.hpp"

#include <ropes_nn/ops.hpp>

#include <stdexcept>

#include "json_fields.hpp"

namespace ropes::crl {

namespace {

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
  return {
      {"image_size", image_size},       {"stem", stem},     {"stem_factor", stem_factor},
      {"stem_channels", stem_channels}, {"widths", widths}, {"blocks_per_stage", blocks_per_stage},
      {"code_channels", code_channels}};
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
  for (std::size_t s = 0; s < n; ++s) {
    const std::int64_t w = spec.widths[s];
    add_stage(*encoder_, c, w, spec.blocks_per_stage);
    encoder_->add(std::make_shared<Conv2d>(w, s + 1 < n ? w : spec.code_channels, 3, 2));
    encoder_->add(std::make_shared<nn::ReLU>());
    c = w;
  }
  // decoder: the mirror, each stage ending in a stride-2 transposed conv
  c = spec.code_channels;
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
  return "";
}

nlohmann::json LdrSpec::to_json() const {
  return {{"in_channels", in_channels},
          {"input_size", input_size},
          {"widths", widths},
          {"hidden", hidden}};
}

LdrSpec LdrSpec::from_json(const nlohmann::json& j) {
  using namespace detail;
  LdrSpec s;
  s.in_channels = get_int(j, "ldr", "in_channels");
  s.input_size = get_int(j, "ldr", "input_size");
  s.widths = get_ints(j, "ldr", "widths");
  s.hidden = get_int(j, "ldr", "hidden");
  if (const std::string p = s.problem(); !p.empty())
    throw std::invalid_argument(p);
  return s;
}

Ldr::Ldr(const LdrSpec& spec) : spec_(spec) {
  if (const std::string p = spec.problem(); !p.empty())
    throw std::invalid_argument("Ldr: " + p);
  features_ = register_module("features", std::make_shared<Sequential>());
  std::int64_t c = spec.in_channels, side = spec.input_size;
  for (std::int64_t w : spec.widths) {
    features_->add(std::make_shared<Conv2d>(c, w, 3, 1, Padding2d::valid()));
    features_->add(std::make_shared<nn::ReLU>());
    c = w;
    side -= 2;
  }
  hidden_ = register_module("hidden", std::make_shared<Dense>(c * side * side, spec.hidden));
  out_ = register_module("out", std::make_shared<Dense>(spec.hidden, 1));
}

Tensor Ldr::forward(const Tensor& y) {
  const Tensor logit = (*out_)(nn::relu((*hidden_)(nn::flatten((*features_)(y)))));
  return nn::reshape(logit, nn::Shape{logit.shape()[0]});
}

// --- AE2 ------------------------------------------------------------------------------------
std::string Ae2Spec::problem() const {
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
          {"activation", activation}};
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
  if (const std::string p = s.problem(); !p.empty())
    throw std::invalid_argument(p);
  return s;
}

Ae2::Ae2(const Ae2Spec& spec) : spec_(spec) {
  if (const std::string p = spec.problem(); !p.empty())
    throw std::invalid_argument("Ae2: " + p);
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

Tensor Ae2::encode(const Tensor& y) {
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
