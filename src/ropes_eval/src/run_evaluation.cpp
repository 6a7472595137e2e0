#include "ropes_eval/run_evaluation.hpp"

#include <ropes_core/dataset.hpp>
#include <ropes_core/file_io.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_core/npy.hpp>
#include <ropes_core/package_share.hpp>
#include <ropes_crl/dataset_version.hpp>
#include <ropes_crl/estimator.hpp>
#include <ropes_crl/run_directory.hpp>
#include <ropes_nn/build_info.hpp>
#include <ropes_nn/ops.hpp>
#include <ropes_nn/parallel.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "json_file.hpp"
#include "ropes_eval/calibration.hpp"
#include "ropes_eval/correlation.hpp"
#include "ropes_eval/occlusion.hpp"
#include "ropes_eval/pca.hpp"
#include "ropes_eval/probes.hpp"
#include "ropes_eval/supervised.hpp"
#include "tensor_matrix.hpp"
#include "text_format.hpp"

namespace ropes::eval {

namespace fs = std::filesystem;
using detail::difference;
using detail::fmt;
using detail::join;
using nn::Shape;
using nn::Tensor;

namespace {

// the paper's calibration of joint k from latent k; a constant latent (no fit) predicts the
// calibration mean of the joint
AffineCalibration calibrate(const Eigen::VectorXd& x, const Eigen::VectorXd& y) {
  if (x.minCoeff() == x.maxCoeff())
    return AffineCalibration{0.0, y.mean()};
  return fit_affine(x, y);
}

// per joint on the test rows: |Pearson| of latent k and joint k (the paper's MCC), |Spearman|,
// the best-assignment MCC over the method's latents, and the MSE of the calibrations fitted
// on the calibration rows (joint k from latent k, and from every latent)
MethodScores score_method(const std::string& name, const Eigen::MatrixXd& latents,
                          const Eigen::MatrixXd& angles, const std::vector<Eigen::Index>& cal,
                          const std::vector<Eigen::Index>& test, crl::Calibration* fit = nullptr) {
  MethodScores s;
  s.method = name;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Eigen::MatrixXd lt = latents(test, Eigen::all), at = angles(test, Eigen::all);
  const Eigen::MatrixXd lc = latents(cal, Eigen::all), ac = angles(cal, Eigen::all);
  for (Eigen::Index k = 0; k < angles.cols(); ++k) {
    double r = nan, rho = nan;
    try {
      r = std::fabs(pearson(lt.col(k), at.col(k)));
      rho = std::fabs(spearman(lt.col(k), at.col(k)));
    } catch (const std::invalid_argument&) {
      // a constant latent: no correlation (reported as NaN, "-" in the table)
    }
    const AffineCalibration a = calibrate(lc.col(k), ac.col(k));
    s.mcc.push_back(r);
    s.spearman.push_back(rho);
    s.mse.push_back(calibration_mse(a, lt.col(k), at.col(k)));
    s.mse_all_latents.push_back(calibration_mse(fit_linear(lc, ac.col(k)), lt, at.col(k)));
    if (fit != nullptr) {
      fit->scale.push_back(a.scale);
      fit->offset.push_back(a.offset);
    }
  }
  try {
    const Assignment best = best_assignment_correlation(lt, at);
    s.best_assignment_mcc.assign(best.correlation.data(),
                                 best.correlation.data() + best.correlation.size());
    s.best_assignment.assign(best.latent_of_joint.begin(), best.latent_of_joint.end());
  } catch (const std::invalid_argument&) {
    // a constant latent: the matching is undefined (NaN, "-")
    s.best_assignment_mcc.assign(static_cast<std::size_t>(angles.cols()), nan);
  }
  return s;
}

// the scores of `y` ([n, code]) on the k leading principal components of the codes in
// `codes_npy` (f32 [rows, C, S, S], the trainer's cache, flattened as y is)
Eigen::MatrixXd pca_of_codes(const fs::path& codes_npy, const Eigen::MatrixXd& y, std::int64_t k) {
  const core::NpyArray codes = core::read_npy(codes_npy);
  std::int64_t per = 1;
  for (std::size_t d = 1; d < codes.shape.size(); ++d)
    per *= codes.shape[d];
  if (codes.dtype != core::DType::kF32 || codes.shape.size() < 2 || per != y.cols())
    throw core::FileFormatError(codes_npy.string() + ": expected f32 codes of " +
                                std::to_string(y.cols()) + " values a row, as the run's AE1 makes");
  const std::int64_t rows = codes.shape[0];
  Eigen::MatrixXd train(rows, per);
  for (std::int64_t r = 0; r < rows; ++r)
    for (std::int64_t c = 0; c < per; ++c) {
      float v;
      std::memcpy(&v, codes.data.data() + (r * per + c) * 4, 4);
      train(r, c) = v;
    }
  return fit_pca(train, k).project(y);
}

// mean and standard deviation (n - 1) over the repeats of each per-joint number; a NaN in
// any repeat makes that joint's summary NaN
void summarize(MethodSummary& m) {
  const std::size_t reps = m.repeats.size();
  auto over = [&](std::vector<double> MethodScores::*field, std::vector<double>& mean,
                  std::vector<double>& sd) {
    const std::size_t k = (m.repeats[0].*field).size();
    mean.assign(k, 0.0);
    sd.assign(k, 0.0);
    for (std::size_t j = 0; j < k; ++j) {
      double sum = 0;
      for (const MethodScores& r : m.repeats)
        sum += (r.*field)[j];
      const double mu = sum / static_cast<double>(reps);
      double ss = 0;
      for (const MethodScores& r : m.repeats)
        ss += ((r.*field)[j] - mu) * ((r.*field)[j] - mu);
      mean[j] = mu;
      sd[j] = reps > 1 ? std::sqrt(ss / static_cast<double>(reps - 1)) : 0.0;
    }
  };
  m.mean.method = m.std.method = m.method;
  over(&MethodScores::mcc, m.mean.mcc, m.std.mcc);
  over(&MethodScores::mse, m.mean.mse, m.std.mse);
  over(&MethodScores::spearman, m.mean.spearman, m.std.spearman);
  over(&MethodScores::best_assignment_mcc, m.mean.best_assignment_mcc, m.std.best_assignment_mcc);
  over(&MethodScores::mse_all_latents, m.mean.mse_all_latents, m.std.mse_all_latents);
}

// The steps of evaluate_run, in order.

// the run: its identity, the builds that trained and evaluate it, what it adds to the paper
void describe_run(RunEvaluation& ev, const crl::RunDirectory& run,
                  const crl::ExperimentConfig& config) {
  ev.config_name = config.name;
  // the setting is the name before its first '-': "2c" of "2c-small" and "2c-small-plus"
  ev.setting = config.name.substr(0, config.name.find('-'));
  ev.joints = config.joints;
  ev.train_dataset_id = run.dataset_id();
  ev.provenance = {{"training", run.provenance()},
                   {"evaluation", nn::provenance(nn::num_threads())}};
  if (ev.provenance["training"].is_null())
    ev.provenance_differences.push_back("the run recorded no provenance (trained before it was)");
  else
    ev.provenance_differences =
        nn::provenance_differences(ev.provenance["training"], ev.provenance["evaluation"]);
  if (const crl::OcclusionAugmentation& a = config.ae1_training.occlusion_augmentation;
      a.probability > 0)
    ev.extensions.push_back(
        "ae1.occlusion_augmentation: AE1 trained to reconstruct clean images "
        "from images with white squares (probability " +
        fmt(a.probability, 2) + ", " + std::to_string(a.min_size) + " to " +
        std::to_string(a.max_size) + " px)");
  if (const crl::PairHeads& h = config.ae1_training.pair_heads; h.weight > 0)
    ev.extensions.push_back(
        "ae1.pair_heads: AE1's encoder also trained to order each joint's two interventions "
        "at one anchor (a head per joint, weight " +
        fmt(h.weight, 3) + ", " + std::to_string(h.pairs_per_joint) + " pair(s) a joint a step, " +
        h.head + " heads; regimes and anchors only, no angle)");
  if (const double w = config.ldr_training.pair_loss.weight; w > 0)
    ev.extensions.push_back(
        "ldr.pair_loss: each LDR also trained to order its joint's two interventions at one "
        "anchor (weight " +
        fmt(w, 3) + "; regimes and anchors only, no angle)");
  if (const std::int64_t k = config.ldr.members; k > 1)
    ev.extensions.push_back("ldr.members: each joint's LDR an ensemble of " + std::to_string(k) +
                            " classifiers, each trained on its own loss from its own start, the "
                            "logit and the score difference their means");
  if (const crl::LdrAllRegimes& a = config.ldr_training.all_regimes; a.on)
    ev.extensions.push_back(
        std::string("ldr.all_regimes: one classifier over every regime (each joint's two "
                    "interventions") +
        (a.observational ? " and the observational samples" : "") +
        ") trained by softmax cross-entropy; each joint's LDR the difference of its two "
        "outputs (regimes only, no angle)");
  if (const double d = config.ldr_training.weight_average.decay; d > 0)
    ev.extensions.push_back(
        "ldr.weight_average: each LDR evaluated, early-stopped and saved as the "
        "moving average of its weights over its steps (decay " +
        fmt(d, 4) + "; regimes only, no angle)");
  if (const double w = config.ae2_training.logit_loss.weight; w > 0)
    ev.extensions.push_back(
        "ae2.logit_loss: each joint's AE2 latent also trained to follow its frozen LDR's logit "
        "(weight " +
        fmt(w, 3) + " on 1 - their batch correlation; regimes only, no angle)");
}

// the test set's observational rows, and where each of the run's joints is among its angles
struct TestRows {
  fs::path manifest;
  std::vector<std::int64_t> rows;
  std::vector<std::size_t> joint_column;  // the angles column of the run's joint k
  std::int64_t angle_width = 0;           // angles columns
};

// the test set: not the training set, the run's cameras, image size and joints; sets
// ev.dataset_id
TestRows observational_rows(const core::DatasetReader& reader, const fs::path& data_dir,
                            const crl::ExperimentConfig& config, RunEvaluation& ev) {
  TestRows t;
  t.manifest = data_dir / "manifest.json";
  ev.dataset_id = core::read_json_file(t.manifest).value("dataset", "");
  if (ev.dataset_id == ev.train_dataset_id)
    throw std::invalid_argument(
        data_dir.string() + " is the dataset the run trained on (dataset id " +
        ev.dataset_id.substr(0, 12) + "...); evaluate on one generated with another --seed");
  const std::vector<std::int64_t> shape = reader.column("images").row_shape;
  if (shape != std::vector<std::int64_t>{config.cameras, config.image_size, config.image_size})
    throw std::invalid_argument(t.manifest.string() + ": images of another shape than the run's (" +
                                std::to_string(config.cameras) + " cameras of " +
                                std::to_string(config.image_size) + "x" +
                                std::to_string(config.image_size) + ")");
  const nlohmann::json& names = reader.metadata_at("/joint_names");
  for (const std::string& j : config.joints) {
    std::size_t c = names.size();
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == j)
        c = i;
    if (c == names.size())
      throw std::invalid_argument(t.manifest.string() + ": metadata.joint_names has no '" + j +
                                  "'");
    t.joint_column.push_back(c);
  }
  t.angle_width = reader.column("angles").row_shape[0];
  const nlohmann::json& regimes = reader.metadata_at("/regimes");
  std::int32_t observational = -1;
  for (std::size_t r = 0; r < regimes.size(); ++r)
    if (regimes[r].contains("joint") && regimes[r]["joint"].is_null())
      observational = static_cast<std::int32_t>(r);
  const core::NpyArray regime = reader.read_rows("regime", 0, reader.rows());
  for (std::int64_t r = 0; r < reader.rows(); ++r) {
    std::int32_t g;
    std::memcpy(&g, regime.data.data() + r * 4, 4);
    if (g == observational)
      t.rows.push_back(r);
  }
  return t;
}

// the protocol's sizes and the occlusion, checked before the images are encoded
void check_options(const RunEvaluationOptions& options, const crl::ExperimentConfig& config,
                   const TestRows& test) {
  if (options.occlusion < 0 || options.occlusion > config.image_size)
    throw std::invalid_argument("the occlusion square is " + std::to_string(options.occlusion) +
                                " px; expected 0 (none) to the image's side, " +
                                std::to_string(config.image_size));
  if (options.occlusion == 0 && !options.occluded_cameras.empty())
    throw std::invalid_argument(
        "occluded_cameras names " + std::to_string(options.occluded_cameras.size()) +
        " camera(s) but the occlusion square is 0 px; expected an occlusion to place, or no "
        "occluded_cameras");
  const std::int64_t wanted = options.calibration_samples + options.test_samples;
  if (static_cast<std::int64_t>(test.rows.size()) < wanted)
    throw std::invalid_argument(
        test.manifest.string() + ": " + std::to_string(test.rows.size()) +
        " observational samples; the protocol draws " +
        std::to_string(options.calibration_samples) + " calibration and " +
        std::to_string(options.test_samples) + " disjoint test samples a repeat (" +
        std::to_string(wanted) +
        "): generate more anchors, or ask for fewer (--calibration-samples, --test-samples)");
}

// this evaluation's cache of clean codes and silhouettes: options.cache (one a suite before
// it may have filled, for this run and test set only) or `own`
EvaluationCache& cache_of(const RunEvaluationOptions& options, EvaluationCache& own,
                          const fs::path& run_dir, const fs::path& data_dir) {
  EvaluationCache& cache = options.cache ? *options.cache : own;
  if (!cache.run_dir.empty() && (cache.run_dir != run_dir || cache.data_dir != data_dir))
    throw std::invalid_argument("the evaluation cache holds run " + cache.run_dir.string() +
                                " on " + cache.data_dir.string() + "; this evaluation is run " +
                                run_dir.string() + " on " + data_dir.string() +
                                ": expected one cache per run and test set");
  cache.run_dir = run_dir;
  cache.data_dir = data_dir;
  return cache;
}

// every observational sample through the run, in chunks of 256
struct Encoded {
  Eigen::MatrixXd y;       // AE1's codes, [n, code]
  Eigen::MatrixXd z;       // ROPES' latents, [n, joints]
  Eigen::MatrixXd z0;      // the lambda = 0 AE2's latents (when the run has one)
  Eigen::MatrixXd logit;   // each joint's LDR logit
  Eigen::MatrixXd angles;  // the run's joints' true angles
  // with robot_masks: per sample, the robot pixels its squares hide
  std::vector<std::int64_t> hidden;
};

// encodes the test rows, with the occlusion painted into the cameras `painted` when asked
// for; the clean codes and the silhouettes go into (or come from) `cache`
Encoded encode(crl::Estimator& estimator, const core::DatasetReader& reader, const TestRows& test,
               const crl::ExperimentConfig& config, const RunEvaluationOptions& options,
               const std::vector<std::int64_t>& painted, EvaluationCache& cache) {
  const std::vector<std::int64_t>& rows = test.rows;
  const std::int64_t n = static_cast<std::int64_t>(rows.size()),
                     jn = static_cast<std::int64_t>(config.joints.size());
  const std::int64_t side = config.image_size, per = config.cameras * side * side;
  Encoded e;
  e.z.resize(n, jn);
  e.z0.resize(n, jn);
  e.logit.resize(n, jn);
  e.angles.resize(n, jn);
  const bool cached_codes = cache.clean_codes.rows() == n;
  if (options.occlusion > 0 && !cached_codes)
    cache.clean_codes.resize(0, 0);
  Eigen::MatrixXd& y_clean = cache.clean_codes;
  const core::NpyArray angle_rows = reader.read_rows_at("angles", rows);
  const std::int64_t angle_width = test.angle_width;
  const bool split_by_robot = options.occlusion > 0 && options.robot_masks != nullptr;
  const bool cached_masks = static_cast<std::int64_t>(cache.silhouettes.size()) == n;
  if (split_by_robot && !cached_masks) {
    cache.robot_pixels.assign(static_cast<std::size_t>(n), 0);
    cache.silhouettes.assign(static_cast<std::size_t>(n), {});
  }
  e.hidden.assign(split_by_robot ? static_cast<std::size_t>(n) : 0, 0);
  std::vector<std::uint8_t> masks(split_by_robot && !cached_masks ? static_cast<std::size_t>(per)
                                                                  : 0);
  auto to_input = [&](const std::vector<std::uint8_t>& bytes, std::int64_t m) {
    nn::Buffer x(static_cast<std::size_t>(m * per));
    for (std::size_t i = 0; i < x.size(); ++i)
      x[i] = static_cast<float>(bytes[i]) / 255.0f;
    return Tensor(Shape{m, config.cameras, side, side}, std::move(x));
  };
  for (std::int64_t b = 0; b < n; b += 256) {
    const std::int64_t m = std::min<std::int64_t>(256, n - b);
    const std::vector<std::int64_t> part(rows.begin() + b, rows.begin() + b + m);
    core::NpyArray raw = reader.read_rows_at("images", part);
    if (options.occlusion > 0) {
      if (!cached_codes) {
        const Eigen::MatrixXd clean = to_matrix(estimator.codes(to_input(raw.data, m)));
        if (y_clean.size() == 0)
          y_clean.resize(n, clean.cols());
        y_clean.middleRows(b, m) = clean;
      }
      occlude(raw.data, part, config.cameras, side, side, options.occlusion, options.occlusion_seed,
              options.occluded_cameras);
    }
    for (std::int64_t i = 0; split_by_robot && i < m; ++i) {
      const std::size_t at = static_cast<std::size_t>(b + i);
      std::vector<bool>& silhouette = cache.silhouettes[at];
      if (!cached_masks) {
        std::vector<double> q(static_cast<std::size_t>(angle_width));
        for (std::int64_t c = 0; c < angle_width; ++c) {
          float a;
          std::memcpy(&a, angle_rows.data.data() + ((b + i) * angle_width + c) * 4, 4);
          q[static_cast<std::size_t>(c)] = a;
        }
        options.robot_masks(q, masks.data());
        silhouette.resize(masks.size());
        for (std::size_t p = 0; p < masks.size(); ++p)
          silhouette[p] = masks[p] != 0;
        cache.robot_pixels[at] = std::count(silhouette.begin(), silhouette.end(), true);
      }
      for (std::int64_t c : painted) {
        const OcclusionSquare sq =
            occlusion_square(options.occlusion_seed, part[static_cast<std::size_t>(i)], c, side,
                             side, options.occlusion);
        for (std::int64_t r = sq.y; r < sq.y + sq.size; ++r)
          for (std::int64_t x = sq.x; x < sq.x + sq.size; ++x)
            e.hidden[at] += silhouette[static_cast<std::size_t>((c * side + r) * side + x)];
      }
    }
    const Tensor codes = estimator.codes(to_input(raw.data, m));
    const Eigen::MatrixXd yc = to_matrix(codes);
    if (e.y.size() == 0)
      e.y.resize(n, yc.cols());
    e.y.middleRows(b, m) = yc;
    e.z.middleRows(b, m) = to_matrix(estimator.latents_from_codes(codes));
    e.logit.middleRows(b, m) = to_matrix(estimator.ldr_logits_from_codes(codes));
    if (estimator.has_lambda0())
      e.z0.middleRows(b, m) = to_matrix(estimator.lambda0_latents_from_codes(codes));
  }
  for (std::int64_t i = 0; i < n; ++i)
    for (std::int64_t k = 0; k < jn; ++k) {
      float a;
      std::memcpy(&a,
                  angle_rows.data.data() +
                      (i * angle_width +
                       static_cast<std::int64_t>(test.joint_column[static_cast<std::size_t>(k)])) *
                          4,
                  4);
      e.angles(i, k) = a;
    }
  return e;
}

// a method's estimates of the joints: latents, or (the supervised baselines) angles
using Source = std::pair<std::string, const Eigen::MatrixXd*>;

// every method's scores over the repeats ("ropes" first, then the baselines) into
// ev.methods, and ROPES' repeat-0 calibration into ev.calibration
void score_methods(RunEvaluation& ev, const std::vector<Source>& sources,
                   const Eigen::MatrixXd& angles, const std::vector<ProtocolSplit>& splits,
                   const crl::RunDirectory& run) {
  const Eigen::Index jn = angles.cols();
  const crl::RunIdentity identity = crl::RunIdentity::of(run);  // hashes the config: once
  for (const auto& [name, latents] : sources) {
    MethodSummary m;
    m.method = name;
    for (std::size_t r = 0; r < splits.size(); ++r) {
      crl::Calibration fit;
      fit.joints = ev.joints;
      fit.run = identity;
      m.repeats.push_back(
          score_method(name, *latents, angles, splits[r].calibration, splits[r].test, &fit));
      if (name.rfind("supervised_", 0) == 0)  // an angle estimate: its own error
        for (Eigen::Index k = 0; k < jn; ++k)
          m.repeats.back().mse[static_cast<std::size_t>(k)] =
              ((*latents)(splits[r].test, k) - angles(splits[r].test, k)).array().square().mean();
      if (name == "ropes" && r == 0)
        ev.calibration = fit;
    }
    summarize(m);
    ev.methods.push_back(std::move(m));
  }
}

// the occlusion diagnostic: per method, the MCC on the test samples whose squares hide robot
// pixels and on the rest
OcclusionSplit split_by_robot_pixels(const std::vector<Source>& sources,
                                     const Eigen::MatrixXd& angles,
                                     const std::vector<ProtocolSplit>& splits,
                                     const std::vector<std::int64_t>& hidden,
                                     const std::vector<std::int64_t>& robot_pixels) {
  const Eigen::Index jn = angles.cols();
  const auto n = static_cast<double>(hidden.size());
  OcclusionSplit sp;
  double hiding = 0, share = 0;
  for (std::size_t i = 0; i < hidden.size(); ++i) {
    hiding += hidden[i] > 0;
    share += robot_pixels[i] > 0
                 ? static_cast<double>(hidden[i]) / static_cast<double>(robot_pixels[i])
                 : 0;
  }
  sp.share_hiding = hiding / n;
  sp.robot_hidden = share / n;
  for (const auto& [name, latents] : sources) {
    sp.methods.push_back(name);
    for (const bool group : {true, false}) {
      std::vector<double> sum(static_cast<std::size_t>(jn), 0.0), count(sum.size(), 0.0);
      for (const ProtocolSplit& split : splits) {
        std::vector<Eigen::Index> members;
        for (Eigen::Index i : split.test)
          if ((hidden[static_cast<std::size_t>(i)] > 0) == group)
            members.push_back(i);
        if (members.size() < 3)
          continue;
        for (Eigen::Index k = 0; k < jn; ++k) {
          try {
            sum[static_cast<std::size_t>(k)] +=
                std::fabs(pearson((*latents)(members, k).eval(), angles(members, k).eval()));
            count[static_cast<std::size_t>(k)] += 1;
          } catch (const std::invalid_argument&) {
            // a constant latent in this group: left out of the mean
          }
        }
      }
      std::vector<double> mean(sum.size());
      for (std::size_t k = 0; k < sum.size(); ++k)
        mean[k] = count[k] > 0 ? sum[k] / count[k] : std::numeric_limits<double>::quiet_NaN();
      (group ? sp.mcc_hiding : sp.mcc_missing).push_back(std::move(mean));
    }
  }
  return sp;
}

// the repeat the scatter plots show, as the paper's do (ROPES' highest mean MCC), and its
// test samples' latent, calibrated estimate and truth per joint
void scatter_of_best_repeat(RunEvaluation& ev, const Eigen::MatrixXd& z,
                            const Eigen::MatrixXd& angles,
                            const std::vector<ProtocolSplit>& splits) {
  double best = -1;
  for (std::size_t r = 0; r < splits.size(); ++r) {
    const std::vector<double>& mcc = ev.methods[0].repeats[r].mcc;
    double sum = 0;
    for (double v : mcc)
      sum += std::isfinite(v) ? v : 0.0;
    if (sum > best) {
      best = sum;
      ev.best_repeat = static_cast<std::int64_t>(r);
    }
  }
  const ProtocolSplit& b = splits[static_cast<std::size_t>(ev.best_repeat)];
  for (Eigen::Index k = 0; k < angles.cols(); ++k) {
    const AffineCalibration a = calibrate(z(b.calibration, k), angles(b.calibration, k));
    std::vector<double> latent, estimate, truth;
    for (Eigen::Index i : b.test) {
      latent.push_back(z(i, k));
      estimate.push_back(a.scale * z(i, k) + a.offset);
      truth.push_back(angles(i, k));
    }
    ev.scatter_latent.push_back(std::move(latent));
    ev.scatter_estimate.push_back(std::move(estimate));
    ev.scatter_truth.push_back(std::move(truth));
  }
}

// the diagnostics, on repeat 0's samples (the MLP probe trains for seconds a repeat): the
// probes from AE1's code, each joint's variance, the LDRs against Bayes
void diagnostics(RunEvaluation& ev, const Eigen::MatrixXd& y, const Eigen::MatrixXd& angles,
                 const ProtocolSplit& split, const RunEvaluationOptions& options,
                 const crl::RunDirectory& run) {
  const std::vector<Eigen::Index>& cal = split.calibration;
  const std::vector<Eigen::Index>& test = split.test;
  ev.probe_linear_mse = detail::linear_probe(y, angles, cal, test);
  if (options.probe_steps > 0)
    ev.probe_mlp_mse = detail::mlp_probe(y, angles, cal, test, options.probe_steps, options.seed);
  for (Eigen::Index k = 0; k < angles.cols(); ++k) {
    const Eigen::VectorXd a = angles(test, Eigen::all).col(k);
    ev.angle_variance.push_back((a.array() - a.mean()).square().mean());
    const std::optional<crl::LdrRecord> l = run.ldr(ev.joints[static_cast<std::size_t>(k)]);
    ev.ldr_accuracy.push_back(l ? l->held_out_accuracy : NAN);
    ev.bayes_accuracy.push_back(l ? l->bayes_accuracy : NAN);
  }
}

// the paper's numbers for this setting (NaN where it gives none)
void paper_numbers(RunEvaluation& ev, const RunEvaluationOptions& options) {
  const nlohmann::json paper = core::read_json_file(
      options.paper_results.empty() ? installed_paper_results() : options.paper_results);
  for (const std::string& j : ev.joints) {
    const nlohmann::json* p = nullptr;
    if (paper["settings"].contains(ev.setting) && paper["settings"][ev.setting].contains(j))
      p = &paper["settings"][ev.setting][j];
    ev.paper_mcc.push_back(p ? (*p)["mcc"].get<double>() : NAN);
    ev.paper_mse.push_back(p ? (*p)["mse"].get<double>() : NAN);
  }
}

}  // namespace

void check_protocol(const RunEvaluationOptions& options) {
  const auto require = [](const char* field, std::int64_t value, const ProtocolRange& range) {
    if (!range.holds(value))
      throw std::invalid_argument(std::string(field) + " is " + std::to_string(value) +
                                  "; expected " + range.text());
  };
  require("repeats", options.repeats, kRepeatsRange);
  require("calibration_samples", options.calibration_samples, kSamplesRange);
  require("test_samples", options.test_samples, kSamplesRange);
  require("probe_steps", options.probe_steps, kProbeStepsRange);
}

EvaluationFiles evaluation_files(const fs::path& results) {
  if (results.filename() == "calibration.json") {
    throw std::invalid_argument(results.string() +
                                ": the calibration is written beside the results as "
                                "calibration.json; name the results file otherwise");
  }
  EvaluationFiles f;
  f.results = results;
  f.markdown = results;
  f.markdown.replace_extension(".md");
  if (f.markdown == results)  // results named something.md: keep both
    f.markdown += ".md";
  f.calibration = results.parent_path() / "calibration.json";
  return f;
}

EvaluationFiles write_evaluation(const RunEvaluation& ev, const fs::path& results) {
  const EvaluationFiles f = evaluation_files(results);
  if (results.has_parent_path())
    fs::create_directories(results.parent_path());
  const auto write_text = [](const fs::path& path, const std::string& text) {
    core::write_text_file_atomically(path, text);
  };
  write_text(f.results, ev.to_json().dump(2) + "\n");
  write_text(f.markdown, ev.markdown());
  ev.calibration.write(f.calibration);
  return f;
}

RunEvaluation evaluate_run(const fs::path& run_dir, const fs::path& data_dir,
                           const RunEvaluationOptions& options) {
  check_protocol(options);  // before a file is read
  RunEvaluation ev;
  ev.run_dir = run_dir.string();
  ev.data_dir = data_dir.string();
  const crl::RunDirectory run = crl::RunDirectory::open(run_dir);
  crl::Estimator estimator = crl::Estimator::load(run);
  crl::require_run_of_current_sim_dataset(run);  // nor a run trained on it
  const crl::ExperimentConfig& config = estimator.config();
  describe_run(ev, run, config);

  const core::DatasetReader reader = core::DatasetReader::open(data_dir);
  crl::require_current_sim_dataset(reader);  // never the old reading of TN(mean, x)
  reader.verify();  // a shard damaged after generation is refused, never evaluated on
  const TestRows test = observational_rows(reader, data_dir, config, ev);
  check_options(options, config, test);
  const std::vector<std::int64_t> painted =
      occluded_cameras(config.cameras, options.occluded_cameras);  // checked before encoding
  EvaluationCache own;
  EvaluationCache& cache = cache_of(options, own, run_dir, data_dir);
  const Encoded e = encode(estimator, reader, test, config, options, painted, cache);
  const std::int64_t n = static_cast<std::int64_t>(test.rows.size()),
                     jn = static_cast<std::int64_t>(config.joints.size());

  // the protocol: repeats of a calibration set and a disjoint test set, drawn by seed
  const std::vector<ProtocolSplit> splits = protocol_splits(
      n, options.repeats, options.calibration_samples, options.test_samples, options.seed);
  ev.calibration_samples = options.calibration_samples;
  ev.test_samples = options.test_samples;
  ev.observational_samples = n;
  ev.seed = options.seed;
  ev.occlusion = options.occlusion;
  ev.occlusion_seed = options.occlusion_seed;
  if (options.occlusion > 0) {
    ev.occluded_cameras = options.occluded_cameras;
    const Eigen::MatrixXd& y_clean = cache.clean_codes;
    const Eigen::RowVectorXd mean = y_clean.colwise().mean();
    const double spread = (y_clean.rowwise() - mean).squaredNorm();
    ev.code_shift = spread > 0 ? (e.y - y_clean).squaredNorm() / spread
                               : std::numeric_limits<double>::quiet_NaN();
  }
  // the methods: ROPES, the lambda = 0 AE2, the LDR logit, the PCA of AE1's code (fitted
  // label-free on the codes of the run's own training set, RUN/codes.npy, component k
  // against joint k) and the supervised baselines (angle estimates straight from Y)
  const Eigen::MatrixXd pca = pca_of_codes(run.codes_file(), e.y, jn);
  std::vector<Source> sources = {{"ropes", &e.z}};
  if (estimator.has_lambda0())
    sources.push_back({"lambda0_autoencoder", &e.z0});
  sources.push_back({"ldr_logit", &e.logit});
  sources.push_back({"pca_of_code", &pca});
  std::vector<std::pair<std::string, Eigen::MatrixXd>> supervised;
  for (const SupervisedEncoder* s : options.supervised) {
    if (s == nullptr || s->joints() != config.joints)
      throw std::invalid_argument(
          "evaluate_run: a supervised baseline " +
          std::string(s == nullptr ? "is null" : "estimates other joints than the run's") +
          "; train it on this run (SupervisedEncoder::train)");
    const std::string name = supervised_method_name(s->fraction());
    supervised.emplace_back(name, s->predict(e.y));
  }
  for (const auto& [name, estimate] : supervised)
    sources.push_back({name, &estimate});

  score_methods(ev, sources, e.angles, splits, run);
  if (options.occlusion > 0 && options.robot_masks != nullptr)
    ev.occlusion_split =
        split_by_robot_pixels(sources, e.angles, splits, e.hidden, cache.robot_pixels);
  scatter_of_best_repeat(ev, e.z, e.angles, splits);
  diagnostics(ev, e.y, e.angles, splits[0], options, run);
  paper_numbers(ev, options);
  return ev;
}

std::vector<ProtocolSplit> protocol_splits(std::int64_t n, std::int64_t repeats,
                                           std::int64_t calibration, std::int64_t test,
                                           std::uint64_t seed) {
  if (repeats < 1 || calibration < 2 || test < 2 || calibration > n - test)
    throw std::invalid_argument(
        "protocol_splits: " + std::to_string(repeats) + " repeats of " +
        std::to_string(calibration) + " calibration and " + std::to_string(test) +
        " test samples from " + std::to_string(n) +
        " observational samples; expected at least 1 repeat, at least 2 samples in each set "
        "and calibration + test <= the samples there are");
  std::vector<ProtocolSplit> splits(static_cast<std::size_t>(repeats));
  for (std::int64_t r = 0; r < repeats; ++r) {
    const std::vector<std::int64_t> order =
        core::shuffled_indices(n, seed, static_cast<std::uint64_t>(r));
    ProtocolSplit& s = splits[static_cast<std::size_t>(r)];
    for (std::int64_t i = 0; i < calibration + test; ++i)
      (i < calibration ? s.calibration : s.test)
          .push_back(static_cast<Eigen::Index>(order[static_cast<std::size_t>(i)]));
    // disjoint: every index at most once across the two sets
    std::vector<char> seen(static_cast<std::size_t>(n), 0);
    for (const std::vector<Eigen::Index>* set : {&s.calibration, &s.test})
      for (Eigen::Index i : *set) {
        ROPES_DEMAND(i >= 0 && i < n && !seen[static_cast<std::size_t>(i)],
                     "protocol_splits: sample " + std::to_string(i) + " drawn twice in repeat " +
                         std::to_string(r));
        seen[static_cast<std::size_t>(i)] = 1;
      }
  }
  return splits;
}

fs::path installed_paper_results() {
  return core::find_package_share("ropes_eval", "paper_results.json", ROPES_EVAL_SHARE_DIR) /
         "paper_results.json";
}

}  // namespace ropes::eval
