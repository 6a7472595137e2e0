#pragma once
/// @file child_process.hpp
/// ChildProcess: another program run by this one, as the workspace's tests and benchmarks run
/// the executables (the one way they do). Its stdout and stderr go together into a log file
/// or through a pipe, which a thread of this process reads into output() and hands, line by
/// line, to a callback; a child still running when the object goes is killed (SIGKILL) and
/// reaped, so a failing test leaves no process behind.
#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace ropes::core {

class ChildProcess;

struct ChildOptions {
  /// stdout and stderr into this file (created, or truncated); empty: through a pipe
  std::filesystem::path log;
  /// With the pipe: called by the reading thread with each line, its '\n' included (a last
  /// line without one when the output ends). It may signal the child.
  std::function<void(ChildProcess& child, const std::string& line)> on_line;
  /// "NAME=value" entries set in the child's environment, over the parent's
  std::vector<std::string> environment;
  /// > 0: the child's RLIMIT_FSIZE in bytes, with SIGXFSZ ignored, so that a write past
  /// it fails with EFBIG instead of killing the child
  std::uint64_t file_size_limit = 0;

  /// Options that send the output into `log`.
  static ChildOptions to_log(const std::filesystem::path& log) {
    ChildOptions o;
    o.log = log;
    return o;
  }
};

class ChildProcess {
 public:
  /// Starts args[0] (a path; PATH is not searched) with the arguments `args`. Throws
  /// std::system_error naming the program when it cannot be started (no such file, not
  /// executable), std::invalid_argument for empty `args`. running() and wait() throw
  /// std::system_error when the child cannot be waited for (SIGCHLD ignored).
  explicit ChildProcess(std::vector<std::string> args, ChildOptions options = {});
  /// Kills (SIGKILL) and reaps a child still running, and ends the reading thread.
  ~ChildProcess();
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  /// True until the child has ended (and been reaped).
  bool running();
  /// Sends `sig` to a child not yet reaped (from any thread, the reading one included).
  void signal(int sig);
  /// Waits up to `timeout` for the end: the exit status, or -1 when the child was killed by a
  /// signal or still runs.
  int wait(std::chrono::milliseconds timeout);
  /// Waits for the end however long it takes: the exit status, -1 when killed by a signal.
  int wait();
  /// The raw wait status once the child has ended (WIFSIGNALED and the like).
  int status() const { return status_; }
  /// What the pipe has given so far (empty with a log file). After wait(), all of it.
  std::string output() const;

 private:
  // reaps the child, which has ended (waitid says so), under reap_mutex_
  void reap();
  void join_reader();
  // the thread that reads the pipe into output() and hands each line to `on_line`
  void start_reader(std::function<void(ChildProcess&, const std::string&)> on_line);

  pid_t pid_ = -1;
  // held while the child is reaped and while it is signalled: a signal never reaches a pid
  // the system has given to another process
  std::mutex reap_mutex_;
  std::atomic<bool> ended_{false};  // read by signal() from the reading thread
  int status_ = 0;
  struct Reader;
  std::unique_ptr<Reader> reader_;
};

/// What run_to_end and run_shell give: the exit status (-1 when killed by a signal) and
/// stdout and stderr together.
struct ChildResult {
  int rc = -1;
  std::string output;
};

/// Runs `args` to its end (see ChildProcess).
ChildResult run_to_end(std::vector<std::string> args, ChildOptions options = {});

/// Runs `command` with /bin/sh -c to its end, stdout and stderr together.
ChildResult run_shell(const std::string& command);

}  // namespace ropes::core
