#include "ropes_eval/run_evaluation.hpp"

#include <ropes_core/dataset.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_core/npy.hpp>
#include <ropes_core/package_share.hpp>
#include <ropes_crl/dataset_version.hpp>
#include <ropes_crl/estimator.hpp>
#include <ropes_crl/run_directory.hpp>
#include <ropes_nn/adam.hpp>
#include <ropes_nn/build_info.hpp>
#include <ropes_nn/demand.hpp>
#include <ropes_nn/layers.hpp>
#include <ropes_nn/ops.hpp>
#include <ropes_nn/parallel.hpp>
#include <ropes_nn/train_step.hpp>

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
#include "ropes_eval/supervised.hpp"
#include "text_format.hpp"

namespace ropes::eval {

namespace fs = std::filesystem;
using detail::difference;
using detail::fmt;
using detail::join;
using nn::Shape;
using nn::Tensor;

namespace {

Eigen::MatrixXd to_matrix(const Tensor& t) {
  const std::int64_t n = t.shape()[0], k = t.numel() / std::max<std::int64_t>(n, 1);
  Eigen::MatrixXd m(n, k);
  for (std::int64_t i = 0; i < n; ++i)
    for (std::int64_t j = 0; j < k; ++j)
      m(i, j) = t.data()[i * k + j];
  return m;
}

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

// 1 / sd of each column, and 0 for a column that barely varies on the calibration samples
// (sd <= 1e-3 of the largest): dividing one by its tiny sd would turn the differences the
// test samples show there into huge values, and it carries no information the fit can use
Eigen::RowVectorXd inverse_spread(const Eigen::RowVectorXd& sd) {
  const double largest = sd.size() > 0 ? sd.maxCoeff() : 0.0;
  return (sd.array() > 1e-3 * largest).select(sd.array().inverse(), 0.0);
}

}  // namespace

std::vector<double> detail::mlp_probe(const Eigen::MatrixXd& y, const Eigen::MatrixXd& angles,
                                      const std::vector<Eigen::Index>& cal,
                                      const std::vector<Eigen::Index>& test, std::int64_t steps,
                                      std::uint64_t seed) {
  const std::int64_t in = y.cols(), j = angles.cols();
  nn::Sequential net;
  net.add(std::make_shared<nn::Dense>(in, 128));
  net.add(std::make_shared<nn::ReLU>());
  net.add(std::make_shared<nn::Dense>(128, 128));
  net.add(std::make_shared<nn::ReLU>());
  net.add(std::make_shared<nn::Dense>(128, j));
  net.initialize(seed);
  const Eigen::RowVectorXd ymu = y(cal, Eigen::all).colwise().mean();
  const Eigen::RowVectorXd yinv = inverse_spread(
      ((y(cal, Eigen::all).rowwise() - ymu).array().square().colwise().mean()).sqrt());
  const Eigen::RowVectorXd amu = angles(cal, Eigen::all).colwise().mean();
  const Eigen::RowVectorXd asd =
      ((angles(cal, Eigen::all).rowwise() - amu).array().square().colwise().mean()).sqrt();
  auto tensor_of = [](const Eigen::MatrixXd& m) {
    std::vector<float> v(static_cast<std::size_t>(m.size()));
    for (Eigen::Index r = 0; r < m.rows(); ++r)
      for (Eigen::Index c = 0; c < m.cols(); ++c)
        v[static_cast<std::size_t>(r * m.cols() + c)] = static_cast<float>(m(r, c));
    return Tensor(Shape{m.rows(), m.cols()}, v);
  };
  const Eigen::MatrixXd xs = (y.rowwise() - ymu).array().rowwise() * yinv.array();
  const Eigen::MatrixXd ts = (angles.rowwise() - amu).array().rowwise() / asd.array();
  nn::Adam adam(net.named_parameters(), nn::AdamOptions{1e-3});
  const std::int64_t n = static_cast<std::int64_t>(cal.size());
  for (std::int64_t s = 0; s < steps; ++s) {
    const std::vector<std::int64_t> order =
        core::shuffled_indices(n, seed, static_cast<std::uint64_t>(s * 64 / n));
    std::vector<Eigen::Index> rows;
    for (std::int64_t k = s * 64; k < (s + 1) * 64; ++k)
      rows.push_back(cal[static_cast<std::size_t>(order[static_cast<std::size_t>(k % n)])]);
    const Tensor x = tensor_of(xs(rows, Eigen::all)), t = tensor_of(ts(rows, Eigen::all));
    nn::train_step(adam, nn::mean_loss([&](std::size_t) {
                     return nn::mean(nn::square(nn::sub(net(x), t)), {1});
                   }));
  }
  nn::GradModeGuard no_grad(false);
  const Eigen::MatrixXd pred = to_matrix(net(tensor_of(xs(test, Eigen::all))));
  std::vector<double> out;
  for (Eigen::Index k = 0; k < j; ++k)
    out.push_back(
        ((pred.col(k).array() * asd(k) + amu(k)) - angles(test, Eigen::all).col(k).array())
            .square()
            .mean());
  return out;
}

std::vector<ProtocolSplit> protocol_splits(std::int64_t n, std::int64_t repeats,
                                           std::int64_t calibration, std::int64_t test,
                                           std::uint64_t seed) {
  if (repeats < 1 || calibration < 2 || test < 2 || calibration + test > n)
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

RunEvaluation evaluate_run(const fs::path& run_dir, const fs::path& data_dir,
                           const RunEvaluationOptions& options) {
  RunEvaluation ev;
  ev.run_dir = run_dir.string();
  ev.data_dir = data_dir.string();
  crl::Estimator estimator = crl::Estimator::load(run_dir);
  crl::require_run_of_current_sim_dataset(run_dir);  // nor a run trained on it
  const crl::ExperimentConfig& config = estimator.config();
  const crl::RunDirectory run = crl::RunDirectory::open(run_dir);
  ev.config_name = config.name;
  ev.setting = config.name.substr(0, config.name.rfind('-'));
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

  // the test dataset: not the training set, the run's cameras and image size
  const core::DatasetReader reader = core::DatasetReader::open(data_dir);
  crl::require_current_sim_dataset(reader);  // never the old reading of TN(mean, x)
  reader.verify();  // a shard damaged after generation is refused, never evaluated on
  const fs::path manifest = data_dir / "manifest.json";
  ev.dataset_id = core::read_json_file(manifest).value("dataset", "");
  if (ev.dataset_id == ev.train_dataset_id)
    throw std::invalid_argument(
        data_dir.string() + " is the dataset the run trained on (dataset id " +
        ev.dataset_id.substr(0, 12) + "...); evaluate on one generated with another --seed");
  const std::vector<std::int64_t> shape = reader.column("images").row_shape;
  if (shape != std::vector<std::int64_t>{config.cameras, config.image_size, config.image_size})
    throw std::invalid_argument(manifest.string() + ": images of another shape than the run's (" +
                                std::to_string(config.cameras) + " cameras of " +
                                std::to_string(config.image_size) + "x" +
                                std::to_string(config.image_size) + ")");
  const nlohmann::json& names = reader.metadata_at("/joint_names");
  std::vector<std::size_t> joint_column;
  for (const std::string& j : config.joints) {
    std::size_t c = names.size();
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == j)
        c = i;
    if (c == names.size())
      throw std::invalid_argument(manifest.string() + ": metadata.joint_names has no '" + j + "'");
    joint_column.push_back(c);
  }
  const nlohmann::json& regimes = reader.metadata_at("/regimes");
  std::int32_t observational = -1;
  for (std::size_t r = 0; r < regimes.size(); ++r)
    if (regimes[r].contains("joint") && regimes[r]["joint"].is_null())
      observational = static_cast<std::int32_t>(r);
  const core::NpyArray regime = reader.read_rows("regime", 0, reader.rows());
  std::vector<std::int64_t> rows;
  for (std::int64_t r = 0; r < reader.rows(); ++r) {
    std::int32_t g;
    std::memcpy(&g, regime.data.data() + r * 4, 4);
    if (g == observational)
      rows.push_back(r);
  }
  // the protocol's sizes and the occlusion, checked before the images are encoded
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
  if (options.repeats < 1 || options.calibration_samples < 2 || options.test_samples < 2)
    throw std::invalid_argument("the protocol asks for " + std::to_string(options.repeats) +
                                " repeats of " + std::to_string(options.calibration_samples) +
                                " calibration and " + std::to_string(options.test_samples) +
                                " test samples; expected at least 1 repeat and 2 samples a set");
  if (static_cast<std::int64_t>(rows.size()) < wanted)
    throw std::invalid_argument(
        manifest.string() + ": " + std::to_string(rows.size()) +
        " observational samples; the protocol draws " +
        std::to_string(options.calibration_samples) + " calibration and " +
        std::to_string(options.test_samples) + " disjoint test samples a repeat (" +
        std::to_string(wanted) +
        "): generate more anchors, or ask for fewer (--calibration-samples, --test-samples)");

  const std::vector<std::int64_t> painted =
      occluded_cameras(config.cameras, options.occluded_cameras);  // checked before encoding

  // latents of every observational sample, in chunks
  const std::int64_t n = static_cast<std::int64_t>(rows.size()),
                     jn = static_cast<std::int64_t>(config.joints.size());
  const std::int64_t side = config.image_size, per = config.cameras * side * side;
  Eigen::MatrixXd z(n, jn), z0(n, jn), logit(n, jn), angles(n, jn), y;
  // the clean codes and silhouettes: this evaluation's own, or those a suite before it left
  EvaluationCache own;
  EvaluationCache& cache = options.cache ? *options.cache : own;
  if (!cache.run_dir.empty() && (cache.run_dir != run_dir || cache.data_dir != data_dir))
    throw std::invalid_argument("the evaluation cache holds run " + cache.run_dir.string() +
                                " on " + cache.data_dir.string() + "; this evaluation is run " +
                                run_dir.string() + " on " + data_dir.string() +
                                ": expected one cache per run and test set");
  cache.run_dir = run_dir;
  cache.data_dir = data_dir;
  const bool cached_codes = cache.clean_codes.rows() == n;
  if (options.occlusion > 0 && !cached_codes)
    cache.clean_codes.resize(0, 0);
  Eigen::MatrixXd& y_clean = cache.clean_codes;
  const core::NpyArray angle_rows = reader.read_rows_at("angles", rows);
  const std::int64_t angle_width = reader.column("angles").row_shape[0];
  // with robot_masks: per sample, robot pixels the squares hide and robot pixels in all
  const bool split_by_robot = options.occlusion > 0 && options.robot_masks != nullptr;
  const bool cached_masks = static_cast<std::int64_t>(cache.silhouettes.size()) == n;
  if (split_by_robot && !cached_masks) {
    cache.robot_pixels.assign(static_cast<std::size_t>(n), 0);
    cache.silhouettes.assign(static_cast<std::size_t>(n), {});
  }
  std::vector<std::int64_t> hidden(split_by_robot ? static_cast<std::size_t>(n) : 0);
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
            hidden[at] += silhouette[static_cast<std::size_t>((c * side + r) * side + x)];
      }
    }
    const Tensor codes = estimator.codes(to_input(raw.data, m));
    const Eigen::MatrixXd yc = to_matrix(codes);
    if (y.size() == 0)
      y.resize(n, yc.cols());
    y.middleRows(b, m) = yc;
    z.middleRows(b, m) = to_matrix(estimator.latents_from_codes(codes));
    logit.middleRows(b, m) = to_matrix(estimator.ldr_logits_from_codes(codes));
    if (estimator.has_lambda0())
      z0.middleRows(b, m) = to_matrix(estimator.lambda0_latents_from_codes(codes));
  }
  for (std::int64_t i = 0; i < n; ++i)
    for (std::int64_t k = 0; k < jn; ++k) {
      float a;
      std::memcpy(&a,
                  angle_rows.data.data() +
                      (i * angle_width +
                       static_cast<std::int64_t>(joint_column[static_cast<std::size_t>(k)])) *
                          4,
                  4);
      angles(i, k) = a;
    }

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
    const Eigen::RowVectorXd mean = y_clean.colwise().mean();
    const double spread = (y_clean.rowwise() - mean).squaredNorm();
    ev.code_shift = spread > 0 ? (y - y_clean).squaredNorm() / spread
                               : std::numeric_limits<double>::quiet_NaN();
  }
  // the PCA baseline: the leading principal components of AE1's code, fitted label-free on
  // the codes of the run's own training set (RUN/codes.npy), component k against joint k
  const Eigen::MatrixXd pca = pca_of_codes(run_dir / "codes.npy", y, jn);
  std::vector<std::pair<std::string, const Eigen::MatrixXd*>> sources = {{"ropes", &z}};
  if (estimator.has_lambda0())
    sources.push_back({"lambda0_autoencoder", &z0});
  sources.push_back({"ldr_logit", &logit});
  sources.push_back({"pca_of_code", &pca});
  // the supervised baselines: angle estimates straight from Y
  std::vector<std::pair<std::string, Eigen::MatrixXd>> supervised;
  for (const SupervisedEncoder* s : options.supervised) {
    if (s == nullptr || s->joints() != config.joints)
      throw std::invalid_argument(
          "evaluate_run: a supervised baseline " +
          std::string(s == nullptr ? "is null" : "estimates other joints than the run's") +
          "; train it on this run (SupervisedEncoder::train)");
    const std::string name = supervised_method_name(s->fraction());
    supervised.emplace_back(name, s->predict(y));
  }
  for (const auto& [name, estimate] : supervised)
    sources.push_back({name, &estimate});
  for (const auto& [name, latents] : sources) {
    MethodSummary m;
    m.method = name;
    for (std::size_t r = 0; r < splits.size(); ++r) {
      crl::Calibration fit;
      fit.joints = config.joints;
      fit.run = crl::RunIdentity::of(run);
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
  // the occlusion diagnostic: the test samples whose squares hide robot pixels, and the rest
  if (split_by_robot) {
    OcclusionSplit sp;
    double hiding = 0, share = 0;
    for (std::size_t i = 0; i < hidden.size(); ++i) {
      hiding += hidden[i] > 0;
      share += cache.robot_pixels[i] > 0
                   ? static_cast<double>(hidden[i]) / static_cast<double>(cache.robot_pixels[i])
                   : 0;
    }
    sp.share_hiding = hiding / static_cast<double>(n);
    sp.robot_hidden = share / static_cast<double>(n);
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
    ev.occlusion_split = std::move(sp);
  }
  // the repeat the scatter plots show, as the paper's do: ROPES' highest mean MCC
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
  {
    const ProtocolSplit& b = splits[static_cast<std::size_t>(ev.best_repeat)];
    for (std::int64_t k = 0; k < jn; ++k) {
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
  // the diagnostics, on repeat 0's samples (the MLP probe trains for seconds a repeat)
  const std::vector<Eigen::Index>& cal = splits[0].calibration;
  const std::vector<Eigen::Index>& test = splits[0].test;
  ev.probe_linear_mse = detail::linear_probe(y, angles, cal, test);
  if (options.probe_steps > 0)
    ev.probe_mlp_mse = detail::mlp_probe(y, angles, cal, test, options.probe_steps, options.seed);
  for (std::int64_t k = 0; k < jn; ++k) {
    const Eigen::VectorXd a = angles(test, Eigen::all).col(k);
    ev.angle_variance.push_back((a.array() - a.mean()).square().mean());
    const std::optional<crl::LdrRecord> l = run.ldr(config.joints[static_cast<std::size_t>(k)]);
    ev.ldr_accuracy.push_back(l ? l->held_out_accuracy : NAN);
    ev.bayes_accuracy.push_back(l ? l->bayes_accuracy : NAN);
  }

  // the paper's numbers for this setting
  const nlohmann::json paper = core::read_json_file(
      options.paper_results.empty() ? installed_paper_results() : options.paper_results);
  for (const std::string& j : config.joints) {
    const nlohmann::json* p = nullptr;
    if (paper["settings"].contains(ev.setting) && paper["settings"][ev.setting].contains(j))
      p = &paper["settings"][ev.setting][j];
    ev.paper_mcc.push_back(p ? (*p)["mcc"].get<double>() : NAN);
    ev.paper_mse.push_back(p ? (*p)["mse"].get<double>() : NAN);
  }
  return ev;
}

nlohmann::json RunEvaluation::to_json() const {
  const auto nums = detail::numbers_or_null;
  // null without an occlusion; code_shift, and the split when robot masks were given
  auto occlusion_json = [&]() -> nlohmann::json {
    if (occlusion <= 0)
      return nullptr;
    nlohmann::json j = {{"code_shift", nums({code_shift})[0]}, {"split", nullptr}};
    if (occlusion_split) {
      const OcclusionSplit& sp = *occlusion_split;
      nlohmann::json hiding = nlohmann::json::object(), missing = nlohmann::json::object();
      for (std::size_t m = 0; m < sp.methods.size(); ++m) {
        hiding[sp.methods[m]] = nums(sp.mcc_hiding[m]);
        missing[sp.methods[m]] = nums(sp.mcc_missing[m]);
      }
      j["split"] = {{"share_hiding_robot", sp.share_hiding},
                    {"robot_hidden", sp.robot_hidden},
                    {"mcc_hiding_robot", hiding},
                    {"mcc_missing_robot", missing}};
    }
    return j;
  };
  auto scores = [&](const MethodScores& m) {
    return nlohmann::json{{"mcc", nums(m.mcc)},
                          {"mse", nums(m.mse)},
                          {"spearman", nums(m.spearman)},
                          {"best_assignment_mcc", nums(m.best_assignment_mcc)},
                          {"mse_all_latents", nums(m.mse_all_latents)}};
  };
  nlohmann::json by_method = nlohmann::json::object();
  for (const MethodSummary& m : methods) {
    nlohmann::json j = scores(m.mean);
    const nlohmann::json sd = scores(m.std);
    for (auto it = sd.begin(); it != sd.end(); ++it)
      j[it.key() + "_std"] = it.value();
    j["repeats"] = nlohmann::json::array();
    for (const MethodScores& r : m.repeats) {
      nlohmann::json one = scores(r);
      one["best_assignment"] = r.best_assignment;
      j["repeats"].push_back(one);
    }
    by_method[m.method] = j;
  }
  return {{"format", "ropes-eval-results"},
          {"format_version", 2},
          {"run", run_dir},
          {"data", data_dir},
          {"config", config_name},
          {"setting", setting},
          {"dataset", dataset_id},
          {"train_dataset", train_dataset_id},
          {"joints", joints},
          {"extensions", extensions},
          {"provenance", provenance},
          {"provenance_differences", provenance_differences},
          {"protocol",
           {{"repeats", methods.empty() ? 0 : methods[0].repeats.size()},
            {"calibration_samples", calibration_samples},
            {"test_samples", test_samples},
            {"observational_samples", observational_samples},
            {"seed", seed},
            {"best_repeat", best_repeat},
            {"occlusion", occlusion},
            {"occlusion_seed", occlusion_seed},
            {"occluded_cameras", occluded_cameras}}},
          {"methods", by_method},
          {"occlusion_diagnostics", occlusion_json()},
          {"diagnostics",
           {{"probe_linear_mse", nums(probe_linear_mse)},
            {"probe_mlp_mse", nums(probe_mlp_mse)},
            {"angle_variance", nums(angle_variance)},
            {"ldr_held_out_accuracy", nums(ldr_accuracy)},
            {"ldr_bayes_accuracy", nums(bayes_accuracy)}}},
          {"paper", {{"mcc", nums(paper_mcc)}, {"mse", nums(paper_mse)}}},
          {"calibration", calibration.to_json()},
          {"notes",
           "each repeat draws calibration_samples and disjoint test_samples from the "
           "observational samples; a method's numbers are the mean over the repeats (*_std: the "
           "standard deviation, n - 1; repeats: each one). mcc: |Pearson| of latent k and joint k "
           "on the test samples; mse: rad^2 of the affine fit of joint k from latent k, fitted on "
           "the calibration samples, on the test samples; diagnostics: repeat 0's samples; "
           "spearman: |Spearman| of latent k and joint k; best_assignment_mcc: |Pearson| of joint "
           "k and the latent best_assignment[k] that a maximum-weight matching of joints to "
           "distinct latents on the |Pearson| matrix gives it; mse_all_latents: rad^2 of the "
           "affine fit of joint k from every latent of the method"}};
}

std::string RunEvaluation::table() const {
  const std::size_t reps = methods.empty() ? 0 : methods[0].repeats.size();
  auto pm = [](double mean, double sd) { return fmt(mean) + " ± " + fmt(sd); };
  std::ostringstream out;
  out << "ropes-eval: " << config_name << ", " << reps << " repeats of " << calibration_samples
      << " calibration and " << test_samples << " test samples (of " << observational_samples
      << " observational, dataset " << dataset_id.substr(0, 12) << "); mean ± std\n";
  if (!provenance_differences.empty())
    out << "note: trained under another build than this one (" << join(provenance_differences)
        << "): the numbers compare to rounding, not bit for bit\n";
  out << "| joint | MCC | MSE rad^2 | paper MCC | paper MSE | best-assignment MCC / Spearman | "
         "MSE from all latents |";
  // PCA's components have no pairing with the joints: its column is the best assignment's
  auto matched = [](const MethodSummary& m) { return m.method == "pca_of_code"; };
  for (std::size_t m = 1; m < methods.size(); ++m)
    out << " " << methods[m].method << (matched(methods[m]) ? " best-assignment" : "") << " MCC |";
  out << " probe MSE linear / MLP | angle var | LDR acc / Bayes |\n";
  out << "| --- | --- | --- | --- | --- | --- | --- |";
  for (std::size_t m = 1; m < methods.size(); ++m)
    out << " --- |";
  out << " --- | --- | --- |\n";
  for (std::size_t k = 0; k < joints.size(); ++k) {
    const MethodSummary& r = methods[0];
    // repeats whose best assignment gives joint k another latent than latent k
    std::size_t other = 0;
    for (const MethodScores& one : r.repeats)
      other +=
          k < one.best_assignment.size() && one.best_assignment[k] != static_cast<std::int64_t>(k)
              ? 1
              : 0;
    out << "| " << joints[k] << " | " << pm(r.mean.mcc[k], r.std.mcc[k]) << " | "
        << pm(r.mean.mse[k], r.std.mse[k]) << " | " << fmt(paper_mcc[k]) << " | "
        << fmt(paper_mse[k]) << " | " << fmt(r.mean.best_assignment_mcc[k])
        << (other > 0
                ? " (another latent in " + std::to_string(other) + "/" + std::to_string(reps) + ")"
                : std::string())
        << " / " << fmt(r.mean.spearman[k]) << " | " << fmt(r.mean.mse_all_latents[k]) << " |";
    for (std::size_t m = 1; m < methods.size(); ++m) {
      const MethodSummary& b = methods[m];
      out << " "
          << (matched(b) ? pm(b.mean.best_assignment_mcc[k], b.std.best_assignment_mcc[k])
                         : pm(b.mean.mcc[k], b.std.mcc[k]))
          << " |";
    }
    out << " " << fmt(probe_linear_mse[k], 4) << " / "
        << (probe_mlp_mse.empty() ? "-" : fmt(probe_mlp_mse[k], 4)) << " | "
        << fmt(angle_variance[k]) << " | " << fmt(ldr_accuracy[k]) << " / "
        << fmt(bayes_accuracy[k]) << " |\n";
  }
  return out.str();
}

std::string RunEvaluation::markdown() const {
  const std::size_t reps = methods.empty() ? 0 : methods[0].repeats.size();
  const MethodSummary& r = methods[0];
  auto pm = [](double mean, double sd) { return fmt(mean) + " ± " + fmt(sd); };
  // the paper's Table 1 has Joint 1 .. Joint 6 of the Panda; a run of other joints gets its own
  const std::vector<std::string> columns = detail::table_columns(joints);
  auto index_of = [&](const std::string& c) { return detail::index_of(joints, c); };
  std::ostringstream out;
  out << "# ropes-eval: " << config_name << "\n\n"
      << "- run: `" << run_dir << "`\n"
      << "- test data: `" << data_dir << "` (dataset " << dataset_id << "); trained on dataset "
      << train_dataset_id << "\n"
      << "- protocol: " << reps << " repeats, each " << calibration_samples << " calibration and "
      << test_samples << " disjoint test samples drawn from the " << observational_samples
      << " observational samples (seed " << seed << "); mean ± std over the repeats; MSE in rad²\n";
  for (const std::string& e : extensions)
    out << "- **extension, not the paper's method**: " << e << "\n";
  if (provenance.is_object() && provenance.contains("evaluation") &&
      provenance["evaluation"].is_object()) {
    const nlohmann::json& built = provenance["evaluation"];
    out << "- build: " << built.value("isa_level", "?") << ", " << built.value("compiler", "?")
        << ", Eigen " << built.value("eigen", "?") << ", revision " << built.value("revision", "?")
        << ", " << built.value("threads", 0) << " thread(s)\n";
  }
  if (!provenance_differences.empty())
    out << "- **trained under another build** (" << join(provenance_differences)
        << "): the numbers compare to rounding, not bit for bit\n";
  out << "\n";

  out << "## MCC and MSE, laid out like the paper's Table 1\n\n| setup |";
  for (const std::string& c : columns)
    out << " " << c << " MCC | MSE |";
  out << "\n| --- |";
  for (std::size_t i = 0; i < columns.size(); ++i)
    out << " --- | --- |";
  out << "\n| this run (" << setting << ") |";
  for (const std::string& c : columns) {
    const std::ptrdiff_t k = index_of(c);
    if (k < 0)
      out << " -- | -- |";
    else
      out << " " << pm(r.mean.mcc[k], r.std.mcc[k]) << " | " << pm(r.mean.mse[k], r.std.mse[k])
          << " |";
  }
  out << "\n| the paper (" << setting << ") |";
  for (const std::string& c : columns) {
    const std::ptrdiff_t k = index_of(c);
    out << " " << (k < 0 ? "--" : fmt(paper_mcc[k])) << " | " << (k < 0 ? "--" : fmt(paper_mse[k]))
        << " |";
  }
  out << "\n| difference |";
  for (const std::string& c : columns) {
    const std::ptrdiff_t k = index_of(c);
    if (k < 0)
      out << " -- | -- |";
    else
      out << " " << difference(r.mean.mcc[k], paper_mcc[k], true) << " | "
          << difference(r.mean.mse[k], paper_mse[k], false) << " |";
  }
  out << "\n\n## Baselines: MCC per joint\n\n"
         "PCA's components have no pairing with the joints: its row is the best assignment's "
         "MCC. The best-assignment MCC matches joints to distinct latents.\n\n| method |";
  for (const std::string& j : joints)
    out << " " << j << " |";
  out << "\n| --- |";
  for (std::size_t k = 0; k < joints.size(); ++k)
    out << " --- |";
  out << "\n";
  auto row = [&](const std::string& label, const std::vector<double>& mean,
                 const std::vector<double>& sd) {
    out << "| " << label << " |";
    for (std::size_t k = 0; k < joints.size(); ++k)
      out << " " << pm(mean[k], sd[k]) << " |";
    out << "\n";
  };
  row("ROPES", r.mean.mcc, r.std.mcc);
  row("ROPES, best assignment", r.mean.best_assignment_mcc, r.std.best_assignment_mcc);
  row("ROPES, Spearman", r.mean.spearman, r.std.spearman);
  for (std::size_t m = 1; m < methods.size(); ++m) {
    const MethodSummary& b = methods[m];
    if (b.method == "pca_of_code")
      row("PCA of AE1's code, best assignment", b.mean.best_assignment_mcc,
          b.std.best_assignment_mcc);
    else
      row(b.method == "lambda0_autoencoder" ? "λ = 0 autoencoder"
          : b.method == "ldr_logit"         ? "LDR logit"
                                            : b.method,
          b.mean.mcc, b.std.mcc);
  }
  out << "\n## Diagnostics (repeat 0's samples)\n\n"
         "| joint | probe MSE from Y, linear | MLP | angle variance | LDR held-out accuracy | "
         "Bayes accuracy | MSE from all of ROPES' latents (mean of the repeats) |\n"
         "| --- | --- | --- | --- | --- | --- | --- |\n";
  for (std::size_t k = 0; k < joints.size(); ++k)
    out << "| " << joints[k] << " | " << fmt(probe_linear_mse[k], 4) << " | "
        << (probe_mlp_mse.empty() ? "-" : fmt(probe_mlp_mse[k], 4)) << " | "
        << fmt(angle_variance[k]) << " | " << fmt(ldr_accuracy[k]) << " | "
        << fmt(bayes_accuracy[k]) << " | " << fmt(r.mean.mse_all_latents[k]) << " |\n";
  return out.str();
}

std::vector<double> detail::linear_probe(const Eigen::MatrixXd& y, const Eigen::MatrixXd& angles,
                                         const std::vector<Eigen::Index>& cal,
                                         const std::vector<Eigen::Index>& test) {
  const Eigen::MatrixXd yc = y(cal, Eigen::all);
  const Eigen::RowVectorXd mu = yc.colwise().mean();
  const Eigen::RowVectorXd inv =
      inverse_spread(((yc.rowwise() - mu).array().square().colwise().mean()).sqrt());
  auto design = [&](const Eigen::MatrixXd& m) {
    Eigen::MatrixXd x(m.rows(), m.cols() + 1);
    x.leftCols(m.cols()) = (m.rowwise() - mu).array().rowwise() * inv.array();
    x.col(m.cols()).setOnes();
    return x;
  };
  const Eigen::MatrixXd xc = design(yc), xt = design(y(test, Eigen::all));
  Eigen::MatrixXd gram = xc.transpose() * xc;
  gram.diagonal().array() += 1e-3 * static_cast<double>(xc.rows());
  const Eigen::MatrixXd w = gram.ldlt().solve(xc.transpose() * angles(cal, Eigen::all));
  const Eigen::MatrixXd err = xt * w - angles(test, Eigen::all);
  std::vector<double> out;
  for (Eigen::Index k = 0; k < err.cols(); ++k)
    out.push_back(err.col(k).array().square().mean());
  return out;
}

}  // namespace ropes::eval
