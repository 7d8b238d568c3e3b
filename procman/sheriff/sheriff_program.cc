// SheriffProgram: polls LCM and stdin, runs the script, sends orders, prints status, quits.
#include "sheriff_program.h"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>
#include <procman_lcm/deputy_info_t.hpp>
#include <procman_lcm/discovery_t.hpp>
#include <procman_lcm/orders_t.hpp>
#include <procman_lcm/output_t.hpp>

#include "lone_ranger.h"
#include "output_printer.h"
#include "say.h"
#include "signals.h"
#include "thicket/common/loop.h"
#include "thicket/common/node.h"
#include "thicket/common/time.h"
#include "thicket/procman/script_runner.h"
#include "thicket/procman/sheriff.h"

namespace thicket::sheriff {

using namespace thicket::procman;

namespace {

constexpr int64_t kOrdersPeriodUs = 1'000'000;
constexpr int kMaxPollMs = 100;

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
    if (args_.lone_ranger &&
        !spawnLocalDeputies(sheriff_.sheet(), args_.lcm_url, local_deputies_)) {
      return 1;
    }

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
      checkLocalDeputies(local_deputies_);
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

int runSheriffProgram(const Args& args, Sheet sheet) {
  SheriffProgram program(args, std::move(sheet));
  return program.run();
}

}  // namespace thicket::sheriff
