#pragma once
// Reading typed fields from JSON with errors that name the field, the value and what was
// expected. `where` is a path prefix such as "ae1" or "config.ldr". Values come from files:
// they are shown with core::describe, never dump() (its recursion is as deep as the value).
#include <nlohmann/json.hpp>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "ropes_core/json_text.hpp"

namespace ropes::crl::detail {

inline const nlohmann::json& field(const nlohmann::json& j, const std::string& where,
                                   const std::string& key) {
  if (!j.is_object())
    throw std::invalid_argument(where + ": expected an object, got " + core::describe(j));
  const auto it = j.find(key);
  if (it == j.end())
    throw std::invalid_argument(where + "." + key + ": missing");
  return *it;
}

inline std::int64_t get_int(const nlohmann::json& j, const std::string& where,
                            const std::string& key) {
  const nlohmann::json& v = field(j, where, key);
  if (!v.is_number_integer())
    throw std::invalid_argument(where + "." + key + ": expected an integer, got " +
                                core::describe(v));
  return v.get<std::int64_t>();
}

inline double get_double(const nlohmann::json& j, const std::string& where,
                         const std::string& key) {
  const nlohmann::json& v = field(j, where, key);
  if (!v.is_number())
    throw std::invalid_argument(where + "." + key + ": expected a number, got " +
                                core::describe(v));
  return v.get<double>();
}

inline bool get_bool(const nlohmann::json& j, const std::string& where, const std::string& key) {
  const nlohmann::json& v = field(j, where, key);
  if (!v.is_boolean())
    throw std::invalid_argument(where + "." + key + ": expected true or false, got " +
                                core::describe(v));
  return v.get<bool>();
}

inline std::string get_string(const nlohmann::json& j, const std::string& where,
                              const std::string& key) {
  const nlohmann::json& v = field(j, where, key);
  if (!v.is_string())
    throw std::invalid_argument(where + "." + key + ": expected a string, got " +
                                core::describe(v));
  return v.get<std::string>();
}

inline std::vector<std::int64_t> get_ints(const nlohmann::json& j, const std::string& where,
                                          const std::string& key) {
  const nlohmann::json& v = field(j, where, key);
  if (!v.is_array())
    throw std::invalid_argument(where + "." + key + ": expected an array of integers, got " +
                                core::describe(v));
  std::vector<std::int64_t> out;
  for (const nlohmann::json& e : v) {
    if (!e.is_number_integer())
      throw std::invalid_argument(where + "." + key + ": expected an array of integers, got " +
                                  core::describe(v));
    out.push_back(e.get<std::int64_t>());
  }
  return out;
}

inline std::vector<std::string> get_strings(const nlohmann::json& j, const std::string& where,
                                            const std::string& key) {
  const nlohmann::json& v = field(j, where, key);
  std::vector<std::string> out;
  if (v.is_array())
    for (const nlohmann::json& e : v)
      if (e.is_string())
        out.push_back(e.get<std::string>());
  if (!v.is_array() || out.size() != v.size())
    throw std::invalid_argument(where + "." + key + ": expected an array of strings, got " +
                                core::describe(v));
  return out;
}

// the keys of `j` that are not in `known`: a misspelt option is an error, not a default
inline void reject_unknown_keys(const nlohmann::json& j, const std::string& where,
                                const std::vector<std::string>& known) {
  if (!j.is_object())  // found by fuzz/experiment_config: a config file holding "0"
    throw std::invalid_argument(where + ": expected a JSON object, got " + core::describe(j));
  for (auto it = j.begin(); it != j.end(); ++it) {
    bool ok = false;
    for (const std::string& k : known)
      ok = ok || k == it.key();
    if (!ok) {
      std::string list;
      for (const std::string& k : known)
        list += (list.empty() ? "" : ", ") + k;
      throw std::invalid_argument(where + "." + it.key() + ": unknown key (expected one of " +
                                  list + ")");
    }
  }
}

}  // namespace ropes::crl::detail
