#include "ropes_nn/demand.hpp"

#include <cstdio>
#include <cstdlib>

namespace ropes::nn::detail {

void demand_failed(const char* file, int line, const char* condition,
                   const std::string& message) noexcept {
  std::fprintf(stderr, "%s:%d: ROPES_DEMAND(%s) failed: %s\n", file, line, condition,
               message.c_str());
  std::fflush(stderr);
  std::abort();
}

}  // namespace ropes::nn::detail
