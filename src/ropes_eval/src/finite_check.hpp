#pragma once
// Private to ropes_eval: the one check of input values its measures share.
#include <Eigen/Core>

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace ropes::eval::detail {

// Throws std::invalid_argument "<function>: <name>[i] is v; expected a finite value" (a
// column vector) or "<function>: <name> (r, c) is v; ..." (a matrix) for the first value
// that is not finite, walking column by column.
inline void require_finite(const std::string& function, const char* name,
                           const Eigen::Ref<const Eigen::MatrixXd>& m) {
  for (Eigen::Index c = 0; c < m.cols(); ++c)
    for (Eigen::Index r = 0; r < m.rows(); ++r)
      if (!std::isfinite(m(r, c))) {
        std::ostringstream message;
        message << function << ": " << name;
        if (m.cols() == 1)
          message << "[" << r << "]";
        else
          message << " (" << r << ", " << c << ")";
        message << " is " << m(r, c) << "; expected a finite value";
        throw std::invalid_argument(message.str());
      }
}

}  // namespace ropes::eval::detail
