// Lone-ranger mode: starting thicket-deputy processes, watching them and stopping them.
#include "lone_ranger.h"

#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <thread>

#include "args.h"
#include "say.h"

namespace thicket::sheriff {

using namespace thicket::procman;

namespace {

std::string deputyExecutable() {
  char self[4096];
  const ssize_t n = ::readlink("/proc/self/exe", self, sizeof(self) - 1);
  if (n <= 0) return {};
  std::string path(self, static_cast<size_t>(n));
  const size_t slash = path.rfind('/');
  return (slash == std::string::npos ? std::string(".") : path.substr(0, slash)) +
         "/thicket-deputy";
}

pid_t spawnDeputy(const std::string& executable, const std::string& url, const std::string& id) {
  std::vector<std::string> words = {executable, "-u", url};
  if (!id.empty()) {
    words.push_back("-i");
    words.push_back(id);
  }
  std::vector<char*> argv;
  for (std::string& word : words) argv.push_back(word.data());
  argv.push_back(nullptr);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid != 0) return pid;
  // Child: dies with the sheriff, keeps out of the terminal's Ctrl-C (the sheriff stops the
  // commands in order first), and starts with the signals the sheriff blocked unblocked.
  ::prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (::getppid() != parent) ::_exit(1);
  ::setpgid(0, 0);
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  std::signal(SIGPIPE, SIG_DFL);
  sigset_t none;
  sigemptyset(&none);
  sigprocmask(SIG_SETMASK, &none, nullptr);
  const int null_fd = ::open("/dev/null", O_RDONLY);
  if (null_fd >= 0) {
    ::dup2(null_fd, 0);
    ::close(null_fd);
  }
  ::execv(executable.c_str(), argv.data());
  std::fprintf(stderr, "%s: cannot run %s: %s\n", kProgram, executable.c_str(),
               std::strerror(errno));
  ::_exit(127);
}

std::string describeWaitStatus(int status) {
  if (WIFEXITED(status)) return "exit status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return std::string("signal ") + ::strsignal(WTERMSIG(status));
  return "status " + std::to_string(status);
}

}  // namespace

bool spawnLocalDeputies(const Sheet& sheet, const std::string& lcm_url,
                        std::vector<LocalDeputy>& deputies) {
  const std::string executable = deputyExecutable();
  if (executable.empty() || ::access(executable.c_str(), X_OK) != 0) {
    std::fprintf(
        stderr, "%s: lone-ranger mode needs %s\n", kProgram,
        executable.empty() ? "thicket-deputy next to thicket-sheriff" : executable.c_str());
    return false;
  }
  std::vector<std::string> ids;
  for (const SheetCommand& command : sheet.commands) {
    if (std::find(ids.begin(), ids.end(), command.deputy) == ids.end()) {
      ids.push_back(command.deputy);
    }
  }
  if (ids.empty()) ids.push_back("");  // the deputy's default id
  for (const std::string& id : ids) {
    const pid_t pid = spawnDeputy(executable, lcm_url, id);
    if (pid < 0) {
      std::fprintf(stderr, "%s: cannot fork: %s\n", kProgram, std::strerror(errno));
      stopDeputies(deputies);
      return false;
    }
    deputies.push_back(LocalDeputy{id, pid});
    say("[sheriff] lone ranger: started local deputy" + (id.empty() ? "" : " '" + id + "'") +
        " (pid " + std::to_string(pid) + ")");
  }
  return true;
}

void checkLocalDeputies(std::vector<LocalDeputy>& deputies) {
  for (LocalDeputy& deputy : deputies) {
    if (deputy.pid <= 0) continue;
    int status = 0;
    if (::waitpid(deputy.pid, &status, WNOHANG) == deputy.pid) {
      say("[sheriff] local deputy" + (deputy.id.empty() ? "" : " '" + deputy.id + "'") +
          " exited (" + describeWaitStatus(status) + ")");
      deputy.pid = -1;
    }
  }
}

void stopDeputies(std::vector<LocalDeputy>& deputies) {
  for (LocalDeputy& deputy : deputies) {
    if (deputy.pid > 0) ::kill(deputy.pid, SIGTERM);
  }
  // The deputy stops its commands (SIGKILL after a second) and exits; give it a few seconds.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(4);
  for (LocalDeputy& deputy : deputies) {
    while (deputy.pid > 0) {
      int status = 0;
      const pid_t done = ::waitpid(deputy.pid, &status, WNOHANG);
      if (done == deputy.pid || (done < 0 && errno != EINTR)) {
        deputy.pid = -1;
      } else if (std::chrono::steady_clock::now() > deadline) {
        ::kill(deputy.pid, SIGKILL);
        ::waitpid(deputy.pid, &status, 0);
        deputy.pid = -1;
      } else {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    }
  }
}

}  // namespace thicket::sheriff
