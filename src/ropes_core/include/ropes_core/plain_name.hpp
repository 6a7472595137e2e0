#pragma once
/// @file plain_name.hpp
/// Names that may become file or directory names as they are.
#include <cstddef>
#include <string>

namespace ropes::core {

/// True when `name` can name a file or directory as it is, never a path: 1 to `max_length`
/// letters, digits, '_', '-', '.', not starting with '.' (so no "..", no '/'). The config
/// names that tools name directories after must be such names.
bool is_plain_name(const std::string& name, std::size_t max_length = 128);

}  // namespace ropes::core
