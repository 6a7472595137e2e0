#include "ropes_eval/correlation.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace ropes::eval {

namespace {

void check_finite(const std::string& function, const char* name,
                  const Eigen::Ref<const Eigen::VectorXd>& v) {
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v(i))) {
      std::ostringstream message;
      message << function << ": " << name << "[" << i << "] is " << v(i)
              << "; expected a finite value";
      throw std::invalid_argument(message.str());
    }
  }
}

void check_pair(const std::string& function, const Eigen::Ref<const Eigen::VectorXd>& x,
                const Eigen::Ref<const Eigen::VectorXd>& y) {
  if (x.size() != y.size() || x.size() < 2) {
    std::ostringstream message;
    message << function << ": samples have lengths " << x.size() << " and " << y.size()
            << "; expected two samples of the same length, at least 2";
    throw std::invalid_argument(message.str());
  }
  check_finite(function, "x", x);
  check_finite(function, "y", y);
}

double pearson_unchecked(const std::string& function, const Eigen::Ref<const Eigen::VectorXd>& x,
                         const Eigen::Ref<const Eigen::VectorXd>& y) {
  // test constancy on the values: a rounded mean leaves tiny nonzero deviations
  const bool x_constant = x.minCoeff() == x.maxCoeff();
  if (x_constant || y.minCoeff() == y.maxCoeff()) {
    std::ostringstream message;
    message << function << ": " << (x_constant ? "x" : "y")
            << " is constant, so the correlation is undefined";
    throw std::invalid_argument(message.str());
  }
  const Eigen::ArrayXd dx = x.array() - x.mean();
  const Eigen::ArrayXd dy = y.array() - y.mean();
  const double sxx = dx.square().sum();
  const double syy = dy.square().sum();
  // clamp the last rounding step into [-1, 1]
  return std::clamp((dx * dy).sum() / std::sqrt(sxx * syy), -1.0, 1.0);
}

// `where` names the caller (and the column) in error messages
double correlation(const std::string& where, Correlation kind,
                   const Eigen::Ref<const Eigen::VectorXd>& x,
                   const Eigen::Ref<const Eigen::VectorXd>& y) {
  check_pair(where, x, y);
  if (kind == Correlation::kPearson) {
    return pearson_unchecked(where, x, y);
  }
  return pearson_unchecked(where, average_ranks(x), average_ranks(y));
}

}  // namespace

double pearson(const Eigen::Ref<const Eigen::VectorXd>& x,
               const Eigen::Ref<const Eigen::VectorXd>& y) {
  return correlation("pearson", Correlation::kPearson, x, y);
}

Eigen::VectorXd average_ranks(const Eigen::Ref<const Eigen::VectorXd>& x) {
  check_finite("average_ranks", "x", x);
  const Eigen::Index n = x.size();
  std::vector<Eigen::Index> order(static_cast<std::size_t>(n));
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  std::stable_sort(order.begin(), order.end(),
                   [&x](Eigen::Index a, Eigen::Index b) { return x(a) < x(b); });
  Eigen::VectorXd ranks(n);
  // walk runs of equal values; a run covering sorted positions [begin, end) gets the mean
  // of the 1-based ranks begin+1 .. end
  for (Eigen::Index begin = 0; begin < n;) {
    Eigen::Index end = begin + 1;
    while (end < n && x(order[end]) == x(order[begin]))
      ++end;
    const double rank = 0.5 * static_cast<double>(begin + 1 + end);
    for (Eigen::Index k = begin; k < end; ++k)
      ranks(order[k]) = rank;
    begin = end;
  }
  return ranks;
}

double spearman(const Eigen::Ref<const Eigen::VectorXd>& x,
                const Eigen::Ref<const Eigen::VectorXd>& y) {
  return correlation("spearman", Correlation::kSpearman, x, y);
}

Eigen::VectorXd per_joint_correlation(const Eigen::Ref<const Eigen::MatrixXd>& latents,
                                      const Eigen::Ref<const Eigen::MatrixXd>& angles,
                                      Correlation kind) {
  if (latents.rows() != angles.rows() || latents.cols() != angles.cols()) {
    std::ostringstream message;
    message << "per_joint_correlation: latents are [" << latents.rows() << ", " << latents.cols()
            << "] but angles are [" << angles.rows() << ", " << angles.cols()
            << "]; expected the same [samples, joints] shape";
    throw std::invalid_argument(message.str());
  }
  Eigen::VectorXd result(latents.cols());
  for (Eigen::Index j = 0; j < latents.cols(); ++j) {
    const std::string where = "per_joint_correlation: joint column " + std::to_string(j);
    result(j) = std::abs(correlation(where, kind, latents.col(j), angles.col(j)));
  }
  return result;
}

}  // namespace ropes::eval
