// Shared by the procman tests that run the real programs (thicket-deputy, thicket-sheriff): a
// private network for LCM, child processes that cannot outlive the test, and waiting for a
// condition with a deadline instead of sleeping.
#pragma once

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "proc_stats.h"

extern char** environ;

namespace thicket::procman::test_support {

/// The LCM URL to use: the default one inside a fresh network namespace of this process (loopback
/// up, multicast routed to it), else, where namespaces are not allowed, a port of its own. The
/// TTL is 0 either way: nothing leaves the host.
inline std::string isolatedUrl() {
  if (::unshare(CLONE_NEWNET) == 0 &&
      std::system("ip link set lo up multicast on && ip route add 224.0.0.0/4 dev lo") == 0) {
    return "udpm://239.255.76.67:7667?ttl=0";
  }
  std::fprintf(stderr, "no private network namespace here; using a unique port\n");
  return "udpm://239.255.76.67:" + std::to_string(20000 + ::getpid() % 20000) + "?ttl=0";
}

inline int64_t wallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

/// `text` with every `from` replaced by `to`.
inline void replaceAll(std::string& text, const std::string& from, const std::string& to) {
  for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) {
    text.replace(at, from.size(), to);
  }
}

/// A whole file, or empty when it cannot be read.
inline std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// Alive: exists and is not a zombie.
inline bool processAlive(int pid) {
  if (pid <= 0) return false;
  const auto entry = parseProcessStat(readFile("/proc/" + std::to_string(pid) + "/stat"));
  return entry.has_value() && entry->alive();
}

/// Tries `condition` until it holds (true) or `seconds` have passed (false). Between tries it
/// calls `between` (which should block briefly, e.g. handling messages), else naps 10 ms: the
/// naps only pace the polling, nothing is timed by them.
inline bool waitUntil(const std::function<bool()>& condition, double seconds = 15.0,
                      const std::function<void()>& between = {}) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!condition()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    if (between) {
      between();
    } else {
      ::usleep(10'000);
    }
  }
  return true;
}

/// A file name in the test's temporary directory that no other process of this test uses.
inline std::string uniqueTempPath(const std::string& stem) {
  static int count = 0;
  return ::testing::TempDir() + "/" + stem + "_" + std::to_string(::getpid()) + "_" +
         std::to_string(++count) + ".txt";
}

/// A program run by the test: stdout and stderr go to a file, stdin is /dev/null or a pipe the
/// test writes to. The destructor sends SIGTERM, waits up to `term_grace_s` for the program to
/// exit (it may have things to stop), then SIGKILLs and reaps it.
class ChildProcess {
 public:
  /// `output_path` empty: a fresh file in the temporary directory.
  explicit ChildProcess(const std::vector<std::string>& argv, std::string output_path = "",
                        bool stdin_pipe = false)
      : output_path_(output_path.empty() ? uniqueTempPath("child") : std::move(output_path)) {
    int pipe_fds[2] = {-1, -1};
    if (stdin_pipe && ::pipe2(pipe_fds, O_CLOEXEC) != 0) {
      ADD_FAILURE() << "pipe2: " << std::strerror(errno);
      return;
    }
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    if (stdin_pipe) {
      posix_spawn_file_actions_adddup2(&actions, pipe_fds[0], STDIN_FILENO);
    } else {
      posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    }
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, output_path_.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    // The program starts with default dispositions and nothing blocked, whatever the test set.
    posix_spawnattr_t attributes;
    posix_spawnattr_init(&attributes);
    sigset_t defaults, none;
    sigemptyset(&defaults);
    for (int signal : {SIGPIPE, SIGINT, SIGTERM, SIGCHLD}) sigaddset(&defaults, signal);
    sigemptyset(&none);
    posix_spawnattr_setsigdefault(&attributes, &defaults);
    posix_spawnattr_setsigmask(&attributes, &none);
    posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);
    std::vector<char*> pointers;
    std::vector<std::string> words = argv;
    for (std::string& word : words) pointers.push_back(word.data());
    pointers.push_back(nullptr);
    const int error =
        ::posix_spawn(&pid_, pointers[0], &actions, &attributes, pointers.data(), environ);
    posix_spawnattr_destroy(&attributes);
    posix_spawn_file_actions_destroy(&actions);
    if (stdin_pipe) {
      ::close(pipe_fds[0]);
      stdin_fd_ = pipe_fds[1];
    }
    if (error != 0) {
      ADD_FAILURE() << "cannot run " << argv[0] << ": " << std::strerror(error);
      pid_ = -1;
    }
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  virtual ~ChildProcess() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGTERM);
      if (!waitExit(term_grace_s_)) {
        ::kill(pid_, SIGKILL);
        waitExit(30.0);
      }
    }
    closeStdin();
  }

  int pid() const { return pid_; }
  const std::string& outputPath() const { return output_path_; }
  /// Everything the program wrote so far.
  std::string output() const { return readFile(output_path_); }
  /// How long the destructor lets the program take after SIGTERM.
  void setTermGrace(double seconds) { term_grace_s_ = seconds; }

  /// Writes `text` to the program's stdin (a pipe); false when it cannot.
  bool write(const std::string& text) {
    size_t done = 0;
    while (stdin_fd_ >= 0 && done < text.size()) {
      const ssize_t n = ::write(stdin_fd_, text.data() + done, text.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return false;
      done += static_cast<size_t>(n);
    }
    return stdin_fd_ >= 0;
  }
  void closeStdin() {
    if (stdin_fd_ >= 0) ::close(stdin_fd_);
    stdin_fd_ = -1;
  }

  bool signal(int signal) { return pid_ > 0 && !exited_ && ::kill(pid_, signal) == 0; }

  /// Waits up to `seconds` for the program to exit; its waitpid() status is then status().
  bool waitExit(double seconds) {
    if (pid_ <= 0) return true;
    return waitUntil(
        [&] {
          if (exited_) return true;
          const pid_t r = ::waitpid(pid_, &status_, WNOHANG);
          if (r == pid_ || (r < 0 && errno == ECHILD)) exited_ = true;
          return exited_;
        },
        seconds);
  }
  bool exited() const { return exited_; }
  int status() const { return status_; }
  /// The exit code, or -1 when it did not exit normally (or has not exited).
  int exitCode() const { return exited_ && WIFEXITED(status_) ? WEXITSTATUS(status_) : -1; }

 private:
  std::string output_path_;
  pid_t pid_ = -1;
  int stdin_fd_ = -1;
  bool exited_ = false;
  int status_ = 0;
  double term_grace_s_ = 10.0;
};

/// Makes this process a child subreaper, so that orphans of the programs it runs become its
/// children instead of init's; when destroyed, SIGKILLs and reaps every descendant still there.
/// Keep it alive longer than every ChildProcess (it reaps them too).
class DescendantReaper {
 public:
  DescendantReaper() { ::prctl(PR_SET_CHILD_SUBREAPER, 1); }
  DescendantReaper(const DescendantReaper&) = delete;
  DescendantReaper& operator=(const DescendantReaper&) = delete;
  ~DescendantReaper() {
    waitUntil(
        [] {
          const std::vector<int> left = descendants();
          for (int pid : left) ::kill(pid, SIGKILL);
          while (::waitpid(-1, nullptr, WNOHANG) > 0) {
          }
          return left.empty();
        },
        10.0);
  }

  /// Every process below this one (zombies included).
  static std::vector<int> descendants() {
    const std::vector<ProcessEntry> table = readProcessTable();
    std::multimap<int, int> children;
    for (const ProcessEntry& entry : table) children.emplace(entry.ppid, entry.pid);
    std::vector<int> result;
    std::vector<int> todo = {::getpid()};
    while (!todo.empty()) {
      const int parent = todo.back();
      todo.pop_back();
      const auto [begin, end] = children.equal_range(parent);
      for (auto it = begin; it != end; ++it) {
        result.push_back(it->second);
        todo.push_back(it->second);
      }
    }
    return result;
  }
};

}  // namespace thicket::procman::test_support
