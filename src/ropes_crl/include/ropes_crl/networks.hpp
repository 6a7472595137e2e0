#pragma once
/// @file networks.hpp
/// The three networks of ROPES (paper, appendix "Architecture Details", tables
/// "Autoencoder1", "Autoencoder 2" and "LDR"), parametrised so that one code path builds the
/// `paper` preset exactly and the smaller presets this CPU can train.
///
/// Shapes (NCHW):
///   Ae1:  image [N, 1, S, S]  -> code [N, K, S/2^stages/stem, ...] = [N, K, 8, 8] -> [N, 1, S, S]
///   Ldr:  y [N, C, 8, 8] -> logit [N]
///   Ae2:  y [N, C, 8, 8] -> z [N, d] -> y_hat [N, C, 8, 8]
/// Each spec has to_json()/from_json() so that a weight file's metadata rebuilds its network.
#include <ropes_nn/layers.hpp>
#include <ropes_nn/module.hpp>

#include <nlohmann/json.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace ropes::crl {

using nn::Tensor;

/// AE1, the image autoencoder. Encoder: an optional stem, then per stage
/// Conv3x3(c -> widths[s]), blocks x ResBlockGN(widths[s]), Conv3x3 stride 2
/// (-> widths[s], or code_channels after the last stage), ReLU. Decoder: per stage in reverse
/// Conv3x3(c -> widths[s]), blocks x ResBlockGN, ConvTranspose4x4 stride 2, ReLU; then
/// Conv3x3(-> 1) (stem "none") or ConvTranspose stem x stem stride stem (stem "patchify"),
/// ReLU. The paper: stem none, widths 64/128/256/512, 2 blocks, image 128, code 8x8x1.
/// code_head changes how the encoder ends (see the field); the paper's is "conv_relu".
struct Ae1Spec {
  std::int64_t image_size = 128;
  std::string stem = "none";  ///< "none" or "patchify" (a k x k stride-k conv, k = stem_factor)
  int stem_factor = 4;        ///< patchify only: 128 -> 32 for 4
  std::int64_t stem_channels = 16;
  std::vector<std::int64_t> widths = {64, 128, 256, 512};
  int blocks_per_stage = 2;
  std::int64_t code_channels = 1;
  /// How the encoder ends. "conv_relu" (the paper's): the last stride-2 conv gives the code,
  /// then ReLU. "linear": the same conv without the ReLU. "resblock_linear": the last
  /// stride-2 conv keeps widths.back() channels (ReLU), then at the code's side ResBlockGN,
  /// GroupNorm, ReLU and a linear 1x1 conv to code_channels; the decoder starts with
  /// Conv3x3(code_channels -> widths.back()) and a ResBlockGN there. Written to JSON only
  /// when not "conv_relu", so files from before the field read as the paper's.
  std::string code_head = "conv_relu";

  /// The code's side: image_size / (stem factor) / 2^stages.
  std::int64_t code_size() const;
  /// What is wrong with the spec ("" when nothing), naming the field and the value.
  std::string problem() const;
  nlohmann::json to_json() const;
  /// Throws std::invalid_argument naming the field for a missing or invalid value.
  static Ae1Spec from_json(const nlohmann::json& j);
};

class Ae1 : public nn::Module {
 public:
  explicit Ae1(const Ae1Spec& spec);
  const Ae1Spec& spec() const { return spec_; }
  /// [N, 1, S, S] -> [N, code_channels, 8, 8]
  Tensor encode(const Tensor& image);
  /// [N, code_channels, 8, 8] -> [N, 1, S, S]
  Tensor decode(const Tensor& code);

 protected:
  Tensor forward(const Tensor& image) override { return decode(encode(image)); }

 private:
  Ae1Spec spec_;
  std::shared_ptr<nn::Sequential> encoder_, decoder_;
};

/// A fixed elementwise map of codes, y [N, C, 8, 8] -> (y - shift) * scale, for networks
/// that read standardised codes (not in the paper). Parameters "shift" and "scale", [C, 8, 8],
/// saved with the weights and never trained: fit() sets them from training codes.
class CodeStandardization : public nn::Module {
 public:
  CodeStandardization(std::int64_t channels, std::int64_t side);
  /// shift = the elementwise mean of `codes` [N, C, 8, 8]; scale = 1 / max(sd, 0.01 * max sd)
  /// with sd the elementwise (population) standard deviation and max sd its largest value,
  /// and 0 where sd <= 0.001 * max sd: an element that does not vary carries no
  /// information, the network does not see it and gradients through the map are 0 there.
  /// Throws std::invalid_argument naming `who` when `codes` has another shape, holds a
  /// non-finite value, or does not vary at all.
  void fit(const Tensor& codes, const std::string& who);
  /// Takes `fitted`'s shift and scale; std::invalid_argument naming `who` when its shape
  /// differs.
  void copy_from(const CodeStandardization& fitted, const std::string& who);
  const Tensor& shift() const { return shift_; }
  const Tensor& scale() const { return scale_; }
  /// A gradient in y's coordinates moved to the map's: g / scale, 0 where scale is 0 (for
  /// s = (y - shift) * scale, d/ds = d/dy / scale). g: [N, C, 8, 8].
  Tensor to_mapped_gradient(const Tensor& g) const;

 protected:
  Tensor forward(const Tensor& y) override;

 private:
  Tensor shift_, scale_;
};

/// LDR, the log-density-ratio classifier: three valid Conv3x3 + ReLU (widths), flatten, Dense
/// hidden + ReLU, Dense 1. The paper: widths 32/64/128, hidden 128, input 8x8xC.
///
/// input_normalization "standardize" (not in the paper) puts a CodeStandardization in front
/// (parameters "input.shift", "input.scale"), set by set_input_map. The logit is
/// still a function of y, so its gradient, the score difference, is taken in y's coordinates
/// through the map.
///
/// members > 1 (an extension, not in the paper): an ensemble of that many such classifiers
/// behind the one input map, each initialised apart (member k's parameters are named
/// "mK_features", "mK_hidden", "mK_out"; member 0's keep the plain names); the logit is the
/// members' mean, so the score difference is their mean gradient.
struct LdrSpec {
  std::int64_t in_channels = 1;
  std::int64_t input_size = 8;
  std::vector<std::int64_t> widths = {32, 64, 128};
  std::int64_t hidden = 128;
  std::string input_normalization = "none";  ///< "none" (the paper) or "standardize"
  std::int64_t members = 1;                  ///< 1 (the paper) or an ensemble's size

  std::string problem() const;
  nlohmann::json to_json() const;
  static LdrSpec from_json(const nlohmann::json& j);
};

class Ldr : public nn::Module {
 public:
  explicit Ldr(const LdrSpec& spec);
  const LdrSpec& spec() const { return spec_; }

  /// With input_normalization "standardize": copies a fitted map's shift and scale into the
  /// input map. std::logic_error when the spec has no input map, std::invalid_argument when
  /// `fitted` has another shape.
  void set_input_map(const CodeStandardization& fitted);
  /// The input map (null without one).
  const CodeStandardization* input_map() const { return input_.get(); }
  /// The parameters an optimiser trains: every parameter but the input map's.
  std::vector<std::pair<std::string, Tensor>> trained_parameters() const;
  /// y [N, C, 8, 8] -> each member's logit [N], members in order (the forward's mean of these)
  std::vector<Tensor> member_logits(const Tensor& y);

 protected:
  /// y [N, C, 8, 8] -> logit [N]
  Tensor forward(const Tensor& y) override;

 private:
  struct Member {
    std::shared_ptr<nn::Sequential> features;
    std::shared_ptr<nn::Dense> hidden, out;
  };
  Tensor member_logit(const Member& m, const Tensor& x) const;
  LdrSpec spec_;
  std::shared_ptr<CodeStandardization> input_;  // with "standardize"
  std::vector<Member> members_;
};

/// ldr.all_regimes (an extension, not in the paper): one classifier over R regimes, the
/// LDR's architecture (its parameter names, its input map) with R outputs instead of one.
/// Trained by softmax cross-entropy on the regimes, output r estimates log p_r(y) up to one
/// function of y, so the difference of two outputs estimates the log density ratio of their
/// regimes. spec.members must be 1.
class RegimeClassifier : public nn::Module {
 public:
  RegimeClassifier(const LdrSpec& spec, std::int64_t regimes);
  std::int64_t regimes() const { return regimes_; }
  /// As Ldr::set_input_map.
  void set_input_map(const CodeStandardization& fitted);
  /// The parameters an optimiser trains: every parameter but the input map's.
  std::vector<std::pair<std::string, Tensor>> trained_parameters() const;
  /// Writes into `ldr` (a one-member Ldr of the same spec) the classifier whose logit is
  /// output `positive` minus output `negative`: the same input map and trunk, and the
  /// difference of the two columns of the output layer. std::invalid_argument for a regime
  /// out of range or another spec.
  void write_ratio(std::int64_t positive, std::int64_t negative, Ldr& ldr) const;

 protected:
  /// y [N, C, 8, 8] -> one output a regime [N, R]
  Tensor forward(const Tensor& y) override;

 private:
  LdrSpec spec_;
  std::int64_t regimes_;
  std::shared_ptr<CodeStandardization> input_;
  std::shared_ptr<nn::Sequential> features_;
  std::shared_ptr<nn::Dense> hidden_, out_;
};

/// Per-sample softmax cross-entropy, log sum_j exp(f_ij) - sum_j t_ij f_ij, of outputs f [N, R]
/// against one-hot rows t [N, R]: [N]. Differentiable in f; each row's maximum is taken out
/// before exp, so large outputs do not overflow.
Tensor softmax_cross_entropy(const Tensor& outputs, const Tensor& one_hot);

/// AE2, the disentangling autoencoder on the codes Y.
///   kind "conv" (the paper): per stage Conv3x3(c -> widths[s]), blocks x ResBlockGN,
///     Conv3x3 stride 2, ReLU (8 -> 4 -> 2 -> 1); Dense(widths.back() -> d); decoder
///     Dense(d -> widths.back()) + ReLU, reshape to 1x1, per stage of decoder_widths
///     Conv3x3, blocks x ResBlockGN, ConvTranspose4x4 stride 2, ReLU; Conv3x3(-> C), ReLU.
///     The paper: widths 64/128/256, decoder widths 512/256/128, 2 blocks.
///   kind "mlp": flatten, Dense + activation per hidden width, Dense(-> d); decoder the
///     mirror, Dense(-> C*8*8) with no activation, reshaped to [N, C, 8, 8].
struct Ae2Spec {
  std::string kind = "conv";  ///< "conv" or "mlp"
  std::int64_t in_channels = 1;
  std::int64_t input_size = 8;
  std::int64_t latent_dim = 3;
  std::vector<std::int64_t> widths = {64, 128, 256};           ///< conv encoder / mlp hidden
  std::vector<std::int64_t> decoder_widths = {512, 256, 128};  ///< conv only
  int blocks_per_stage = 2;                                    ///< conv only
  std::string activation = "relu";  ///< mlp only: "relu" or "silu" (x * sigmoid(x))
  /// "none" (the paper) or "standardize": a CodeStandardization in front of the encoder; the
  /// decoder then reconstructs the standardised code (see Ae2::coordinates).
  std::string input_normalization = "none";

  std::string problem() const;
  nlohmann::json to_json() const;
  static Ae2Spec from_json(const nlohmann::json& j);
};

class Ae2 : public nn::Module {
 public:
  explicit Ae2(const Ae2Spec& spec);
  const Ae2Spec& spec() const { return spec_; }
  /// y [N, C, 8, 8] -> z [N, d]
  Tensor encode(const Tensor& y);
  /// z [N, d] -> the reconstruction [N, C, 8, 8], in AE2's coordinates: y itself, or with
  /// input_normalization "standardize" the standardised code coordinates(y)
  Tensor decode(const Tensor& z);
  /// y in AE2's coordinates (what decode reconstructs): y, or (y - shift) * scale.
  Tensor coordinates(const Tensor& y);
  /// With input_normalization "standardize": copies a fitted map into the input map, as
  /// Ldr::set_input_map.
  void set_input_map(const CodeStandardization& fitted);
  /// The input map (null without one).
  const CodeStandardization* input_map() const { return input_.get(); }
  /// The parameters an optimiser trains: every parameter but the input map's.
  std::vector<std::pair<std::string, Tensor>> trained_parameters() const;

 protected:
  Tensor forward(const Tensor& y) override { return decode(encode(y)); }

 private:
  Tensor activate(const Tensor& x) const;
  Ae2Spec spec_;
  std::shared_ptr<CodeStandardization> input_;  // with "standardize"
  std::shared_ptr<nn::Sequential> encoder_, decoder_;
  std::vector<std::shared_ptr<nn::Dense>> mlp_encoder_, mlp_decoder_;
  std::shared_ptr<nn::Dense> to_latent_, from_latent_;
};

}  // namespace ropes::crl
