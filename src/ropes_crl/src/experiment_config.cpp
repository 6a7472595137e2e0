#include "ropes_crl/experiment_config.hpp"

#include <fstream>
#include <sstream>
#include <stdexcept>

#include "json_fields.hpp"
#include "ropes_core/file_format_error.hpp"
#include "ropes_core/file_io.hpp"
#include "ropes_core/json_text.hpp"
#include "ropes_core/package_share.hpp"
#include "ropes_core/plain_name.hpp"

namespace ropes::crl {

namespace fs = std::filesystem;
using namespace detail;

namespace {

OptimizerConfig parse_optimizer(const nlohmann::json& j, const std::string& where) {
  reject_unknown_keys(j, where, {"lr", "schedule", "final_lr", "warmup", "clip_norm"});
  OptimizerConfig o;
  o.lr = get_double(j, where, "lr");
  o.schedule = get_string(j, where, "schedule");
  o.final_lr = get_double(j, where, "final_lr");
  o.warmup = get_int(j, where, "warmup");
  o.clip_norm = get_double(j, where, "clip_norm");
  if (!(o.lr > 0) || o.final_lr < 0 || o.warmup < 0 || o.clip_norm < 0)
    throw std::invalid_argument(
        where +
        ": expected lr > 0, final_lr >= 0, warmup >= 0 and "
        "clip_norm >= 0, got lr " +
        core::describe(j["lr"]) + ", final_lr " + core::describe(j["final_lr"]) + ", warmup " +
        core::describe(j["warmup"]) + ", clip_norm " + core::describe(j["clip_norm"]));
  if (o.schedule != "constant" && o.schedule != "cosine")
    throw std::invalid_argument(where + ".schedule: expected \"constant\" or \"cosine\", got \"" +
                                o.schedule + "\"");
  return o;
}

void require_positive(std::int64_t v, const std::string& name) {
  if (v < 1)
    throw std::invalid_argument(name + ": expected >= 1, got " + std::to_string(v));
}

std::string number_text(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// An optional option object (an extension's settings): parent[key] must be an object (`shape`
// names its fields in the error) with no key outside `keys`. Returns the object.
const nlohmann::json& optional_object(const nlohmann::json& parent, const std::string& parent_at,
                                      const std::string& key, const std::string& shape,
                                      const std::vector<std::string>& keys) {
  const std::string at = parent_at + "." + key;
  const nlohmann::json& o = field(parent, parent_at, key);
  if (!o.is_object())
    throw std::invalid_argument(at + ": expected an object " + shape + ", got a " +
                                std::string(o.type_name()));
  reject_unknown_keys(o, at, keys);
  return o;
}

// An optional weighted term of a loss (ae1.difference_loss, ae1.pair_heads, ldr.pair_loss,
// ae2.logit_loss): an optional_object with a weight in (0, 1e6]. Returns the object; its weight
// goes to `weight`.
const nlohmann::json& weighted_term(const nlohmann::json& parent, const std::string& parent_at,
                                    const std::string& key, const std::string& shape,
                                    const std::vector<std::string>& keys, double& weight) {
  const std::string at = parent_at + "." + key;
  const nlohmann::json& o = optional_object(parent, parent_at, key, shape, keys);
  weight = get_double(o, at, "weight");
  if (!(weight > 0 && weight <= 1e6))
    throw std::invalid_argument(at + ".weight: expected in (0, 1e6], got " + number_text(weight));
  return o;
}

}  // namespace

nn::LrSchedule OptimizerConfig::make_schedule(std::int64_t steps) const {
  if (schedule == "cosine")
    return nn::LrSchedule::cosine(lr, std::max<std::int64_t>(steps, 1), final_lr, warmup);
  return nn::LrSchedule::constant(lr);
}

nlohmann::json ExperimentConfig::to_json() const {
  return raw;
}

ExperimentConfig ExperimentConfig::from_json(const nlohmann::json& j, const std::string& where) {
  try {
    reject_unknown_keys(j, "config",
                        {"name", "preset", "source", "deviations", "dataset", "ae1", "ldr", "ae2",
                         "log_every", "checkpoint_every"});
    ExperimentConfig c;
    c.raw = j;
    c.name = get_string(j, "config", "name");
    // ropes-run's default output is runs/<name>: a name is never a path
    if (!core::is_plain_name(c.name)) {
      throw std::invalid_argument(
          "config.name: expected a plain name (letters, digits, '_', "
          "'-', '.', not starting with '.'; at most 128 characters), "
          "got \"" +
          c.name.substr(0, 64) + "\"");
    }
    c.preset = get_string(j, "config", "preset");
    if (c.preset != "tiny" && c.preset != "small" && c.preset != "paper")
      throw std::invalid_argument(
          "config.preset: expected \"tiny\", \"small\" or \"paper\", got \"" + c.preset + "\"");
    c.source = get_string(j, "config", "source");
    c.deviations = get_strings(j, "config", "deviations");
    c.log_every = get_int(j, "config", "log_every");
    c.checkpoint_every = get_int(j, "config", "checkpoint_every");
    require_positive(c.log_every, "config.log_every");
    require_positive(c.checkpoint_every, "config.checkpoint_every");

    // the dataset
    const nlohmann::json& d = field(j, "config", "dataset");
    reject_unknown_keys(d, "config.dataset", {"config", "cameras", "image_size", "joints"});
    c.dataset_config = get_string(d, "config.dataset", "config");
    c.cameras = get_int(d, "config.dataset", "cameras");
    c.image_size = get_int(d, "config.dataset", "image_size");
    c.joints = get_strings(d, "config.dataset", "joints");
    require_positive(c.cameras, "config.dataset.cameras");
    if (c.joints.empty())
      throw std::invalid_argument("config.dataset.joints: expected at least one joint, got []");

    // AE1
    const nlohmann::json& a1 = field(j, "config", "ae1");
    reject_unknown_keys(
        a1, "config.ae1",
        {"stem", "stem_factor", "stem_channels", "widths", "blocks_per_stage", "code_channels",
         "code_head", "batch_size", "steps", "epochs", "micro_batch", "optimizer",
         "occlusion_augmentation", "difference_loss", "pair_heads"});
    c.ae1.image_size = c.image_size;
    c.ae1.stem = get_string(a1, "config.ae1", "stem");
    c.ae1.stem_factor = static_cast<int>(get_int(a1, "config.ae1", "stem_factor"));
    c.ae1.stem_channels = get_int(a1, "config.ae1", "stem_channels");
    c.ae1.widths = get_ints(a1, "config.ae1", "widths");
    c.ae1.blocks_per_stage = static_cast<int>(get_int(a1, "config.ae1", "blocks_per_stage"));
    c.ae1.code_channels = get_int(a1, "config.ae1", "code_channels");
    if (a1.contains("code_head"))  // optional: "conv_relu", the paper's, when absent
      c.ae1.code_head = get_string(a1, "config.ae1", "code_head");
    if (const std::string p = c.ae1.problem(); !p.empty())
      throw std::invalid_argument("config." + p);
    c.ae1_training.batch_size = get_int(a1, "config.ae1", "batch_size");
    if (c.ae1_training.batch_size % c.cameras != 0)
      throw std::invalid_argument(
          "config.ae1.batch_size: " + std::to_string(c.ae1_training.batch_size) +
          " is not a multiple of the cameras (" + std::to_string(c.cameras) +
          "): a step takes whole samples");
    c.ae1_training.micro_batch = get_int(a1, "config.ae1", "micro_batch");
    require_positive(c.ae1_training.batch_size, "config.ae1.batch_size");
    require_positive(c.ae1_training.micro_batch, "config.ae1.micro_batch");
    const bool has_steps = a1.contains("steps"), has_epochs = a1.contains("epochs");
    if (has_steps == has_epochs)
      throw std::invalid_argument("config.ae1: expected exactly one of \"steps\" and \"epochs\"");
    if (has_steps) {
      c.ae1_training.steps = get_int(a1, "config.ae1", "steps");
      require_positive(c.ae1_training.steps, "config.ae1.steps");
    } else if (!(get_double(a1, "config.ae1", "epochs") > 0)) {
      throw std::invalid_argument("config.ae1.epochs: expected > 0, got " +
                                  core::describe(a1["epochs"]));
    }
    c.ae1_training.optimizer =
        parse_optimizer(field(a1, "config.ae1", "optimizer"), "config.ae1.optimizer");
    if (a1.contains("occlusion_augmentation")) {  // optional, an extension: off when absent
      const std::string aug = "config.ae1.occlusion_augmentation";
      const nlohmann::json& o = field(a1, "config.ae1", "occlusion_augmentation");
      if (!o.is_object())
        throw std::invalid_argument(aug +
                                    ": expected an object {\"probability\", \"min_size\", "
                                    "\"max_size\"}, got " +
                                    core::describe(o));
      reject_unknown_keys(o, aug, {"probability", "min_size", "max_size"});
      OcclusionAugmentation& a = c.ae1_training.occlusion_augmentation;
      a.probability = get_double(o, aug, "probability");
      a.min_size = get_int(o, aug, "min_size");
      a.max_size = get_int(o, aug, "max_size");
      if (!(a.probability > 0 && a.probability <= 1))
        throw std::invalid_argument(aug + ".probability: expected in (0, 1], got " +
                                    core::describe(o["probability"]));
      if (a.min_size < 1 || a.max_size < a.min_size || a.max_size > c.image_size)
        throw std::invalid_argument(aug + ": min_size " + std::to_string(a.min_size) +
                                    ", max_size " + std::to_string(a.max_size) +
                                    "; expected 1 <= min_size <= max_size <= the image's " +
                                    std::to_string(c.image_size) + " px");
    }

    if (a1.contains("difference_loss")) {  // optional, a variant: off when absent
      const std::string at = "config.ae1.difference_loss";
      double w = 0;
      weighted_term(a1, "config.ae1", "difference_loss", "{\"weight\"}", {"weight"}, w);
      const std::int64_t samples = c.ae1_training.batch_size / c.cameras;
      if (samples % 2 != 0)
        throw std::invalid_argument(
            at + ": config.ae1.batch_size " + std::to_string(c.ae1_training.batch_size) + " is " +
            std::to_string(samples) +
            " samples a step; expected an even number (half of them are the observational "
            "samples of the other half's anchors)");
      c.ae1_training.difference_loss.weight = w;
    }

    if (a1.contains("pair_heads")) {  // optional, an extension: off when absent
      const std::string at = "config.ae1.pair_heads";
      double w = 0;
      const nlohmann::json& o =
          weighted_term(a1, "config.ae1", "pair_heads", "{\"weight\", \"pairs_per_joint\"}",
                        {"weight", "pairs_per_joint", "head"}, w);
      const std::int64_t k = get_int(o, at, "pairs_per_joint");
      if (k < 1 || k > 4096)
        throw std::invalid_argument(at + ".pairs_per_joint: expected in [1, 4096], got " +
                                    std::to_string(k));
      const std::string head = o.contains("head") ? get_string(o, at, "head") : "ldr";
      if (head != "ldr" && head != "linear")
        throw std::invalid_argument(at + ".head: expected \"ldr\" or \"linear\", got \"" + head +
                                    "\"");
      c.ae1_training.pair_heads = {w, k, head};
    }

    // the code Y: [C, 8, 8]
    const std::int64_t side = c.ae1.code_size();

    // LDR
    const nlohmann::json& l = field(j, "config", "ldr");
    reject_unknown_keys(l, "config.ldr",
                        {"widths", "hidden", "batch_size", "max_epochs", "patience",
                         "held_out_fraction", "optimizer", "input_normalization", "pair_loss",
                         "members", "weight_average", "all_regimes"});
    c.ldr.in_channels = c.code_channels();
    c.ldr.input_size = side;
    c.ldr.widths = get_ints(l, "config.ldr", "widths");
    c.ldr.hidden = get_int(l, "config.ldr", "hidden");
    if (l.contains("input_normalization"))  // optional: "none", the paper's, when absent
      c.ldr.input_normalization = get_string(l, "config.ldr", "input_normalization");
    if (l.contains("members"))  // optional, an extension: one classifier (the paper's) when absent
      c.ldr.members = get_int(l, "config.ldr", "members");
    if (const std::string p = c.ldr.problem(); !p.empty())
      throw std::invalid_argument("config." + p);
    c.ldr_training.batch_size = get_int(l, "config.ldr", "batch_size");
    c.ldr_training.max_epochs = get_int(l, "config.ldr", "max_epochs");
    c.ldr_training.patience = get_int(l, "config.ldr", "patience");
    c.ldr_training.held_out_fraction = get_double(l, "config.ldr", "held_out_fraction");
    require_positive(c.ldr_training.batch_size, "config.ldr.batch_size");
    require_positive(c.ldr_training.max_epochs, "config.ldr.max_epochs");
    require_positive(c.ldr_training.patience, "config.ldr.patience");
    if (!(c.ldr_training.held_out_fraction > 0 && c.ldr_training.held_out_fraction < 1))
      throw std::invalid_argument("config.ldr.held_out_fraction: expected in (0, 1), got " +
                                  core::describe(l["held_out_fraction"]));
    c.ldr_training.optimizer =
        parse_optimizer(field(l, "config.ldr", "optimizer"), "config.ldr.optimizer");
    if (l.contains("pair_loss")) {  // optional, an extension: off when absent
      double w = 0;
      weighted_term(l, "config.ldr", "pair_loss", "{\"weight\"}", {"weight"}, w);
      c.ldr_training.pair_loss.weight = w;
    }
    if (l.contains("weight_average")) {  // optional, an extension: off when absent
      const std::string at = "config.ldr.weight_average";
      const nlohmann::json& o =
          optional_object(l, "config.ldr", "weight_average", "{\"decay\"}", {"decay"});
      const double decay = get_double(o, at, "decay");
      if (!(decay > 0 && decay < 1))
        throw std::invalid_argument(at + ".decay: expected in (0, 1), got " + number_text(decay));
      c.ldr_training.weight_average.decay = decay;
    }
    if (l.contains("all_regimes")) {  // optional, an extension: off when absent
      const std::string at = "config.ldr.all_regimes";
      const nlohmann::json& o =
          optional_object(l, "config.ldr", "all_regimes", "{\"observational\"}", {"observational"});
      c.ldr_training.all_regimes.on = true;
      if (o.contains("observational"))
        c.ldr_training.all_regimes.observational = get_bool(o, at, "observational");
      if (c.ldr.members > 1)
        throw std::invalid_argument(at +
                                    ": one classifier over every regime, not with "
                                    "config.ldr.members " +
                                    std::to_string(c.ldr.members) + " (expected 1 or absent)");
    }

    // AE2
    const nlohmann::json& a2 = field(j, "config", "ae2");
    reject_unknown_keys(a2, "config.ae2",
                        {"kind",
                         "latent_dim",
                         "widths",
                         "decoder_widths",
                         "blocks_per_stage",
                         "activation",
                         "mode",
                         "lambda",
                         "sparsity_norm",
                         "sparsity_diagonal",
                         "score_normalization",
                         "score_samples",
                         "batch_size",
                         "sparsity_batch_size",
                         "steps",
                         "micro_batch",
                         "optimizer",
                         "lambda0_baseline",
                         "input_normalization",
                         "logit_loss"});
    c.ae2.kind = get_string(a2, "config.ae2", "kind");
    c.ae2.in_channels = c.code_channels();
    c.ae2.input_size = side;
    c.ae2.latent_dim = get_int(a2, "config.ae2", "latent_dim");
    c.ae2.widths = get_ints(a2, "config.ae2", "widths");
    c.ae2.decoder_widths = get_ints(a2, "config.ae2", "decoder_widths");
    c.ae2.blocks_per_stage = static_cast<int>(get_int(a2, "config.ae2", "blocks_per_stage"));
    c.ae2.activation = get_string(a2, "config.ae2", "activation");
    if (a2.contains("input_normalization"))  // optional: "none", the paper's, when absent
      c.ae2.input_normalization = get_string(a2, "config.ae2", "input_normalization");
    if (const std::string p = c.ae2.problem(); !p.empty())
      throw std::invalid_argument("config." + p);
    Ae2Training& t = c.ae2_training;
    t.mode = get_string(a2, "config.ae2", "mode");
    if (t.mode != "per_joint" && t.mode != "joint")
      throw std::invalid_argument("config.ae2.mode: expected \"per_joint\" or \"joint\", got \"" +
                                  t.mode + "\"");
    t.lambda = get_double(a2, "config.ae2", "lambda");
    if (!(t.lambda >= 0))
      throw std::invalid_argument("config.ae2.lambda: expected >= 0, got " +
                                  core::describe(a2["lambda"]));
    t.norm = parse_sparsity_norm(get_string(a2, "config.ae2", "sparsity_norm"));
    if (a2.contains("sparsity_diagonal"))
      t.diagonal = parse_sparsity_diagonal(get_string(a2, "config.ae2", "sparsity_diagonal"));
    t.score_normalization = get_string(a2, "config.ae2", "score_normalization");
    if (t.score_normalization != "none" && t.score_normalization != "unit" &&
        t.score_normalization != "mean_unit")
      throw std::invalid_argument(
          "config.ae2.score_normalization: expected \"none\", \"unit\" or \"mean_unit\", "
          "got \"" +
          t.score_normalization + "\"");
    t.score_samples = get_string(a2, "config.ae2", "score_samples");
    if (t.score_samples != "intervened" && t.score_samples != "all")
      throw std::invalid_argument(
          "config.ae2.score_samples: expected \"intervened\" or \"all\", got \"" + t.score_samples +
          "\"");
    t.batch_size = get_int(a2, "config.ae2", "batch_size");
    t.sparsity_batch_size = get_int(a2, "config.ae2", "sparsity_batch_size");
    t.steps = get_int(a2, "config.ae2", "steps");
    t.micro_batch = get_int(a2, "config.ae2", "micro_batch");
    require_positive(t.batch_size, "config.ae2.batch_size");
    require_positive(t.sparsity_batch_size, "config.ae2.sparsity_batch_size");
    require_positive(t.steps, "config.ae2.steps");
    require_positive(t.micro_batch, "config.ae2.micro_batch");
    t.optimizer = parse_optimizer(field(a2, "config.ae2", "optimizer"), "config.ae2.optimizer");
    t.lambda0_baseline = get_bool(a2, "config.ae2", "lambda0_baseline");
    if (a2.contains("logit_loss")) {  // optional, an extension: off when absent
      double w = 0;
      weighted_term(a2, "config.ae2", "logit_loss", "{\"weight\"}", {"weight"}, w);
      t.logit_loss.weight = w;
    }
    if (c.ae2.latent_dim < static_cast<std::int64_t>(c.joints.size()))
      throw std::invalid_argument("config.ae2.latent_dim: " + std::to_string(c.ae2.latent_dim) +
                                  " is smaller than the number of intervened joints (" +
                                  std::to_string(c.joints.size()) +
                                  "); latent i estimates joint i");
    return c;
  } catch (const std::invalid_argument& e) {  // a field's check: named with its source
    throw core::ConfigError(where + ": " + e.what());
  }
}

void ExperimentConfig::resolve_epochs(std::int64_t dataset_images) {
  if (!raw["ae1"].contains("epochs"))
    return;
  const double epochs = raw["ae1"]["epochs"].get<double>();
  ae1_training.steps = std::max<std::int64_t>(
      1, static_cast<std::int64_t>(epochs * static_cast<double>(dataset_images) /
                                       static_cast<double>(ae1_training.batch_size) +
                                   0.999999));
}

fs::path installed_config_dir() {
  return core::find_package_share("ropes_crl", "configs", ROPES_CRL_SHARE_DIR) / "configs";
}

ExperimentConfig load_experiment_config(const std::string& name_or_path) {
  fs::path path = name_or_path;
  if (!core::is_regular_file(path)) {
    const fs::path installed = installed_config_dir() / (name_or_path + ".json");
    if (!core::is_regular_file(installed)) {
      std::string names;
      std::error_code ec;
      for (const auto& e : fs::directory_iterator(installed_config_dir(), ec))
        if (e.path().extension() == ".json")
          names += (names.empty() ? "" : ", ") + e.path().stem().string();
      throw core::ConfigError("experiment config '" + name_or_path +
                              "' is neither a file nor an installed config (installed in " +
                              installed_config_dir().string() + ": " + names + ")");
    }
    path = installed;
  }
  // a huge file is refused by its size; a number too large for any type (found by
  // fuzz/experiment_config) is "not JSON"
  return ExperimentConfig::from_json(core::read_json_file(path), path.string());
}

}  // namespace ropes::crl
