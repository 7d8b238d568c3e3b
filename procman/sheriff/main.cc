// thicket-sheriff: runs a process sheet through procman_lcm deputies (docs/procman.md).
// Headless: prints a status table and the commands' output to stdout, takes commands on stdin
// (one per line; EOF does not quit), quits on `quit`, SIGINT or SIGTERM after stopping what it
// ordered. `thicket-sheriff --help` lists the options.
#include <fcntl.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <lcm/lcm-cpp.hpp>
#include <procman_lcm/deputy_info_t.hpp>
#include <procman_lcm/discovery_t.hpp>
#include <procman_lcm/orders_t.hpp>
#include <procman_lcm/output_t.hpp>

#include "thicket/common/cli.h"
#include "thicket/common/expected.h"
#include "thicket/common/loop.h"
#include "thicket/common/node.h"
#include "thicket/common/node_main.h"
#include "thicket/common/time.h"
#include "thicket/procman/printable.h"
#include "thicket/procman/script_runner.h"
#include "thicket/procman/sheet.h"
#include "thicket/procman/sheriff.h"

namespace {

using namespace thicket;
using namespace thicket::procman;

constexpr const char* kProgram = "thicket-sheriff";
constexpr int64_t kOrdersPeriodUs = 1'000'000;
constexpr int kMaxPollMs = 100;

struct Args {
  bool lone_ranger = false;
  bool observer = false;
  bool exit_after_script = false;
  std::string lcm_url;
  double wait_timeout_s = 0;
  double status_period_s = 1;
  std::string sheet_path;
  std::string script;
};

// Parses the command line into `args`; the exit status when main should return now.
std::optional<int> parseArgs(int argc, char** argv, Args& args) {
  CLI::App app(
      "thicket-sheriff: runs the commands of a procman sheet through thicket-deputy (or any\n"
      "procman_lcm deputy). Prints a status table and the commands' output; reads commands on\n"
      "stdin ('help').\n"
      "  thicket-sheriff [options] sheet.pmd [script]\n"
      "  thicket-sheriff -o [options] [sheet.pmd]",
      kProgram);
  app.footer(
      "Exit status: 0 on quit or a completed script, 1 on a failed script or a runtime error,\n"
      "2 on a bad command line, sheet or script name.");
  app.add_option("sheet", args.sheet_path, "the process sheet (.pmd)")->check(cli::nonEmpty());
  app.add_option("script", args.script, "a script of the sheet to run")->check(cli::nonEmpty());
  CLI::Option* lone_ranger =
      app.add_flag("-l,--lone-ranger", args.lone_ranger,
                   "spawn a local thicket-deputy for the sheet's deputy id (one per id when the "
                   "sheet names several); it dies with the sheriff")
          ->disable_flag_override();
  app.add_flag("-o,--observer", args.observer,
               "send no orders: only show what deputies and sheriffs say")
      ->disable_flag_override()
      ->excludes(lone_ranger);
  cli::addLcmUrl(app, args.lcm_url, true);
  app.add_flag("--exit-after-script", args.exit_after_script,
               "exit when the script ends: 0 if it completed, 1 if it failed or timed out "
               "(commands keep running on their deputies; with -l the local deputy stops them "
               "as it exits)")
      ->disable_flag_override();
  app.add_option("--wait-timeout", args.wait_timeout_s,
                 "fail a script whose status wait lasts more than S seconds (0: wait forever)")
      ->check(cli::number(0, 1e6))
      ->capture_default_str();
  app.add_option("--status-period", args.status_period_s,
                 "reprint the status table on changes at most every S seconds (0: only on "
                 "'status')")
      ->check(cli::number(0, 1e6))
      ->capture_default_str();
  if (auto exit_code = cli::parse(app, argc, argv)) return exit_code;
  std::string problem;
  if (args.sheet_path.empty() && !args.observer) {
    problem = "no sheet given";
  } else if (args.observer && !args.script.empty()) {
    problem = "an observer sends no orders, so it cannot run a script";
  } else if (args.exit_after_script && args.script.empty()) {
    problem = "--exit-after-script needs a script";
  }
  if (!problem.empty()) return cli::usageError(kProgram, problem);
  return std::nullopt;
}

int64_t wallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string wallClockText() {
  const std::time_t now = std::time(nullptr);
  std::tm local{};
  ::localtime_r(&now, &local);
  char text[32];
  std::strftime(text, sizeof(text), "%H:%M:%S", &local);
  return text;
}

void say(const std::string& text) {
  std::fputs(text.c_str(), stdout);
  if (text.empty() || text.back() != '\n') std::fputc('\n', stdout);
}

// ---- signals: blocked except inside ppoll(), so that none is lost between checks -------------

volatile std::sig_atomic_t g_signal_count = 0;
volatile std::sig_atomic_t g_last_signal = 0;

void onSignal(int signal) {
  g_last_signal = signal;
  g_signal_count = g_signal_count + 1;
}

sigset_t installSignals() {
  struct sigaction action {};
  action.sa_handler = onSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
  sigset_t blocked, previous;
  sigemptyset(&blocked);
  sigaddset(&blocked, SIGINT);
  sigaddset(&blocked, SIGTERM);
  sigprocmask(SIG_BLOCK, &blocked, &previous);
  sigdelset(&previous, SIGINT);
  sigdelset(&previous, SIGTERM);
  return previous;  // the mask to wait with
}

// ---- lone ranger --------------------------------------------------------------------------

struct LocalDeputy {
  std::string id;  // empty: the deputy's default (host name)
  pid_t pid = -1;
};

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

// ---- command output --------------------------------------------------------------------------

class OutputPrinter {
 public:
  explicit OutputPrinter(const Sheriff& sheriff) : sheriff_(sheriff) {}

  void handle(const procman_lcm::output_t& msg) {
    const size_t n = std::min({static_cast<size_t>(std::max<int16_t>(0, msg.num_commands)),
                               msg.command_ids.size(), msg.text.size()});
    for (size_t i = 0; i < n; ++i) {
      const std::string label = labelFor(msg.deputy_id, msg.command_ids[i]);
      std::string& partial = partial_[label];
      partial += msg.text[i];
      size_t start = 0;
      for (size_t newline; (newline = partial.find('\n', start)) != std::string::npos;) {
        emit(label, partial.substr(start, newline - start));
        start = newline + 1;
      }
      partial.erase(0, start);
      if (partial.size() > 4096) flush(label);
    }
    // Unfinished lines of commands nobody runs (junk on PM_OUTPUT) must not pile up.
    if (partial_.size() > kMaxPartialLines) flushAll();
  }

  /// Prints lines that have waited for their end.
  void flushAll() {
    for (auto& [label, partial] : partial_) flush(label);
    partial_.clear();
  }

 private:
  std::string labelFor(const std::string& deputy, const std::string& id) const {
    if (id.empty()) return "[deputy " + printableShort(deputy) + "]";
    if (sheriff_.command(deputy, id)) return "[" + id + "]";
    return "[" + printableShort(deputy) + "/" + printableShort(id) + "]";
  }
  void flush(const std::string& label) {
    std::string& partial = partial_[label];
    if (!partial.empty()) emit(label, partial);
    partial.clear();
  }
  // Controls are escaped: a command (or a stranger on the bus) printing ESC[2J must not clear
  // the operator's screen.
  static void emit(const std::string& label, std::string line) {
    while (!line.empty() && (line.back() == '\r' || line.back() == '\n')) line.pop_back();
    say(printable(label + " " + line));
  }

  static constexpr size_t kMaxPartialLines = 256;
  const Sheriff& sheriff_;
  std::map<std::string, std::string> partial_;
};

// ---- the program -------------------------------------------------------------------------

class SheriffProgram {
 public:
  SheriffProgram(const Args& args, Sheet sheet)
      : args_(args),
        sheriff_(std::move(sheet), SheriffOptions{"", args.observer}),
        runner_(sheriff_.sheet(), sheriff_, secondsToUtime(args.wait_timeout_s)),
        output_(sheriff_) {}

  int run() {
    if (!args_.script.empty()) {
      const std::string problem = runner_.check(args_.script);
      if (!problem.empty()) {
        std::fprintf(stderr, "%s: cannot run script: %s\n", kProgram, problem.c_str());
        return 2;
      }
    }
    const sigset_t wait_mask = installSignals();
    if (args_.lone_ranger && !spawnLocalDeputies()) return 1;

    lcm::LCM lcm(args_.lcm_url);
    if (!lcm.good()) {
      std::fprintf(stderr, "%s: cannot open LCM at '%s'\n", kProgram, args_.lcm_url.c_str());
      stopDeputies(local_deputies_);
      return 1;
    }
    Node node(kProgram, lcm);
    node_ = &node;
    node.subscribe<procman_lcm::deputy_info_t>(
        "PM_INFO",
        [this](const procman_lcm::deputy_info_t& info, const MessageInfo&) {
          sheriff_.handleInfo(info, steadyClockMicros());
        },
        200);
    node.subscribe<procman_lcm::orders_t>(
        "PM_ORDERS",
        [this](const procman_lcm::orders_t& orders, const MessageInfo&) {
          sheriff_.handleOrders(orders, steadyClockMicros());
        },
        200);
    node.subscribe<procman_lcm::output_t>(
        "PM_OUTPUT",
        [this](const procman_lcm::output_t& output, const MessageInfo&) { output_.handle(output); },
        500);

    procman_lcm::discovery_t discovery;
    discovery.utime = wallMicros();
    discovery.transmitter_id = sheriff_.id();
    discovery.nonce = 0;
    node.publish("PM_DISCOVER", discovery);

    say("[sheriff] " + sheriff_.id() + (args_.observer ? " observing" : " commanding") +
        (args_.sheet_path.empty() ? "" : " sheet " + args_.sheet_path) + " on " + args_.lcm_url +
        "; type 'help' for commands");
    printNotes();

    int64_t now = steadyClockMicros();
    next_orders_us_ = now;
    next_flush_us_ = now + kOrdersPeriodUs;
    if (!args_.script.empty()) {
      const std::string problem = runner_.run(args_.script, now);
      if (!problem.empty()) say("[sheriff] cannot run script: " + problem);
    }

    while (true) {
      now = steadyClockMicros();
      int timeout_ms = kMaxPollMs;
      if (auto deadline = runner_.nextDeadline()) {
        timeout_ms =
            static_cast<int>(std::clamp<int64_t>((*deadline - now + 999) / 1000, 0, kMaxPollMs));
      }
      pollfd fds[2] = {{lcm.getFileno(), POLLIN, 0}, {stdin_open_ ? 0 : -1, POLLIN, 0}};
      timespec timeout{timeout_ms / 1000, (timeout_ms % 1000) * 1'000'000L};
      const int ready = ::ppoll(fds, 2, &timeout, &wait_mask);
      if (ready < 0 && errno != EINTR) {
        say(std::string("[sheriff] poll failed: ") + std::strerror(errno));
        exit_status_ = 1;
        break;
      }
      if (ready > 0 && (fds[0].revents & (POLLIN | POLLERR | POLLHUP)) != 0) {
        for (int handled = 0; handled < 1000; ++handled) {
          const int status = lcm.handleTimeout(0);
          if (status < 0) {
            say("[sheriff] LCM failed while receiving; exiting");
            exit_status_ = 1;
            finished_ = true;
            break;
          }
          if (status == 0) break;
        }
      }
      if (ready > 0 && (fds[1].revents & (POLLIN | POLLHUP | POLLERR)) != 0) readStdin();

      if (g_signal_count >= 2) {
        say("[sheriff] second signal: exiting without waiting");
        exit_status_ = exit_status_ == 0 ? 1 : exit_status_;
        break;
      }
      if (g_signal_count == 1 && !quitting_) {
        beginQuit(std::string("signal ") + ::strsignal(g_last_signal));
      }
      tick();
      if (finished_) break;
    }

    if (!args_.observer) publishOrders();
    output_.flushAll();
    stopDeputies(local_deputies_);
    say("[sheriff] exiting with status " + std::to_string(exit_status_));
    std::fflush(stdout);
    node_ = nullptr;
    return exit_status_;
  }

 private:
  bool spawnLocalDeputies() {
    const std::string executable = deputyExecutable();
    if (executable.empty() || ::access(executable.c_str(), X_OK) != 0) {
      std::fprintf(
          stderr, "%s: lone-ranger mode needs %s\n", kProgram,
          executable.empty() ? "thicket-deputy next to thicket-sheriff" : executable.c_str());
      return false;
    }
    std::vector<std::string> ids;
    for (const SheetCommand& command : sheriff_.sheet().commands) {
      if (std::find(ids.begin(), ids.end(), command.deputy) == ids.end()) {
        ids.push_back(command.deputy);
      }
    }
    if (ids.empty()) ids.push_back("");  // the deputy's default id
    for (const std::string& id : ids) {
      const pid_t pid = spawnDeputy(executable, args_.lcm_url, id);
      if (pid < 0) {
        std::fprintf(stderr, "%s: cannot fork: %s\n", kProgram, std::strerror(errno));
        stopDeputies(local_deputies_);
        return false;
      }
      local_deputies_.push_back(LocalDeputy{id, pid});
      say("[sheriff] lone ranger: started local deputy" + (id.empty() ? "" : " '" + id + "'") +
          " (pid " + std::to_string(pid) + ")");
    }
    return true;
  }

  void readStdin() {
    char buffer[4096];
    const ssize_t n = ::read(0, buffer, sizeof(buffer));
    if (n < 0 && (errno == EINTR || errno == EAGAIN)) return;
    if (n <= 0) {
      stdin_open_ = false;
      if (!stdin_buffer_.empty()) handleLine(stdin_buffer_);
      stdin_buffer_.clear();
      say("[sheriff] stdin closed; still running (SIGINT or SIGTERM quits)");
      return;
    }
    stdin_buffer_.append(buffer, static_cast<size_t>(n));
    size_t start = 0;
    for (size_t newline; (newline = stdin_buffer_.find('\n', start)) != std::string::npos;) {
      handleLine(stdin_buffer_.substr(start, newline - start));
      start = newline + 1;
    }
    stdin_buffer_.erase(0, start);
    if (stdin_buffer_.size() > 65536) {
      say("[sheriff] input line too long: ignored");
      stdin_buffer_.clear();
    }
  }

  void handleLine(const std::string& line) {
    handleConsoleCommand(parseConsoleCommand(line, sheriff_));
    printNotes();
  }

  void handleConsoleCommand(const ConsoleCommand& command) {
    const int64_t now = steadyClockMicros();
    switch (command.kind) {
      case ConsoleCommand::Kind::kNone:
        return;
      case ConsoleCommand::Kind::kError:
        say("[sheriff] " + command.error);
        return;
      case ConsoleCommand::Kind::kHelp:
        say(consoleHelp());
        return;
      case ConsoleCommand::Kind::kStatus:
        printStatus(now, true);
        return;
      case ConsoleCommand::Kind::kQuit:
        beginQuit("quit requested");
        return;
      case ConsoleCommand::Kind::kRun: {
        if (args_.observer) {
          say("[sheriff] an observer cannot run scripts");
          return;
        }
        if (quitting_) {
          say("[sheriff] quitting: not running '" + command.script + "'");
          return;
        }
        const std::string problem = runner_.run(command.script, now);
        if (!problem.empty()) say("[sheriff] cannot run script: " + problem);
        return;
      }
      case ConsoleCommand::Kind::kAction: {
        if (quitting_) {
          say("[sheriff] quitting: ignored");
          return;
        }
        const char* verb = command.action == SheetAction::Kind::kStart  ? "start"
                           : command.action == SheetAction::Kind::kStop ? "stop"
                                                                        : "restart";
        const std::string problem = sheriff_.apply(command.action, command.target);
        if (!problem.empty()) {
          say("[sheriff] cannot " + std::string(verb) + ": " + problem);
        } else {
          say("[sheriff] " + std::string(verb) + " " + describeTarget(command.target));
        }
        return;
      }
    }
  }

  void beginQuit(const std::string& why) {
    if (quitting_) return;
    quitting_ = true;
    runner_.abort(why);
    if (args_.exit_after_script) exit_status_ = 1;  // the script did not complete
    if (args_.observer) {
      say("[sheriff] " + why + ": exiting");
      finished_ = true;
      return;
    }
    sheriff_.stopEverything();
    const double allowed = sheriff_.maxStopTimeAllowed() + 2.0;
    quit_deadline_us_ = steadyClockMicros() + secondsToUtime(allowed);
    say("[sheriff] " + why + ": stopping every command (waiting up to " +
        std::to_string(static_cast<int>(std::ceil(allowed))) + " s)");
  }

  void publishOrders() {
    for (const procman_lcm::orders_t& orders : sheriff_.makeOrders(wallMicros())) {
      node_->publish("PM_ORDERS", orders);
    }
  }

  void printNotes() {
    for (const std::string& text : sheriff_.takeNotes()) say("[sheriff] " + text);
    for (const std::string& text : runner_.takeLog()) say("[script] " + text);
  }

  void printStatus(int64_t now, bool requested) {
    std::string text = "---- status " + wallClockText() + " ----\n";
    text += formatStatusTable(sheriff_, now, true);
    const std::string script = runner_.describe(now);
    if (!script.empty()) text += script + "\n";
    if (requested && !runner_.active() && runner_.state() != ScriptRunner::State::kIdle) {
      text += "script '" + runner_.scriptName() + "' " + scriptStateName(runner_.state()) + "\n";
    }
    text += "----";
    say(text);
    last_printed_us_ = now;
  }

  void tick() {
    if (finished_) return;
    const int64_t now = steadyClockMicros();
    if (!args_.observer && !quitting_) runner_.step(now);
    printNotes();

    if (!args_.observer) {
      if (sheriff_.takeOrdersChanged() || now >= next_orders_us_) {
        publishOrders();
        if (now >= next_orders_us_) next_orders_us_ = now + kOrdersPeriodUs;
      }
    }
    if (now >= next_flush_us_) {
      output_.flushAll();
      next_flush_us_ = now + kOrdersPeriodUs;
      checkLocalDeputies();
    }

    if (args_.status_period_s > 0) {
      const std::string signature = formatStatusTable(sheriff_, now, false) +
                                    (runner_.active() ? "script " + runner_.scriptName() : "");
      if (signature != printed_signature_ &&
          now - last_printed_us_ >= secondsToUtime(args_.status_period_s)) {
        printStatus(now, false);
        printed_signature_ = signature;
      }
    }

    if (quitting_) {
      if (sheriff_.everythingStopped(now)) {
        say("[sheriff] every command is stopped");
        finished_ = true;
      } else if (now >= quit_deadline_us_) {
        say("[sheriff] gave up waiting for the commands to stop");
        finished_ = true;
      }
      return;
    }
    if (args_.exit_after_script && !runner_.active()) {
      if (runner_.state() == ScriptRunner::State::kCompleted) {
        // Orders for a deputy not heard from yet are held back (see Sheriff::makeOrders): do
        // not leave before they went out.
        if (sheriff_.hasHeldOperations()) {
          if (exit_wait_since_us_ == 0) {
            exit_wait_since_us_ = now;
            say("[sheriff] script completed; waiting for silent deputies before exiting");
          }
          if (now - exit_wait_since_us_ < 5 * kOrdersPeriodUs) return;
          say("[sheriff] some deputies never reported: their orders were not sent");
          exit_status_ = 1;
        } else {
          exit_status_ = 0;
        }
        finished_ = true;
      } else if (runner_.state() == ScriptRunner::State::kFailed) {
        say("[sheriff] the script failed: exiting");
        exit_status_ = 1;
        finished_ = true;
      }
    }
  }

  void checkLocalDeputies() {
    for (LocalDeputy& deputy : local_deputies_) {
      if (deputy.pid <= 0) continue;
      int status = 0;
      if (::waitpid(deputy.pid, &status, WNOHANG) == deputy.pid) {
        say("[sheriff] local deputy" + (deputy.id.empty() ? "" : " '" + deputy.id + "'") +
            " exited (" + describeWaitStatus(status) + ")");
        deputy.pid = -1;
      }
    }
  }

  const Args& args_;
  Sheriff sheriff_;
  ScriptRunner runner_;
  OutputPrinter output_;
  Node* node_ = nullptr;
  std::vector<LocalDeputy> local_deputies_;
  bool stdin_open_ = true;
  std::string stdin_buffer_;
  bool quitting_ = false;
  bool finished_ = false;
  int exit_status_ = 0;
  int64_t quit_deadline_us_ = 0;
  int64_t next_orders_us_ = 0;
  int64_t next_flush_us_ = 0;
  int64_t last_printed_us_ = INT64_MIN / 2;
  int64_t exit_wait_since_us_ = 0;
  std::string printed_signature_;
};

}  // namespace

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  Args args;
  if (auto exit_code = parseArgs(argc, argv, args)) return *exit_code;
  Sheet sheet;
  if (!args.sheet_path.empty()) {
    auto loaded = loadSheet(args.sheet_path);
    if (!loaded) {
      std::fprintf(stderr, "%s: %s\n", kProgram, loaded.error().c_str());
      return 2;
    }
    sheet = std::move(*loaded);
  }
  try {
    SheriffProgram program(args, std::move(sheet));
    return program.run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", kProgram, e.what());
    return 1;
  }
}
