#pragma once
// ropes-eval --live: the rolling error and MCC of a pose-estimate stream against the
// simulator's ground truth (built with Fast DDS only).

namespace ropes::eval::tools {

/// argv[1] is "--live". Returns the exit status.
int run_live(int argc, char** argv);

}  // namespace ropes::eval::tools
