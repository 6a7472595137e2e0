#pragma once
/// @file cli.hpp
/// What every executable of the workspace does the same way on its command line: usage errors,
/// number flags, the flags themselves, and one `main` that turns an exception into one line
/// and an exit status.
#include <charconv>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace ropes::core {

/// A mistake on the command line (an unknown flag, a missing or malformed value). run_main
/// prints it and returns exit status 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace detail {
template <typename T>
std::string bound_text(T v) {
  if constexpr (std::is_floating_point_v<T>) {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%g", static_cast<double>(v));
    return buffer;
  } else {
    return std::to_string(v);
  }
}
template <typename T>
const char* kind_text() {
  return std::is_floating_point_v<T> ? "a number" : "an integer";
}
}  // namespace detail

/// The value of flag `flag` given as `text`: the whole text must be a T (an integer type: no
/// sign for an unsigned one, no fraction; a floating-point type: finite). Throws UsageError
/// "FLAG is 'TEXT'; expected an integer" (or "a number") otherwise.
template <typename T>
T parse_number(const std::string& flag, const std::string& text) {
  static_assert(std::is_arithmetic_v<T> && !std::is_same_v<T, bool>, "parse_number: a number");
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  bool ok = !text.empty() && ec == std::errc() && end == text.data() + text.size();
  if constexpr (std::is_floating_point_v<T>)
    ok = ok && std::isfinite(value);
  if (!ok)
    throw UsageError(flag + " is '" + text + "'; expected " + detail::kind_text<T>());
  return value;
}

/// The same, and the value must lie in [lo, hi]: UsageError "FLAG is 'TEXT'; expected an
/// integer in [LO, HI]" (or "a number in") otherwise.
template <typename T>
T parse_number(const std::string& flag, const std::string& text, T lo, T hi) {
  const auto fail = [&] {
    return UsageError(flag + " is '" + text + "'; expected " + detail::kind_text<T>() + " in [" +
                      detail::bound_text(lo) + ", " + detail::bound_text(hi) + "]");
  };
  T value{};
  try {
    value = parse_number<T>(flag, text);
  } catch (const UsageError&) {
    throw fail();
  }
  if (!(value >= lo && value <= hi))
    throw fail();
  return value;
}

/// f() for the value of flag `flag`: its std::invalid_argument becomes a UsageError
/// "FLAG: MESSAGE" (for the parsers of other libraries, which know no command line).
template <typename F>
auto for_flag(const std::string& flag, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const std::invalid_argument& e) {
    throw UsageError(flag + ": " + e.what());
  }
}

/// A tool's command line: options with a value ("--run DIR"), switches ("--screen") and, for
/// a tool that takes them, positional arguments; -h or --help prints the usage. Every tool's
/// mistakes read the same: "'--run' needs a value (see --help)", "unknown option '--x' (see
/// --help)".
class CommandLine {
 public:
  /// `usage` is what --help prints; `help` is how the messages point to it.
  explicit CommandLine(std::string usage, std::string help = "see --help");
  /// --flag VALUE: `take` gets the value; it may throw UsageError (parse_number does).
  CommandLine& option(const std::string& flag, std::function<void(const std::string&)> take);
  /// --flag alone.
  CommandLine& flag(const std::string& flag, std::function<void()> set);
  /// The arguments that do not start with "--" (without this they are unknown options);
  /// `take` may throw UsageError (one positional argument only, say).
  CommandLine& positional(std::function<void(const std::string&)> take);
  /// Parses argv[first] to argv[argc - 1] in order. Returns false when -h or --help came (the
  /// usage is printed on stdout; the tool then exits 0), true otherwise; throws UsageError for
  /// an unknown option or a missing value, and passes on what `take` and `set` throw.
  bool parse(int argc, char** argv, int first = 1) const;

 private:
  std::string usage_, help_;
  std::vector<std::pair<std::string, std::function<void(const std::string&)>>> options_;
  std::vector<std::pair<std::string, std::function<void()>>> flags_;
  std::function<void(const std::string&)> positional_;
};

/// A tool's main: returns run(argc, argv). An exception escaping it is printed on stderr as
/// one line, "NAME: error: MESSAGE", and the status is 2 for a UsageError, 1 for any other
/// std::exception. NAME is the executable's name (ropes-generate, ropes-train, ...).
int run_main(const char* name, int (*run)(int, char**), int argc, char** argv);

}  // namespace ropes::core
