#pragma once
// Numbers as the tables print them (private to ropes_eval).
#include <cmath>
#include <cstdio>
#include <string>

namespace ropes::eval::detail {

// `digits` decimals; "-" for NaN or infinity
inline std::string fmt(double v, int digits = 3) {
  if (!std::isfinite(v))
    return "-";
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

inline std::string plus_minus(double mean, double sd) {
  return fmt(mean) + " ± " + fmt(sd);
}

// ours - theirs, signed, marked by which way it goes: "better" or "**worse**" (a higher MCC
// and a lower MSE are better); "--" when either is missing
inline std::string difference(double ours, double theirs, bool higher_is_better) {
  if (!std::isfinite(ours) || !std::isfinite(theirs))
    return "--";
  const double d = ours - theirs;
  char b[48];
  std::snprintf(b, sizeof b, "%+.3f", d);
  if (std::fabs(d) < 0.0005)
    return b;
  return std::string(b) + ((d > 0) == higher_is_better ? " better" : " **worse**");
}

}  // namespace ropes::eval::detail
