#include "ropes_core/child_process.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <mutex>
#include <stdexcept>
#include <system_error>
#include <thread>

extern char** environ;

namespace ropes::core {

struct ChildProcess::Reader {
  int fd = -1;
  // set once the child is reaped: what is still in the pipe is read, then the thread ends
  // (a grandchild that kept the pipe open would otherwise hold it until it ends too)
  std::atomic<bool> child_ended{false};
  std::thread thread;
  mutable std::mutex mutex;
  std::string text;
};

namespace {

// the name part of "NAME=value"
std::string name_of(const std::string& entry) {
  return entry.substr(0, entry.find('='));
}

}  // namespace

ChildProcess::ChildProcess(std::vector<std::string> args, ChildOptions options) {
  if (args.empty())
    throw std::invalid_argument("ChildProcess: no program to run");
  // everything the child needs is made before fork: between fork and exec it calls only
  // async-signal-safe functions (this process may have other threads)
  std::vector<char*> argv;
  for (std::string& a : args)
    argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<std::string> env;
  for (char** e = environ; *e != nullptr; ++e) {
    bool replaced = false;
    for (const std::string& over : options.environment)
      replaced = replaced || name_of(over) == name_of(*e);
    if (!replaced)
      env.emplace_back(*e);
  }
  env.insert(env.end(), options.environment.begin(), options.environment.end());
  std::vector<char*> envp;
  for (std::string& e : env)
    envp.push_back(e.data());
  envp.push_back(nullptr);

  int out = -1, pipe_fds[2] = {-1, -1};
  if (options.log.empty()) {
    if (::pipe2(pipe_fds, O_CLOEXEC) != 0)
      throw std::system_error(errno, std::generic_category(), "ChildProcess: pipe");
    out = pipe_fds[1];
  } else {
    out = ::open(options.log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (out < 0)
      throw std::system_error(errno, std::generic_category(),
                              "ChildProcess: " + options.log.string());
  }
  // exec's outcome: closed on success (O_CLOEXEC), errno written on failure
  int exec_fds[2];
  if (::pipe2(exec_fds, O_CLOEXEC) != 0) {
    const int e = errno;
    ::close(out);
    if (pipe_fds[0] >= 0)
      ::close(pipe_fds[0]);
    throw std::system_error(e, std::generic_category(), "ChildProcess: pipe");
  }
  const rlimit limit{options.file_size_limit, options.file_size_limit};
  pid_ = ::fork();
  if (pid_ == 0) {
    ::dup2(out, 1);
    ::dup2(out, 2);
    if (options.file_size_limit > 0) {
      ::setrlimit(RLIMIT_FSIZE, &limit);
      ::signal(SIGXFSZ, SIG_IGN);
    }
    ::execve(argv[0], argv.data(), envp.data());
    const int e = errno;
    [[maybe_unused]] const ssize_t n = ::write(exec_fds[1], &e, sizeof e);
    ::_exit(127);
  }
  const int fork_errno = errno;
  ::close(exec_fds[1]);
  ::close(out);
  if (pid_ < 0) {
    ::close(exec_fds[0]);
    if (pipe_fds[0] >= 0)
      ::close(pipe_fds[0]);
    throw std::system_error(fork_errno, std::generic_category(), "ChildProcess: fork");
  }
  int exec_errno = 0;
  ssize_t n;
  do
    n = ::read(exec_fds[0], &exec_errno, sizeof exec_errno);
  while (n < 0 && errno == EINTR);
  ::close(exec_fds[0]);
  if (n > 0) {
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
    if (pipe_fds[0] >= 0)
      ::close(pipe_fds[0]);
    throw std::system_error(exec_errno, std::generic_category(),
                            "ChildProcess: cannot run " + args[0]);
  }
  if (pipe_fds[0] >= 0) {
    try {
      reader_ = std::make_unique<Reader>();
    } catch (...) {
      ::close(pipe_fds[0]);
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
      throw;
    }
    reader_->fd = pipe_fds[0];
    try {
      start_reader(std::move(options.on_line));
    } catch (...) {
      ::close(pipe_fds[0]);
      reader_.reset();
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
      throw;
    }
  }
}

void ChildProcess::start_reader(std::function<void(ChildProcess&, const std::string&)> on_line) {
  reader_->thread = std::thread([this, on_line = std::move(on_line)] {
    std::string line;
    char buf[4096];
    ssize_t got;
    while (true) {
      pollfd ready{reader_->fd, POLLIN, 0};
      const int polled = ::poll(&ready, 1, 20);
      if (polled == 0) {
        if (reader_->child_ended)
          break;
        continue;
      }
      if (polled < 0 && errno == EINTR)
        continue;
      got = polled < 0 ? -1 : ::read(reader_->fd, buf, sizeof buf);
      if (got == 0)
        break;
      if (got < 0) {
        if (errno == EINTR)
          continue;
        break;
      }
      {
        const std::lock_guard<std::mutex> lock(reader_->mutex);
        reader_->text.append(buf, static_cast<std::size_t>(got));
      }
      if (!on_line)
        continue;
      for (ssize_t i = 0; i < got; ++i) {
        line += buf[i];
        if (buf[i] == '\n') {
          on_line(*this, line);
          line.clear();
        }
      }
    }
    if (on_line && !line.empty())
      on_line(*this, line);
  });
}

ChildProcess::~ChildProcess() {
  if (!ended_ && pid_ > 0) {
    {
      const std::lock_guard<std::mutex> lock(reap_mutex_);
      ::kill(pid_, SIGKILL);
      int status = 0;
      while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
      }
      ended_ = true;
    }
  }
  join_reader();
}

void ChildProcess::join_reader() {
  if (reader_ && reader_->thread.joinable()) {
    reader_->child_ended = true;
    reader_->thread.join();
    ::close(reader_->fd);
  }
}

void ChildProcess::reap() {
  {
    const std::lock_guard<std::mutex> lock(reap_mutex_);
    int status = 0;
    pid_t r;
    do
      r = ::waitpid(pid_, &status, 0);
    while (r < 0 && errno == EINTR);
    if (r != pid_)
      throw std::system_error(errno, std::generic_category(), "ChildProcess: waitpid");
    status_ = status;
    ended_ = true;
  }
  join_reader();
}

namespace {

// waits (up to blocking forever) until the child has ended, without reaping it: true when it
// has; a child that cannot be waited for is an error
bool has_ended(pid_t pid, bool block) {
  siginfo_t info{};
  int r;
  do
    r = ::waitid(P_PID, static_cast<id_t>(pid), &info, WEXITED | WNOWAIT | (block ? 0 : WNOHANG));
  while (r < 0 && errno == EINTR);
  if (r != 0)
    throw std::system_error(errno, std::generic_category(), "ChildProcess: waitid");
  return info.si_pid == pid;
}

int exit_code(int status) {
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

bool ChildProcess::running() {
  if (ended_ || pid_ <= 0)
    return false;
  if (has_ended(pid_, false))
    reap();
  return !ended_;
}

void ChildProcess::signal(int sig) {
  const std::lock_guard<std::mutex> lock(reap_mutex_);
  if (!ended_ && pid_ > 0)
    ::kill(pid_, sig);
}

int ChildProcess::wait(std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (running() && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  return running() ? -1 : exit_code(status_);
}

int ChildProcess::wait() {
  if (!ended_ && pid_ > 0) {
    has_ended(pid_, true);
    reap();
  }
  return exit_code(status_);
}

std::string ChildProcess::output() const {
  if (!reader_)
    return "";
  const std::lock_guard<std::mutex> lock(reader_->mutex);
  return reader_->text;
}

ChildResult run_to_end(std::vector<std::string> args, ChildOptions options) {
  ChildProcess child(std::move(args), std::move(options));
  ChildResult r;
  r.rc = child.wait();
  r.output = child.output();
  return r;
}

ChildResult run_shell(const std::string& command) {
  return run_to_end({"/bin/sh", "-c", command});
}

}  // namespace ropes::core
