#include "ropes_core/plain_name.hpp"

#include <algorithm>
#include <cctype>

namespace ropes::core {

bool is_plain_name(const std::string& name, std::size_t max_length) {
  if (name.empty() || name.size() > max_length || name[0] == '.')
    return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
  });
}

}  // namespace ropes::core
