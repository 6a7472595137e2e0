#pragma once
// Numbers as the tables print them (private to ropes_eval).
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

namespace ropes::eval::detail {

// `digits` decimals; "-" for NaN or infinity
inline std::string fmt(double v, int digits = 3) {
  if (!std::isfinite(v))
    return "-";
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// fmt(*v), or "--" when there is no value
inline std::string fmt(const std::optional<double>& v) {
  return v ? fmt(*v) : "--";
}

// the strings, separated by "; "
inline std::string join(const std::vector<std::string>& parts) {
  std::string out;
  for (const std::string& p : parts)
    out += (out.empty() ? "" : "; ") + p;
  return out;
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

// the columns of the paper's tables: the Panda's joints 1..6 when the run's joints are among
// them, else the run's own
inline std::vector<std::string> table_columns(const std::vector<std::string>& joints) {
  bool panda = true;
  for (const std::string& j : joints)
    panda =
        panda && j.size() == 12 && j.rfind("panda_joint", 0) == 0 && j[11] >= '1' && j[11] <= '6';
  if (!panda)
    return joints;
  std::vector<std::string> c;
  for (int i = 1; i <= 6; ++i)
    c.push_back("panda_joint" + std::to_string(i));
  return c;
}

// the position of joint `j` in `joints`, -1 when absent
inline std::ptrdiff_t index_of(const std::vector<std::string>& joints, const std::string& j) {
  for (std::size_t k = 0; k < joints.size(); ++k)
    if (joints[k] == j)
      return static_cast<std::ptrdiff_t>(k);
  return -1;
}

}  // namespace ropes::eval::detail
