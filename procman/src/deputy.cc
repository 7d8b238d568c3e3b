// The deputy's event loop (deputy.h runDeputy): one poll() over the LCM descriptor, a signalfd
// for SIGCHLD/SIGINT/SIGTERM and the pty masters of the commands, with every deadline taken from
// a monotonic clock. DeputyCore decides; this file does the I/O.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/signalfd.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <map>

#include <lcm/lcm-cpp.hpp>
#include <procman_lcm/deputy_info_t.hpp>
#include <procman_lcm/discovery_t.hpp>
#include <procman_lcm/orders_t.hpp>
#include <procman_lcm/output_t.hpp>

#include "child_process.h"
#include "proc_stats.h"
#include "thicket/common/node.h"
#include "thicket/procman/command_line.h"
#include "thicket/procman/deputy.h"

namespace thicket::procman {
namespace {

constexpr int64_t kInfoPeriodUs = 1'000'000;
constexpr int64_t kAnnouncePeriodUs = 100'000;
constexpr int64_t kShutdownPollUs = 50'000;  // how often a shutdown looks for leftover trees
constexpr size_t kReadChunk = 4096;
constexpr size_t kMaxReadPerWake = 16 * kReadChunk;  // per pty, so that none starves the others
constexpr size_t kMaxOutputEntries = 256;            // per output_t

// The deputy is a child subreaper: whatever its commands left behind (a grandchild forked while
// its tree was being signalled) is its own descendant. On exit it kills and reaps those, so that
// nothing outlives it.
void killRemainingDescendants() {
  const int self = ::getpid();
  for (int round = 0; round < 20; ++round) {
    const std::vector<ProcessEntry> table = readProcessTable();
    std::map<int, int> parent;
    for (const ProcessEntry& p : table) parent[p.pid] = p.ppid;
    bool any = false;
    for (const ProcessEntry& p : table) {
      int ancestor = p.ppid;
      for (int depth = 0; depth < 64 && ancestor > 1 && ancestor != self; ++depth) {
        const auto up = parent.find(ancestor);
        ancestor = up == parent.end() ? 0 : up->second;
      }
      if (ancestor != self || p.pid == self) continue;
      any = true;
      if (p.alive()) ::kill(p.pid, SIGKILL);
    }
    while (::waitpid(-1, nullptr, WNOHANG) > 0) {
    }
    if (!any) return;
    struct timespec pause = {0, 10'000'000};  // let the kernel deliver the kills
    ::nanosleep(&pause, nullptr);
  }
}

int64_t clockMicros(clockid_t clock) {
  timespec t{};
  ::clock_gettime(clock, &t);
  return static_cast<int64_t>(t.tv_sec) * 1'000'000 + t.tv_nsec / 1000;
}
int64_t monotonicNow() {
  return clockMicros(CLOCK_MONOTONIC);
}
int64_t wallNow() {
  return clockMicros(CLOCK_REALTIME);
}

// The deputy's own log: stderr, and appended to a file when one is given.
class Log {
 public:
  Log(std::string id, const std::string& path) : id_(std::move(id)) {
    if (path.empty()) return;
    fd_ = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) error_ = "cannot open log file '" + path + "': " + std::strerror(errno);
  }
  ~Log() {
    if (fd_ >= 0) ::close(fd_);
  }
  Log(const Log&) = delete;
  Log& operator=(const Log&) = delete;

  const std::string& error() const { return error_; }

  void line(std::string text) {
    while (!text.empty() && text.back() == '\n') text.pop_back();
    const int64_t now = wallNow();
    const std::time_t seconds = static_cast<std::time_t>(now / 1'000'000);
    std::tm local{};
    ::localtime_r(&seconds, &local);
    char stamp[40];
    const size_t n = std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%S", &local);
    std::snprintf(stamp + n, sizeof stamp - n, ".%03d", static_cast<int>(now / 1000 % 1000));
    const std::string full = std::string(stamp) + " thicket-deputy[" + id_ + "]: " + text + "\n";
    std::fputs(full.c_str(), stderr);
    if (fd_ >= 0 && ::write(fd_, full.data(), full.size()) < 0) {
      std::fprintf(stderr, "thicket-deputy: cannot write the log file: %s\n", std::strerror(errno));
    }
  }

 private:
  std::string id_;
  int fd_ = -1;
  std::string error_;
};

// A pty master of a command's process; open until every holder of its slave side is gone.
struct Pty {
  int fd = -1;
  int pid = 0;
  std::string command_id;
};

// ProcessControl on the real system: ptys, fork/exec, /proc trees.
class PtyProcessControl : public ProcessControl {
 public:
  PtyProcessControl(OutputBatcher& output, Log& log) : output_(output), log_(log) {}
  ~PtyProcessControl() override {
    for (const Pty& pty : ptys_) ::close(pty.fd);
  }

  Expected<int> start(const CommandSpec& spec) override {
    auto command = splitCommandLine(spec.exec, environment_);
    if (!command) return unexpected(command.error());
    auto child = startChild(*command, environment_);
    if (!child) return unexpected(child.error());
    ptys_.push_back({child->pty_fd, child->pid, spec.id});
    log_.line("[" + spec.id + "] started pid " + std::to_string(child->pid) + ": " + spec.exec);
    if (!child->exec_error.empty()) {
      log_.line("[" + spec.id + "] " + child->exec_error);
      output_.add(spec.id, "thicket-deputy: " + child->exec_error + "\n", monotonicNow());
    }
    return child->pid;
  }

  void signalTree(int root, int signal) override {
    log_.line("signal " + std::to_string(signal) + " to the process tree of " +
              std::to_string(root));
    trees_.signal(root, signal);
  }

  bool treeAlive(int root) override { return trees_.alive(root); }

  ProcessTrees& trees() { return trees_; }

  const std::vector<Pty>& ptys() const { return ptys_; }

  // Reads what the pty at `index` holds (bounded); closes it at its end. Returns false when
  // it was closed (the index then names the next pty).
  bool read(size_t index, int64_t now) {
    Pty& pty = ptys_[index];
    char buffer[kReadChunk];
    for (size_t total = 0; total < kMaxReadPerWake;) {
      const ssize_t n = ::read(pty.fd, buffer, sizeof buffer);
      if (n > 0) {
        output_.add(pty.command_id, std::string_view(buffer, static_cast<size_t>(n)), now);
        total += static_cast<size_t>(n);
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return true;
      // EIO (every slave descriptor closed) or end of file: nothing more will come.
      ::close(pty.fd);
      ptys_.erase(ptys_.begin() + static_cast<std::ptrdiff_t>(index));
      return false;
    }
    return true;
  }

  // Everything the process `pid` left in its pty, before its exit is reported.
  void drain(int pid, int64_t now) {
    for (size_t i = 0; i < ptys_.size(); ++i) {
      if (ptys_[i].pid == pid) {
        read(i, now);
        return;
      }
    }
  }

 private:
  OutputBatcher& output_;
  Log& log_;
  Environment environment_ = currentEnvironment();
  std::vector<Pty> ptys_;
  ProcessTrees trees_;
};

// CPU and memory of the host and of each command's process tree, sampled once a second.
class Usage {
 public:
  struct Command {
    float cpu = 0;  // share of one CPU over the last period
    int64_t vsize_bytes = 0;
    int64_t rss_bytes = 0;
  };

  void sample(const std::vector<DeputyCommand>& commands, ProcessTrees& trees, int64_t now) {
    if (auto times = parseCpuTimes(readTextFile("/proc/stat"))) {
      const uint64_t busy = times->busy - std::min(times->busy, cpu_.busy);
      const uint64_t total = times->total - std::min(times->total, cpu_.total);
      cpu_load_ = total > 0 && busy <= total ? static_cast<float>(busy) / total : 0.0f;
      cpu_ = *times;
    }
    memory_ = parseMemoryInfo(readTextFile("/proc/meminfo"));

    const std::vector<ProcessEntry> table = readProcessTable();
    trees.prune(table);
    const double ticks_per_second = static_cast<double>(::sysconf(_SC_CLK_TCK));
    const long page_size = ::sysconf(_SC_PAGESIZE);
    std::map<std::string, Sample> next;
    for (const DeputyCommand& command : commands) {
      if (command.pid == 0) continue;
      Sample sample;
      sample.pid = command.pid;
      sample.at = now;
      for (const ProcessEntry& entry : trees.members(command.pid, table)) {
        sample.ticks += entry.cpu_ticks;
        sample.usage.vsize_bytes += entry.vsize_bytes;
        sample.usage.rss_bytes += entry.rss_pages * page_size;
      }
      const auto previous = samples_.find(command.spec.id);
      if (previous != samples_.end() && previous->second.pid == command.pid &&
          now > previous->second.at && sample.ticks >= previous->second.ticks) {
        const double seconds = static_cast<double>(now - previous->second.at) * 1e-6;
        sample.usage.cpu =
            static_cast<float>(static_cast<double>(sample.ticks - previous->second.ticks) /
                               ticks_per_second / seconds);
      }
      next[command.spec.id] = sample;
    }
    samples_ = std::move(next);
  }

  Command of(const DeputyCommand& command) const {
    const auto it = samples_.find(command.spec.id);
    if (command.pid == 0 || it == samples_.end() || it->second.pid != command.pid) return {};
    return it->second.usage;
  }
  float cpuLoad() const { return cpu_load_; }
  const MemoryInfo& memory() const { return memory_; }

 private:
  struct Sample {
    int pid = 0;
    int64_t at = 0;
    uint64_t ticks = 0;
    Command usage;
  };
  CpuTimes cpu_;
  float cpu_load_ = 0;
  MemoryInfo memory_;
  std::map<std::string, Sample> samples_;
};

class Deputy {
 public:
  Deputy(const DeputyOptions& options, lcm::LCM& lcm, int signal_fd, Log& log)
      : options_(options),
        lcm_(lcm),
        node_("thicket-deputy", lcm),
        signal_fd_(signal_fd),
        log_(log),
        control_(output_, log),
        core_(options.id, control_, [this](const std::string& command_id, const std::string& text) {
          log_.line((command_id.empty() ? "" : "[" + command_id + "] ") + text);
          output_.add(command_id, text, monotonicNow());
        }) {
    node_.subscribe<procman_lcm::discovery_t>(
        "PM_DISCOVER",
        [this](const procman_lcm::discovery_t& msg, const MessageInfo&) { onDiscovery(msg); });
    node_.subscribe<procman_lcm::deputy_info_t>(
        "PM_INFO", [this](const procman_lcm::deputy_info_t& msg, const MessageInfo&) {
          if (discovering_ && msg.deputy_id == options_.id) {
            conflict_ = "another deputy with id '" + options_.id + "' is running";
          }
        });
    node_.subscribe<procman_lcm::orders_t>(
        "PM_ORDERS", [this](const procman_lcm::orders_t& msg, const MessageInfo&) {
          if (discovering_ || msg.deputy_id != options_.id) return;
          if (msg.sheriff_id != last_sheriff_) {
            log_.line("orders from sheriff '" + msg.sheriff_id + "'");
            last_sheriff_ = msg.sheriff_id;
          }
          core_.handleOrders(msg, wallNow(), monotonicNow());
        });
  }

  int run() {
    const int discovered = discover();
    if (discovered >= 0) return discovered;
    return serve();
  }

 private:
  // Announces the id and listens for a namesake. Returns an exit code, or -1 to go on.
  int discover() {
    const int64_t start = monotonicNow();
    const int64_t end = start + options_.discovery_us;
    int64_t next_announce = start;
    while (true) {
      const int64_t now = monotonicNow();
      if (!conflict_.empty()) {
        log_.line("ERROR: " + conflict_ + "; exiting to avoid conflicts");
        return kDeputyExitConflict;
      }
      if (now >= end) break;
      if (now >= next_announce) {
        procman_lcm::discovery_t msg;
        msg.utime = wallNow();
        msg.transmitter_id = options_.id;
        msg.nonce = ::getpid();
        node_.publish("PM_DISCOVER", msg);
        next_announce += kAnnouncePeriodUs;
      }
      pollfd fds[2] = {{lcm_.getFileno(), POLLIN, 0}, {signal_fd_, POLLIN, 0}};
      const int64_t wait = std::min(next_announce, end) - now;
      if (::poll(fds, 2, static_cast<int>((std::max<int64_t>(wait, 0) + 999) / 1000)) < 0 &&
          errno != EINTR) {
        log_.line(std::string("poll: ") + std::strerror(errno));
        return kDeputyExitFailure;
      }
      if (fds[0].revents & POLLIN) lcm_.handle();
      if (fds[1].revents & POLLIN) {
        readSignals(now);
        if (terminate_) return kDeputyExitOk;
      }
    }
    discovering_ = false;
    log_.line("deputy '" + options_.id + "' serving on " + options_.lcm_url + " (pid " +
              std::to_string(::getpid()) + ")");
    return -1;
  }

  int serve() {
    int64_t next_info = monotonicNow();
    int exit_code = kDeputyExitOk;
    while (true) {
      int64_t now = monotonicNow();
      if (terminate_ && !core_.shuttingDown()) {
        log_.line("stopping every command and exiting");
        core_.beginShutdown(now);
      }
      core_.handleTimers(now);
      flushOutput(now, false);
      if (now >= next_info) {
        usage_.sample(core_.commands(), control_.trees(), now);
        publishInfo();
        next_info = std::max(next_info + kInfoPeriodUs, now + 1);
      } else if (core_.takeChanged() || info_requested_) {
        publishInfo();
      }
      info_requested_ = false;
      if (core_.shuttingDown() && core_.shutdownComplete(now)) break;

      // Sleep until the next deadline or event.
      int64_t deadline = next_info;
      if (auto t = core_.nextTimer()) deadline = std::min(deadline, *t);
      if (auto t = output_.nextDue()) deadline = std::min(deadline, *t);
      if (core_.shuttingDown()) deadline = std::min(deadline, now + kShutdownPollUs);
      std::vector<pollfd> fds = {{lcm_.getFileno(), POLLIN, 0}, {signal_fd_, POLLIN, 0}};
      for (const Pty& pty : control_.ptys()) fds.push_back({pty.fd, POLLIN, 0});
      const int timeout_ms = static_cast<int>((std::max<int64_t>(deadline - now, 0) + 999) / 1000);
      if (::poll(fds.data(), fds.size(), timeout_ms) < 0) {
        if (errno == EINTR) continue;
        log_.line(std::string("poll: ") + std::strerror(errno));
        exit_code = kDeputyExitFailure;
        terminate_ = true;
        continue;
      }
      now = monotonicNow();

      // Output first, so that a process's last words go out before its exit is reported.
      const std::vector<Pty>& ptys = control_.ptys();
      for (size_t i = fds.size(); i-- > 2;) {
        if (fds[i].revents == 0) continue;
        for (size_t k = 0; k < ptys.size(); ++k) {
          if (ptys[k].fd == fds[i].fd) {
            control_.read(k, now);
            break;
          }
        }
      }
      if (fds[1].revents & POLLIN) readSignals(now);
      if (fds[0].revents & (POLLERR | POLLNVAL)) {
        if (!terminate_) log_.line("the LCM connection failed");
        exit_code = kDeputyExitFailure;
        terminate_ = true;
      } else if (fds[0].revents & POLLIN) {
        if (lcm_.handle() != 0 && !terminate_) {
          log_.line("LCM cannot receive");
          exit_code = kDeputyExitFailure;
          terminate_ = true;
        }
      }
    }
    for (size_t i = control_.ptys().size(); i-- > 0;) control_.read(i, monotonicNow());
    flushOutput(monotonicNow(), true);
    publishInfo();
    killRemainingDescendants();
    log_.line("exiting");
    return exit_code;
  }

  void onDiscovery(const procman_lcm::discovery_t& msg) {
    const bool self = msg.transmitter_id == options_.id && msg.nonce == ::getpid();
    if (self) return;
    if (msg.transmitter_id == options_.id && discovering_) {
      conflict_ = "another deputy with id '" + options_.id + "' (nonce " +
                  std::to_string(msg.nonce) + ") is announcing itself";
      return;
    }
    // Someone new (a sheriff, or a namesake deputy that must learn about us): report now.
    if (!discovering_) info_requested_ = true;
  }

  void readSignals(int64_t now) {
    signalfd_siginfo info{};
    bool child = false;
    while (::read(signal_fd_, &info, sizeof info) == static_cast<ssize_t>(sizeof info)) {
      if (info.ssi_signo == SIGCHLD) {
        child = true;
      } else if (!terminate_) {
        log_.line("received signal " + std::to_string(info.ssi_signo) + " (" +
                  ::strsignal(static_cast<int>(info.ssi_signo)) + ")");
        terminate_ = true;
      }
    }
    if (!child) return;
    int status = 0;
    pid_t pid;
    while ((pid = ::waitpid(-1, &status, WNOHANG)) > 0) {
      control_.drain(pid, now);
      const DeputyCommand* command = nullptr;
      for (const DeputyCommand& c : core_.commands()) {
        if (c.pid == pid) command = &c;
      }
      if (command != nullptr) {
        log_.line("[" + command->spec.id + "] pid " + std::to_string(pid) + " " +
                  (WIFSIGNALED(status) ? "killed by signal " + std::to_string(WTERMSIG(status))
                                       : "exited with " + std::to_string(WEXITSTATUS(status))));
      }
      core_.handleExit(pid, status, now);
    }
  }

  void flushOutput(int64_t now, bool all) {
    auto batches = output_.take(now, all);
    for (size_t first = 0; first < batches.size(); first += kMaxOutputEntries) {
      const size_t last = std::min(batches.size(), first + kMaxOutputEntries);
      procman_lcm::output_t msg;
      msg.utime = wallNow();
      msg.deputy_id = options_.id;
      msg.num_commands = static_cast<int16_t>(last - first);
      for (size_t i = first; i < last; ++i) {
        msg.command_ids.push_back(batches[i].first);
        msg.text.push_back(batches[i].second);
      }
      node_.publish("PM_OUTPUT", msg);
    }
  }

  void publishInfo() {
    procman_lcm::deputy_info_t info;
    info.utime = wallNow();
    info.deputy_id = options_.id;
    info.cpu_load = usage_.cpuLoad();
    info.phys_mem_total_bytes = usage_.memory().phys_total_bytes;
    info.phys_mem_free_bytes = usage_.memory().phys_free_bytes;
    info.swap_total_bytes = usage_.memory().swap_total_bytes;
    info.swap_free_bytes = usage_.memory().swap_free_bytes;
    for (const DeputyCommand& command : core_.commands()) {
      procman_lcm::cmd_status_t status;
      status.cmd.command_id = command.spec.id;
      status.cmd.exec_str = command.spec.exec;
      status.cmd.group = command.spec.group;
      status.cmd.auto_respawn = command.spec.auto_respawn;
      status.cmd.stop_signal = static_cast<int8_t>(command.spec.stop_signal);
      status.cmd.stop_time_allowed = command.spec.stop_time_allowed;
      status.pid = command.pid;
      status.actual_runid = command.actual_runid;
      status.exit_code = command.exit_status;
      const Usage::Command usage = usage_.of(command);
      status.cpu_usage = usage.cpu;
      status.mem_vsize_bytes = usage.vsize_bytes;
      status.mem_rss_bytes = usage.rss_bytes;
      info.cmds.push_back(status);
    }
    info.ncmds = static_cast<int32_t>(info.cmds.size());
    node_.publish("PM_INFO", info);
    core_.takeChanged();
  }

  const DeputyOptions& options_;
  lcm::LCM& lcm_;
  Node node_;
  int signal_fd_;
  Log& log_;
  OutputBatcher output_;
  PtyProcessControl control_;
  DeputyCore core_;
  Usage usage_;
  bool discovering_ = true;
  std::string conflict_;
  bool terminate_ = false;
  bool info_requested_ = false;
  std::string last_sheriff_;
};

// Descriptors 0-2 exist, so that no pty or pipe of ours lands on them.
void ensureStandardDescriptors() {
  for (int fd = 0; fd <= 2; ++fd) {
    if (::fcntl(fd, F_GETFD) < 0) ::open("/dev/null", O_RDWR);
  }
}

}  // namespace

int runDeputy(const DeputyOptions& options) {
  ensureStandardDescriptors();
  Log log(options.id, options.log_path);
  if (!log.error().empty()) {
    log.line("ERROR: " + log.error());
    return kDeputyExitFailure;
  }
  // Blocked before LCM exists, so that its threads inherit the mask and every one of these
  // signals arrives through the signalfd. SIGCHLD must not be ignored (that would reap for us).
  ::signal(SIGCHLD, SIG_DFL);
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGCHLD);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  if (::sigprocmask(SIG_BLOCK, &signals, nullptr) != 0) {
    log.line(std::string("ERROR: sigprocmask: ") + std::strerror(errno));
    return kDeputyExitFailure;
  }
  const int signal_fd = ::signalfd(-1, &signals, SFD_NONBLOCK | SFD_CLOEXEC);
  if (signal_fd < 0) {
    log.line(std::string("ERROR: signalfd: ") + std::strerror(errno));
    return kDeputyExitFailure;
  }
  // Orphans of our commands become our children, so that their trees can still be found.
  if (::prctl(PR_SET_CHILD_SUBREAPER, 1) != 0) {
    log.line(std::string("warning: cannot become a child subreaper: ") + std::strerror(errno));
  }

  int exit_code = kDeputyExitFailure;
  {
    lcm::LCM lcm(options.lcm_url);
    if (!lcm.good()) {
      log.line("ERROR: cannot open LCM at " + options.lcm_url);
    } else {
      Deputy deputy(options, lcm, signal_fd, log);
      exit_code = deputy.run();
    }
  }
  ::close(signal_fd);
  return exit_code;
}

}  // namespace thicket::procman
