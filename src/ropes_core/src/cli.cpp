#include "ropes_core/cli.hpp"

#include <cstdio>
#include <exception>
#include <iostream>

namespace ropes::core {

CommandLine::CommandLine(std::string usage, std::string help)
    : usage_(std::move(usage)), help_(std::move(help)) {}

CommandLine& CommandLine::option(const std::string& flag,
                                 std::function<void(const std::string&)> take) {
  options_.emplace_back(flag, std::move(take));
  return *this;
}

CommandLine& CommandLine::flag(const std::string& flag, std::function<void()> set) {
  flags_.emplace_back(flag, std::move(set));
  return *this;
}

CommandLine& CommandLine::positional(std::function<void(const std::string&)> take) {
  positional_ = std::move(take);
  return *this;
}

bool CommandLine::parse(int argc, char** argv, int first) const {
  for (int i = first; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-h" || arg == "--help") {
      std::cout << usage_;
      return false;
    }
    bool known = false;
    for (const auto& [name, set] : flags_)
      if (arg == name) {
        set();
        known = true;
        break;
      }
    if (known)
      continue;
    for (const auto& [name, take] : options_)
      if (arg == name) {
        if (i + 1 >= argc)
          throw UsageError("'" + arg + "' needs a value (" + help_ + ")");
        take(argv[++i]);
        known = true;
        break;
      }
    if (known)
      continue;
    if (positional_ && arg.rfind("--", 0) != 0) {
      positional_(arg);
      continue;
    }
    throw UsageError("unknown option '" + arg + "' (" + help_ + ")");
  }
  return true;
}

int run_main(const char* name, int (*run)(int, char**), int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const UsageError& e) {
    std::fflush(stdout);
    std::fprintf(stderr, "%s: error: %s\n", name, e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fflush(stdout);
    std::fprintf(stderr, "%s: error: %s\n", name, e.what());
    return 1;
  }
}

}  // namespace ropes::core
