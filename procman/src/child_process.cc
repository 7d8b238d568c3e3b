#include "child_process.h"

#include <fcntl.h>
#include <pty.h>
#include <signal.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <set>

#include "proc_stats.h"

namespace thicket::procman {
namespace {

std::string errorText(int error) {
  return std::strerror(error);
}

// The PATH of "NAME=value" strings, or the usual default.
std::string searchPath(const std::vector<std::string>& environment) {
  for (const std::string& entry : environment) {
    if (entry.rfind("PATH=", 0) == 0) return entry.substr(5);
  }
  return "/usr/local/bin:/usr/bin:/bin";
}

// The file to execute for `program`, or empty when no executable file of that name is found.
std::string resolveProgram(const std::string& program, const std::string& path) {
  if (program.find('/') != std::string::npos) return program;
  size_t begin = 0;
  while (begin <= path.size()) {
    size_t end = path.find(':', begin);
    if (end == std::string::npos) end = path.size();
    const std::string dir = end > begin ? path.substr(begin, end - begin) : ".";
    const std::string candidate = dir + "/" + program;
    struct stat info {};
    if (::stat(candidate.c_str(), &info) == 0 && S_ISREG(info.st_mode) &&
        ::access(candidate.c_str(), X_OK) == 0) {
      return candidate;
    }
    begin = end + 1;
  }
  return {};
}

std::vector<char*> pointers(std::vector<std::string>& strings) {
  std::vector<char*> result;
  for (std::string& s : strings) result.push_back(s.data());
  result.push_back(nullptr);
  return result;
}

void closeFrom(int first, int last, int open_max) {
  if (first > last) return;
  if (::close_range(static_cast<unsigned>(first), static_cast<unsigned>(last), 0) == 0) return;
  for (int fd = first; fd <= last && fd < open_max; ++fd) ::close(fd);
}

// In the child, between fork and exec: only async-signal-safe calls. Reports errno on
// `report_fd` (close-on-exec, so a successful exec closes it silently) and exits 127.
[[noreturn]] void execChild(int slave, int report_fd, int open_max, const char* path,
                            char* const argv[], char* const envp[]) {
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);
  struct sigaction default_action {};
  default_action.sa_handler = SIG_DFL;
  sigemptyset(&default_action.sa_mask);
  for (int signal = 1; signal < NSIG; ++signal) ::sigaction(signal, &default_action, nullptr);

  int error = 0;
  if (::setsid() < 0 || ::ioctl(slave, TIOCSCTTY, 0) < 0 || ::dup2(slave, STDIN_FILENO) < 0 ||
      ::dup2(slave, STDOUT_FILENO) < 0 || ::dup2(slave, STDERR_FILENO) < 0) {
    error = errno;
  }
  if (error == 0) {
    closeFrom(3, report_fd - 1, open_max);
    closeFrom(report_fd + 1, open_max > 0 ? open_max : 1 << 20, open_max);
    if (path[0] == '\0') {
      error = ENOENT;
    } else {
      ::execve(path, argv, envp);
      error = errno;
    }
  }
  ssize_t written;
  do {
    written = ::write(report_fd, &error, sizeof error);
  } while (written < 0 && errno == EINTR);
  ::_exit(127);
}

}  // namespace

Expected<StartedChild> startChild(const CommandLine& command, const Environment& base) {
  std::vector<std::string> environment = childEnvironment(base, command);
  std::vector<std::string> argv = command.argv;
  const std::string path = resolveProgram(argv.at(0), searchPath(environment));
  std::vector<char*> argv_pointers = pointers(argv);
  std::vector<char*> envp_pointers = pointers(environment);
  const int open_max = static_cast<int>(::sysconf(_SC_OPEN_MAX));

  int master = -1;
  int slave = -1;
  struct winsize size {};
  size.ws_row = 24;
  size.ws_col = 80;
  if (::openpty(&master, &slave, nullptr, nullptr, &size) != 0) {
    return unexpected("cannot open a pty: " + errorText(errno));
  }
  struct termios settings {};
  if (::tcgetattr(slave, &settings) == 0) {
    settings.c_oflag &= ~static_cast<tcflag_t>(OPOST);
    ::tcsetattr(slave, TCSANOW, &settings);
  }
  ::fcntl(master, F_SETFD, FD_CLOEXEC);
  ::fcntl(master, F_SETFL, ::fcntl(master, F_GETFL) | O_NONBLOCK);
  ::fcntl(slave, F_SETFD, FD_CLOEXEC);

  int report[2];
  if (::pipe2(report, O_CLOEXEC) != 0) {
    const int error = errno;
    ::close(master);
    ::close(slave);
    return unexpected("cannot create a pipe: " + errorText(error));
  }

  const pid_t pid = ::fork();
  if (pid == 0) {
    execChild(slave, report[1], open_max, path.c_str(), argv_pointers.data(), envp_pointers.data());
  }
  const int fork_error = errno;
  ::close(slave);
  ::close(report[1]);
  if (pid < 0) {
    ::close(report[0]);
    ::close(master);
    return unexpected("cannot fork: " + errorText(fork_error));
  }

  StartedChild child;
  child.pid = pid;
  child.pty_fd = master;
  int exec_errno = 0;
  ssize_t n;
  do {
    n = ::read(report[0], &exec_errno, sizeof exec_errno);
  } while (n < 0 && errno == EINTR);
  ::close(report[0]);
  if (n == static_cast<ssize_t>(sizeof exec_errno)) {
    child.exec_error = "cannot execute '" + command.argv[0] + "': " + errorText(exec_errno);
  }
  return child;
}

std::vector<ProcessEntry> ProcessTrees::members(int root, const std::vector<ProcessEntry>& table) {
  std::map<int, uint64_t>& known = remembered_[root];
  std::map<int, const ProcessEntry*> by_pid;
  for (const ProcessEntry& entry : table) by_pid[entry.pid] = &entry;
  std::vector<int> also;
  for (const auto& [pid, start] : known) {
    const auto it = by_pid.find(pid);
    if (it != by_pid.end() && it->second->start_ticks == start) also.push_back(pid);
  }
  std::vector<ProcessEntry> result;
  known.clear();
  for (const ProcessEntry* entry : processTree(table, root, ::getpid(), also)) {
    if (!entry->alive()) continue;
    result.push_back(*entry);
    known[entry->pid] = entry->start_ticks;
  }
  if (known.empty()) remembered_.erase(root);
  return result;
}

void ProcessTrees::signal(int root, int signal) {
  if (root <= 1) return;
  std::set<int> signalled;
  for (int look = 0; look < 3; ++look) {
    const std::vector<ProcessEntry> tree = members(root, readProcessTable());
    if (look == 0) {
      bool group_exists = false;
      for (const ProcessEntry& entry : tree) {
        if (entry.pgrp != root) continue;
        group_exists = true;
        signalled.insert(entry.pid);
      }
      if (group_exists) ::kill(-root, signal);
    }
    bool any = false;
    for (const ProcessEntry& entry : tree) {
      if (!signalled.insert(entry.pid).second) continue;
      ::kill(entry.pid, signal);
      any = true;
    }
    if (!any && look > 0) break;
  }
}

void ProcessTrees::prune(const std::vector<ProcessEntry>& table) {
  std::map<int, uint64_t> starts;
  for (const ProcessEntry& entry : table) {
    if (entry.alive()) starts[entry.pid] = entry.start_ticks;
  }
  for (auto root = remembered_.begin(); root != remembered_.end();) {
    std::erase_if(root->second, [&starts](const auto& member) {
      const auto it = starts.find(member.first);
      return it == starts.end() || it->second != member.second;
    });
    root = root->second.empty() ? remembered_.erase(root) : std::next(root);
  }
}

bool ProcessTrees::alive(int root) {
  return root > 1 && !members(root, readProcessTable()).empty();
}

}  // namespace thicket::procman
