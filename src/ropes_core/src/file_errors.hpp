#pragma once
// What ropes_core's file readers and writers share (private to ropes_core): the error each of
// them throws, and a C stream closed on destruction. One definition each, so that no two
// sources of the library hold helpers of one name (the sanitizer build compiles them as unity
// sources, several to a translation unit).
#include <cstdio>
#include <memory>
#include <string>

namespace ropes::core::detail {

// a FileFormatError "<name>: <what>"
[[noreturn]] void fail(const std::string& name, const std::string& what);

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

}  // namespace ropes::core::detail
