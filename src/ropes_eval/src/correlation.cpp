#include "ropes_eval/correlation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "finite_check.hpp"

namespace ropes::eval {

namespace {

void check_pair(const std::string& function, const Eigen::Ref<const Eigen::VectorXd>& x,
                const Eigen::Ref<const Eigen::VectorXd>& y) {
  if (x.size() != y.size() || x.size() < 2) {
    std::ostringstream message;
    message << function << ": samples have lengths " << x.size() << " and " << y.size()
            << "; expected two samples of the same length, at least 2";
    throw std::invalid_argument(message.str());
  }
  detail::require_finite(function, "x", x);
  detail::require_finite(function, "y", y);
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
  detail::require_finite("average_ranks", "x", x);
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

Eigen::MatrixXd correlation_matrix(const Eigen::Ref<const Eigen::MatrixXd>& latents,
                                   const Eigen::Ref<const Eigen::MatrixXd>& angles,
                                   Correlation kind) {
  if (latents.rows() != angles.rows() || latents.rows() < 2) {
    std::ostringstream message;
    message << "correlation_matrix: latents are [" << latents.rows() << ", " << latents.cols()
            << "] and angles [" << angles.rows() << ", " << angles.cols()
            << "]; expected the same number of samples (rows), at least 2";
    throw std::invalid_argument(message.str());
  }
  // each column once: checked, constancy tested, ranked if asked
  auto prepared = [&](const Eigen::Ref<const Eigen::MatrixXd>& m, const char* what) {
    Eigen::MatrixXd out(m.rows(), m.cols());
    for (Eigen::Index c = 0; c < m.cols(); ++c) {
      const std::string where =
          std::string("correlation_matrix: ") + what + " column " + std::to_string(c);
      detail::require_finite(where, "value", m.col(c));
      if (m.col(c).minCoeff() == m.col(c).maxCoeff())
        throw std::invalid_argument(where + " is constant, so its correlation is undefined");
      out.col(c) =
          kind == Correlation::kPearson ? Eigen::VectorXd(m.col(c)) : average_ranks(m.col(c));
    }
    return out;
  };
  const Eigen::MatrixXd z = prepared(latents, "latent"), a = prepared(angles, "joint");
  Eigen::MatrixXd result(a.cols(), z.cols());
  for (Eigen::Index j = 0; j < a.cols(); ++j)
    for (Eigen::Index l = 0; l < z.cols(); ++l)
      result(j, l) = std::abs(pearson_unchecked("correlation_matrix", z.col(l), a.col(j)));
  return result;
}

Assignment best_assignment(const Eigen::Ref<const Eigen::MatrixXd>& weights) {
  const Eigen::Index k = weights.rows(), d = weights.cols();
  if (k == 0 || k > d) {
    std::ostringstream message;
    message << "best_assignment: the weights are [" << k << ", " << d
            << "]; expected [joints, latents] with 1 <= joints <= latents";
    throw std::invalid_argument(message.str());
  }
  detail::require_finite("best_assignment", "weight", weights);
  // minimum-cost assignment of cost = -weight, rows added one at a time; each addition
  // finds a shortest augmenting path (Dijkstra on reduced costs) and updates the dual
  // potentials u (rows) and v (columns) so that reduced costs stay >= 0. Index 0 of the
  // column arrays is a virtual column that holds the row being added.
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> u(static_cast<std::size_t>(k + 1), 0.0),
      v(static_cast<std::size_t>(d + 1), 0.0);
  std::vector<Eigen::Index> row_of(static_cast<std::size_t>(d + 1), 0),  // column -> row (1-based)
      way(static_cast<std::size_t>(d + 1), 0);
  auto at = [](auto& vec, Eigen::Index i) -> auto& {
    return vec[static_cast<std::size_t>(i)];
  };
  for (Eigen::Index row = 1; row <= k; ++row) {
    at(row_of, 0) = row;
    Eigen::Index col0 = 0;
    std::vector<double> dist(static_cast<std::size_t>(d + 1), inf);
    std::vector<char> used(static_cast<std::size_t>(d + 1), 0);
    do {
      at(used, col0) = 1;
      const Eigen::Index r = at(row_of, col0);
      double delta = inf;
      Eigen::Index next = 0;
      for (Eigen::Index c = 1; c <= d; ++c) {
        if (at(used, c))
          continue;
        const double reduced = -weights(r - 1, c - 1) - at(u, r) - at(v, c);
        if (reduced < at(dist, c)) {
          at(dist, c) = reduced;
          at(way, c) = col0;
        }
        if (at(dist, c) < delta) {  // strict: the lowest-numbered column wins a tie
          delta = at(dist, c);
          next = c;
        }
      }
      for (Eigen::Index c = 0; c <= d; ++c) {
        if (at(used, c)) {
          at(u, at(row_of, c)) += delta;
          at(v, c) -= delta;
        } else {
          at(dist, c) -= delta;
        }
      }
      col0 = next;
    } while (at(row_of, col0) != 0);
    // flip the augmenting path back to the virtual column
    do {
      const Eigen::Index prev = at(way, col0);
      at(row_of, col0) = at(row_of, prev);
      col0 = prev;
    } while (col0 != 0);
  }
  Assignment out;
  out.latent_of_joint.assign(static_cast<std::size_t>(k), -1);
  for (Eigen::Index c = 1; c <= d; ++c)
    if (at(row_of, c) != 0)
      out.latent_of_joint[static_cast<std::size_t>(at(row_of, c) - 1)] = c - 1;
  out.correlation.resize(k);
  for (Eigen::Index j = 0; j < k; ++j)
    out.correlation(j) = weights(j, out.latent_of_joint[static_cast<std::size_t>(j)]);
  out.mean = out.correlation.mean();
  return out;
}

Assignment best_assignment_correlation(const Eigen::Ref<const Eigen::MatrixXd>& latents,
                                       const Eigen::Ref<const Eigen::MatrixXd>& angles,
                                       Correlation kind) {
  return best_assignment(correlation_matrix(latents, angles, kind));
}

}  // namespace ropes::eval
