#include "ropes_crl/bayes_accuracy.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "json_fields.hpp"

namespace ropes::crl {

TruncatedNormal truncated_normal_from_json(const nlohmann::json& j, const std::string& where) {
  const double mean = detail::get_double(j, where, "mean");
  double sd = 0;
  // the paper's TN(mean, x) takes the variance x (ropes_sim's distribution files say
  // `variance`); `std` is read too, never both
  const bool has_variance = j.is_object() && j.contains("variance");
  const bool has_std = j.is_object() && j.contains("std");
  if (has_variance == has_std)
    throw std::invalid_argument(
        where +
        (has_variance ? ": gives both variance and std" : ": gives neither variance nor std") +
        "; expected exactly one");
  if (has_variance) {
    const double variance = detail::get_double(j, where, "variance");
    if (!(variance > 0) || !std::isfinite(variance)) {
      std::ostringstream got;
      got << variance;
      throw std::invalid_argument(where + ".variance: expected a finite number > 0, got " +
                                  got.str());
    }
    sd = std::sqrt(variance);
  } else {
    sd = detail::get_double(j, where, "std");
  }
  const double lower = detail::get_double(j, where, "lower");
  const double upper = detail::get_double(j, where, "upper");
  try {
    return TruncatedNormal(mean, sd, lower, upper);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(where + ": " + e.what());
  }
}

double bayes_accuracy(const TruncatedNormal& p, const TruncatedNormal& q) {
  // composite Simpson on each piece between the supports' ends (the densities jump there)
  std::vector<double> cuts = {p.lower(), p.upper(), q.lower(), q.upper()};
  std::sort(cuts.begin(), cuts.end());
  const int n = 20000;
  double total = 0;
  for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
    const double a = cuts[c], b = cuts[c + 1];
    if (!(b > a))
      continue;
    // evaluate just inside the piece so that a jump at its ends is not sampled
    const double h = (b - a) / n, inset = 1e-12 * (b - a);
    double s = 0;
    for (int i = 0; i <= n; ++i) {
      const double x = i == 0 ? a + inset : (i == n ? b - inset : a + h * i);
      const double w = (i == 0 || i == n) ? 1 : (i % 2 == 1 ? 4 : 2);
      s += w * std::max(p.pdf(x), q.pdf(x));
    }
    total += s * h / 3.0;
  }
  return 0.5 * total;
}

}  // namespace ropes::crl
