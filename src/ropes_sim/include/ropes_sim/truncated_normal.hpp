#pragma once
/// @file truncated_normal.hpp
/// The simulator's truncated normal is ropes_core's (ropes_core/truncated_normal.hpp), the one
/// the learner's Bayes accuracy uses too; here under the simulator's namespace.
#include <ropes_core/truncated_normal.hpp>

namespace ropes::sim {

using core::standard_normal_quantile;
using core::TruncatedNormal;

}  // namespace ropes::sim
