#include "ropes_core/truncated_normal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace ropes::core {

namespace {

constexpr double kSqrt2 = 1.41421356237309504880;
constexpr double kSqrt2Pi = 2.50662827463100050242;
constexpr double kTailLimit = 37.0;  // standard deviations

double phi(double x) {
  return std::exp(-0.5 * x * x) / kSqrt2Pi;
}
double big_phi(double x) {
  return 0.5 * std::erfc(-x / kSqrt2);
}

[[noreturn]] void throw_invalid(const char* what, double mu, double sigma, double lower,
                                double upper) {
  std::ostringstream message;
  message.precision(17);
  message << "TruncatedNormal(mu=" << mu << ", sigma=" << sigma << ", lower=" << lower
          << ", upper=" << upper << "): " << what;
  throw std::invalid_argument(message.str());
}

}  // namespace

double standard_normal_quantile(double p) {
  if (!(p >= 0.0 && p <= 1.0)) {
    std::ostringstream message;
    message << "standard_normal_quantile: p=" << p << " is outside [0, 1]";
    throw std::invalid_argument(message.str());
  }
  if (p == 0.0)
    return -std::numeric_limits<double>::infinity();
  if (p == 1.0)
    return std::numeric_limits<double>::infinity();

  // Acklam's rational approximation, relative error < 1.15e-9
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  const double p_low = 0.02425;
  double x = 0.0;
  if (p < p_low) {
    const double q = std::sqrt(-2.0 * std::log(p));
    x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  } else if (p <= 1.0 - p_low) {
    const double q = p - 0.5;
    const double r = q * q;
    x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
  } else {
    const double q = std::sqrt(-2.0 * std::log1p(-p));
    x = -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  }

  // one Halley step on Phi(x) - p brings it to full double precision
  const double e = big_phi(x) - p;
  const double u = e * kSqrt2Pi * std::exp(0.5 * x * x);
  if (!std::isfinite(u))
    return x;  // |x| > 37.6: exp overflows, keep the approximation
  return x - u / (1.0 + 0.5 * x * u);
}

TruncatedNormal::TruncatedNormal(double mu, double sigma, double lower, double upper)
    : mu_(mu), sigma_(sigma), lower_(lower), upper_(upper) {
  if (!std::isfinite(mu) || !std::isfinite(sigma) || !std::isfinite(lower) ||
      !std::isfinite(upper)) {
    throw_invalid("every parameter must be finite", mu, sigma, lower, upper);
  }
  if (!(sigma > 0.0)) {
    throw_invalid("sigma (a standard deviation) must be > 0", mu, sigma, lower, upper);
  }
  if (!(lower < upper)) {
    throw_invalid("the interval is empty: expected lower < upper", mu, sigma, lower, upper);
  }
  // standardise; an interval in the upper tail is mirrored into the lower tail
  double alpha = (lower - mu) / sigma;
  double beta = (upper - mu) / sigma;
  flipped_ = alpha > 0.0;
  if (flipped_) {
    std::swap(alpha, beta);
    alpha = -alpha;
    beta = -beta;
  }
  alpha_ = alpha;
  beta_ = beta;
  cdf_alpha_ = big_phi(alpha_);
  cdf_beta_ = big_phi(beta_);
  // beyond 37 sigma the normal density underflows: no mass double precision can represent
  if (beta_ < -kTailLimit || !(cdf_beta_ - cdf_alpha_ > 0.0)) {
    throw_invalid("the interval holds no probability mass in double precision", mu, sigma, lower,
                  upper);
  }
}

double TruncatedNormal::quantile(double u) const {
  if (!(u >= 0.0 && u <= 1.0)) {
    std::ostringstream message;
    message << "TruncatedNormal::quantile: u=" << u << " is outside [0, 1]";
    throw std::invalid_argument(message.str());
  }
  // the bounds exactly, not through a rounded round trip
  if (u == 0.0)
    return lower_;
  if (u == 1.0)
    return upper_;
  // in the (possibly mirrored) standard frame, the mass left of the result is u
  const double v = flipped_ ? 1.0 - u : u;
  const double p = cdf_alpha_ + v * (cdf_beta_ - cdf_alpha_);
  double z = standard_normal_quantile(p);
  z = std::clamp(z, alpha_, beta_);
  const double x = mu_ + sigma_ * (flipped_ ? -z : z);
  return std::clamp(x, lower_, upper_);
}

double TruncatedNormal::sample(PhiloxStream& rng) const {
  return quantile(rng.uniform_double());
}

double TruncatedNormal::cdf(double x) const {
  if (x <= lower_)
    return 0.0;
  if (x >= upper_)
    return 1.0;
  const double z = (x - mu_) / sigma_;
  const double mass = cdf_beta_ - cdf_alpha_;
  if (flipped_) {
    // P(X <= x) = P(-X >= -x) = (Phi(beta') - Phi(-z)) / mass
    return (cdf_beta_ - big_phi(-z)) / mass;
  }
  return (big_phi(z) - cdf_alpha_) / mass;
}

double TruncatedNormal::pdf(double x) const {
  if (x < lower_ || x > upper_)
    return 0.0;
  return phi((x - mu_) / sigma_) / (sigma_ * (cdf_beta_ - cdf_alpha_));
}

double TruncatedNormal::mean() const {
  const double mass = cdf_beta_ - cdf_alpha_;
  const double shift = (phi(alpha_) - phi(beta_)) / mass;  // mean of the standard frame
  return mu_ + sigma_ * (flipped_ ? -shift : shift);
}

double TruncatedNormal::variance() const {
  const double mass = cdf_beta_ - cdf_alpha_;
  const double shift = (phi(alpha_) - phi(beta_)) / mass;
  const double spread = (alpha_ * phi(alpha_) - beta_ * phi(beta_)) / mass;
  return sigma_ * sigma_ * (1.0 + spread - shift * shift);
}

}  // namespace ropes::core
