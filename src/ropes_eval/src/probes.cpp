#include "ropes_eval/probes.hpp"

#include <ropes_core/dataset.hpp>
#include <ropes_nn/adam.hpp>
#include <ropes_nn/layers.hpp>
#include <ropes_nn/ops.hpp>
#include <ropes_nn/train_step.hpp>

#include <Eigen/Dense>

#include <memory>

#include "tensor_matrix.hpp"

namespace ropes::eval {

using nn::Shape;
using nn::Tensor;

namespace {

// 1 / sd of each column, and 0 for a column that barely varies on the calibration samples
// (sd <= 1e-3 of the largest): dividing one by its tiny sd would turn the differences the
// test samples show there into huge values, and it carries no information the fit can use
Eigen::RowVectorXd inverse_spread(const Eigen::RowVectorXd& sd) {
  const double largest = sd.size() > 0 ? sd.maxCoeff() : 0.0;
  return (sd.array() > 1e-3 * largest).select(sd.array().inverse(), 0.0);
}

}  // namespace

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

}  // namespace ropes::eval
