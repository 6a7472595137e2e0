#pragma once
// Private: JSON read from files, bounded, and described in messages without dumping it.
#include <nlohmann/json.hpp>

#include <string>

namespace ropes::nn::detail {

inline constexpr int kMaxJsonDepth = 64;

// parses `text`; "" and the value in `out`, or what is wrong. Nesting is bounded, so that
// dumping or destroying the value later cannot overflow the stack.
std::string parse_json(const std::string& text, nlohmann::json* out);

// a short description of a value read from a file (never dump() an untrusted value: its
// recursion is as deep as the value)
std::string describe(const nlohmann::json& v);

// the same, but an array is shown as its first 8 sizes ("[2,3,?]", "?" for an entry that is
// not a non-negative integer): a shape or a pair of offsets
std::string describe_sizes(const nlohmann::json& v);

}  // namespace ropes::nn::detail
