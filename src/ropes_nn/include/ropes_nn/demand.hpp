#pragma once
/// @file demand.hpp
/// ROPES_DEMAND(condition, message): the first error tier of STYLE.md. A broken invariant —
/// something no caller input can cause, only a bug in this library — aborts the process with
/// the file, the line, the condition and `message`, instead of reading or writing out of
/// bounds. Always on (release builds too); the message is only built when the check fails.
/// Caller mistakes are exceptions, not demands.

#include <string>

namespace ropes::nn::detail {
/// Prints "<file>:<line>: ROPES_DEMAND(<condition>) failed: <message>" to stderr and aborts.
[[noreturn]] void demand_failed(const char* file, int line, const char* condition,
                                const std::string& message) noexcept;
}  // namespace ropes::nn::detail

#define ROPES_DEMAND(condition, message)                                             \
  do {                                                                               \
    if (!(condition))                                                                \
      ::ropes::nn::detail::demand_failed(__FILE__, __LINE__, #condition, (message)); \
  } while (false)
