// ChildProcess: the one way the workspace's tests run the executables. Exercised on /bin/sh,
// whose behaviour POSIX fixes: output through the pipe and into a log file, the exit status,
// a kill decided line by line, the environment, a file-size limit, and a child that cannot
// start or outlives its object.
#include "ropes_core/child_process.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>

namespace ropes::core {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

fs::path scratch(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("ropes_child_process_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
}

std::string text_of(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(ChildProcess, GivesTheExitStatusAndStdoutAndStderrTogether) {
  const ChildResult r = run_to_end({"/bin/sh", "-c", "echo out; echo err >&2; exit 3"});
  EXPECT_EQ(r.rc, 3);
  EXPECT_EQ(r.output, "out\nerr\n");
  EXPECT_EQ(run_shell("printf 'a b'").output, "a b");
  EXPECT_EQ(run_shell("exit 0").rc, 0);
}

TEST(ChildProcess, WritesIntoALogFileWhenGivenOne) {
  const fs::path log = scratch("log.txt");
  std::ofstream(log) << "what was there before\n";
  ChildProcess child({"/bin/sh", "-c", "echo to the log; echo and its errors >&2"},
                     ChildOptions::to_log(log));
  EXPECT_EQ(child.wait(), 0);
  EXPECT_EQ(text_of(log), "to the log\nand its errors\n");
  EXPECT_EQ(child.output(), "");
}

TEST(ChildProcess, AKillDecidedLineByLineEndsIt) {
  std::vector<std::string> lines;
  ChildOptions options;
  options.on_line = [&](ChildProcess& child, const std::string& line) {
    lines.push_back(line);
    if (line == "two\n")
      child.signal(SIGKILL);
  };
  ChildProcess child({"/bin/sh", "-c", "echo one; echo two; sleep 30; echo three"}, options);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(child.wait(), -1);
  EXPECT_LT(std::chrono::steady_clock::now() - start, 20s);
  EXPECT_TRUE(WIFSIGNALED(child.status()));
  EXPECT_EQ(WTERMSIG(child.status()), SIGKILL);
  EXPECT_EQ(child.output(), "one\ntwo\n");
  EXPECT_EQ(lines, (std::vector<std::string>{"one\n", "two\n"}));
}

TEST(ChildProcess, SetsTheEnvironmentOverTheParents) {
  ::setenv("ROPES_CHILD_PROCESS_TEST", "parent", 1);
  EXPECT_EQ(run_shell("echo $ROPES_CHILD_PROCESS_TEST").output, "parent\n");
  ChildOptions options;
  options.environment = {"ROPES_CHILD_PROCESS_TEST=child", "ROPES_CHILD_PROCESS_OTHER=2"};
  EXPECT_EQ(
      run_to_end({"/bin/sh", "-c", "echo $ROPES_CHILD_PROCESS_TEST $ROPES_CHILD_PROCESS_OTHER"},
                 options)
          .output,
      "child 2\n");
  ::unsetenv("ROPES_CHILD_PROCESS_TEST");
}

TEST(ChildProcess, AFileSizeLimitMakesAWriteFailInsteadOfKilling) {
  const fs::path file = scratch("big.bin");
  ChildOptions options;
  options.file_size_limit = 1000;
  const ChildResult r = run_to_end(
      {"/bin/sh", "-c", "head -c 100000 /dev/zero > " + file.string() + "; echo head $?"}, options);
  EXPECT_EQ(r.rc, 0) << r.output;
  EXPECT_NE(r.output.find("head 1"), std::string::npos) << r.output;
  EXPECT_EQ(fs::file_size(file), 1000u);
}

TEST(ChildProcess, AProgramThatCannotStartIsAnErrorNamingIt) {
  const fs::path missing = scratch("no-such-program");
  try {
    ChildProcess child({missing.string()});
    ADD_FAILURE() << "started " << missing;
  } catch (const std::system_error& e) {
    EXPECT_EQ(e.code().value(), ENOENT);
    EXPECT_NE(std::string(e.what()).find("cannot run " + missing.string()), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(ChildProcess({}), std::invalid_argument);
}

TEST(ChildProcess, AChildThatCannotBeWaitedForIsAnErrorNotAnExitStatus) {
  // with SIGCHLD ignored the system reaps children itself: no status to report
  struct sigaction ignore {
  }, before{};
  ignore.sa_handler = SIG_IGN;
  ::sigaction(SIGCHLD, &ignore, &before);
  {
    ChildProcess child({"/bin/sh", "-c", "exit 3"});
    EXPECT_THROW(child.wait(), std::system_error);
  }
  ::sigaction(SIGCHLD, &before, nullptr);
  EXPECT_EQ(run_shell("exit 3").rc, 3);
}

TEST(ChildProcess, AChildStillRunningIsKilledWithItsObject) {
  pid_t pid = -1;
  {
    ChildProcess child({"/bin/sleep", "30"});
    pid = child.pid();
    EXPECT_TRUE(child.running());
    EXPECT_EQ(child.wait(50ms), -1);  // still running
  }
  EXPECT_EQ(::kill(pid, 0), -1);  // gone, and reaped
  EXPECT_EQ(errno, ESRCH);
}

}  // namespace
}  // namespace ropes::core
