// thicket's procman deputy: runs the commands a sheriff orders on this host and reports them,
// speaking the procman_lcm protocol (docs/procman.md).
//
// DeputyCore holds every decision — orders to starts and stops, run ids, respawn backoff, the
// SIGKILL deadline of a stop, shutdown — with time passed in and processes reached through
// ProcessControl, so that tests drive it without processes or clocks. runDeputy() is the event
// loop around it: LCM, ptys, signals, /proc.
//
// Conventions (upstream ashuang/procman where it has one):
//  - exit_code on the wire is the raw waitpid() status: WIFEXITED/WEXITSTATUS or
//    WIFSIGNALED/WTERMSIG decode it (exit 1 is 256, SIGINT is 2). A program that cannot be
//    executed exits with 127 (status 32512) and the reason is written to its output.
//  - When stopped (pid 0) and either force_quit is set or the run ids already match, the deputy
//    adopts desired_runid as actual_runid, so a sheriff sees "stopped" rather than a start that
//    never happens.
//  - A changed definition (exec, group, auto_respawn, stop_signal, stop_time_allowed) of a known
//    command id does not touch a running process; it applies from the next start (a run id
//    change, i.e. a restart, or a respawn).
//  - A restart (new run id while running) stops the process and starts it again as soon as it
//    has exited.
//  - An orders entry that is refused (empty or duplicate id, an exec that does not split, a
//    negative or non-finite stop_time_allowed, a stop_signal outside 1..64) leaves any command
//    of that id as it was; for a duplicate id the first entry applies. Each refusal is said once
//    on PM_OUTPUT (deputy text) until it changes or goes away.
//  - The process tree of a command is its process, everything in its session or process group,
//    and all their descendants (the deputy is a child subreaper, so orphans stay findable). When
//    the main process exits during a stop, what is left of the tree is still killed at the stop's
//    SIGKILL deadline.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <procman_lcm/orders_t.hpp>

#include "thicket/common/expected.h"

namespace thicket::procman {

/// A command as the sheriff defines it (procman_lcm cmd_t).
struct CommandSpec {
  std::string id;
  std::string exec;
  std::string group;
  bool auto_respawn = false;
  int stop_signal = 2;          ///< first signal of a stop
  float stop_time_allowed = 7;  ///< seconds between the stop signal and SIGKILL
  bool operator==(const CommandSpec&) const = default;
};

/// Respawn delays for a command that keeps dying: 10 ms, doubling up to 1 s while each run lasts
/// less than a second; a run of a second or more starts the sequence again.
class RespawnBackoff {
 public:
  static constexpr int64_t kMinDelayUs = 10'000;
  static constexpr int64_t kMaxDelayUs = 1'000'000;
  static constexpr int64_t kStableRunUs = 1'000'000;

  /// The delay before respawning a process that ran for `ran_us`; advances the sequence.
  int64_t next(int64_t ran_us);

 private:
  int64_t delay_us_ = kMinDelayUs;
};

/// What the deputy knows about one command.
struct DeputyCommand {
  CommandSpec spec;
  int32_t desired_runid = 0;  ///< from the latest orders
  bool force_quit = false;    ///< from the latest orders
  int32_t actual_runid = 0;
  int pid = 0;          ///< 0 when not running
  int exit_status = 0;  ///< the last waitpid() status (exit_code on the wire)
  int64_t started_at = 0;
  bool stop_sent = false;          ///< the stop signal went out; the process has not exited yet
  std::optional<int64_t> kill_at;  ///< SIGKILL deadline of a stop in progress
  std::optional<int64_t> respawn_at;
  bool removing = false;  ///< missing from the orders: removed once it has exited
  RespawnBackoff backoff;
};

/// The deputy's reach into the operating system.
class ProcessControl {
 public:
  virtual ~ProcessControl() = default;
  /// Starts `spec` in a new session; returns its pid, or why no process could be created. A
  /// program that cannot be executed still yields a pid (its process exits with 127).
  virtual Expected<int> start(const CommandSpec& spec) = 0;
  /// Sends `signal` to the process tree of `root` (see the header comment), also after `root`
  /// itself has exited.
  virtual void signalTree(int root, int signal) = 0;
  /// Whether any process of the tree of `root` is still alive (zombies do not count).
  virtual bool treeAlive(int root) = 0;
};

/// The decisions of a deputy. Times are microseconds of a monotonic clock, except the wall-clock
/// `wall_utime` that stale orders are judged by.
class DeputyCore {
 public:
  /// Deputy text for PM_OUTPUT: the command it concerns ("" for the deputy itself) and a line.
  using Say = std::function<void(const std::string& command_id, const std::string& text)>;

  static constexpr int64_t kMaxOrdersAgeUs = 60'000'000;
  static constexpr int64_t kShutdownGraceUs = 1'000'000;  ///< stop signal → SIGKILL on exit
  static constexpr int64_t kShutdownLimitUs = 3'000'000;  ///< exit even if something hangs on

  DeputyCore(std::string deputy_id, ProcessControl& control, Say say);

  const std::string& id() const { return id_; }

  /// Carries out orders: ignores other deputies' orders and orders older than kMaxOrdersAgeUs
  /// by `wall_utime` (saying so), refuses invalid entries, then starts, stops, restarts and
  /// removes commands.
  void handleOrders(const procman_lcm::orders_t& orders, int64_t wall_utime, int64_t now);
  /// A child was reaped with waitpid() `status`. Pids that are no command's (orphans the deputy
  /// adopted) are ignored.
  void handleExit(int pid, int status, int64_t now);
  /// Sends the SIGKILLs and starts the respawns that are due.
  void handleTimers(int64_t now);
  /// When handleTimers() next has something to do.
  std::optional<int64_t> nextTimer() const;

  /// Stops everything (each command's stop signal, SIGKILL after kShutdownGraceUs); no more
  /// starts or orders from now on.
  void beginShutdown(int64_t now);
  bool shuttingDown() const { return exiting_; }
  /// After beginShutdown(): true once every command has exited and nothing of their trees is
  /// left, or kShutdownLimitUs have passed.
  bool shutdownComplete(int64_t now);

  /// Every command, in the order it first appeared in orders.
  const std::vector<DeputyCommand>& commands() const { return commands_; }
  const DeputyCommand* command(const std::string& id) const;
  /// Whether the reported state changed since the last call (then info goes out at once).
  bool takeChanged();

 private:
  struct Leftover {  // what remains of a stopped tree after its main process exited
    int root;
    int64_t kill_at;
  };
  DeputyCommand* find(const std::string& id);
  void reconcile(DeputyCommand& command, int64_t now);
  void start(DeputyCommand& command, int32_t runid, int64_t now);
  void stop(DeputyCommand& command, int64_t now);
  void scheduleRespawn(DeputyCommand& command, int64_t now);
  std::string validate(const procman_lcm::cmd_desired_t& entry) const;

  std::string id_;
  ProcessControl& control_;
  Say say_;
  std::vector<DeputyCommand> commands_;
  std::vector<Leftover> leftovers_;
  std::map<std::string, std::string> refusals_;  // said once until they change
  bool changed_ = true;
  bool exiting_ = false;
  int64_t exit_deadline_ = 0;
};

/// Command output batched per command: a batch goes out when it holds kMaxBatchBytes or its
/// oldest byte is kMaxDelayUs old.
class OutputBatcher {
 public:
  static constexpr size_t kMaxBatchBytes = 4096;
  static constexpr int64_t kMaxDelayUs = 10'000;

  void add(const std::string& command_id, std::string_view text, int64_t now);
  /// When the next batch is due (now or earlier when one is full).
  std::optional<int64_t> nextDue() const;
  /// The batches due at `now` (every pending one when `all`), as (command id, text) with at
  /// most kMaxBatchBytes of text each, in the order the commands first wrote.
  std::vector<std::pair<std::string, std::string>> take(int64_t now, bool all = false);
  bool empty() const { return pending_.empty(); }

 private:
  struct Pending {
    std::string command_id;
    std::string text;
    int64_t first_at;
  };
  std::vector<Pending> pending_;
};

struct DeputyOptions {
  std::string id;        ///< the deputy id sheriffs address (main defaults it to the host name)
  std::string lcm_url;   ///< e.g. udpm://239.255.76.67:7667?ttl=0
  std::string log_path;  ///< the deputy's own log lines are appended here when not empty
  int64_t discovery_us = 500'000;  ///< how long to announce and listen for a namesake at start
};

/// Exit codes of runDeputy().
inline constexpr int kDeputyExitOk = 0;        ///< stopped by SIGINT/SIGTERM
inline constexpr int kDeputyExitFailure = 1;   ///< LCM or the operating system failed
inline constexpr int kDeputyExitConflict = 2;  ///< another live deputy has this id

/// Runs a deputy in this process until SIGINT or SIGTERM: blocks those and SIGCHLD for a
/// signalfd, makes the process a child subreaper, announces itself on PM_DISCOVER, then serves
/// PM_ORDERS and reports on PM_INFO and PM_OUTPUT.
int runDeputy(const DeputyOptions& options);

}  // namespace thicket::procman
