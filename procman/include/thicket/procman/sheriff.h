// The sheriff's core (docs/procman.md "Sheriff"): the desired state of every command of a
// sheet, merged with what deputies report on PM_INFO, turned into status strings and into one
// orders_t per deputy. No LCM, no clock: messages and times are passed in, so tests feed fake
// deputy reports. thicket-sheriff (procman/sheriff/main.cc) wraps it with LCM and a console.
//
// exit_code convention: cmd_status_t.exit_code is the status word of waitpid(2), as upstream
// procman's deputy reports it (its sheriff decodes it with WIFSIGNALED/WTERMSIG): 0 is a clean
// exit, WEXITSTATUS(code) an exit code, WTERMSIG(code) the signal that killed the process.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <procman_lcm/deputy_info_t.hpp>
#include <procman_lcm/orders_t.hpp>

#include "thicket/procman/script_runner.h"
#include "thicket/procman/sheet.h"

namespace thicket::procman {

enum class CommandStatus {
  kUnknown,       ///< no report about the command from its deputy (yet)
  kStarting,      ///< a new run is wanted and the process is not running
  kRestarting,    ///< a new run is wanted and the old process still runs
  kRunning,       ///< the wanted run is running
  kStopping,      ///< a stop is wanted and the process still runs
  kRemoving,      ///< not in the sheet (or, observed, not in the orders) but reported by its deputy
  kStoppedOk,     ///< not running; exit 0, or killed by SIGTERM/SIGINT/SIGKILL after a stop
  kStoppedError,  ///< not running otherwise
};

/// The exact upstream strings: "Unknown", "Starting (Command Sent)", "Restarting (Command Sent)",
/// "Running", "Stopping (Command Sent)", "Removing (Command Sent)", "Stopped (OK)",
/// "Stopped (Error)".
const char* statusName(CommandStatus status);
inline bool isStopped(CommandStatus status) {
  return status == CommandStatus::kStoppedOk || status == CommandStatus::kStoppedError;
}

/// A waitpid status in words: "0", "3" (exit code), "SIGKILL", "status 0x137f".
std::string describeExitCode(int32_t exit_code);

/// host:pid:utime, the upstream form.
std::string makeSheriffId();

struct SheriffOptions {
  std::string sheriff_id;  ///< empty: makeSheriffId()
  bool observer = false;   ///< send no orders; take desired state from other sheriffs' orders
  int64_t deputy_timeout_us = 3'000'000;    ///< silent longer than this: "not responding"
  int64_t conflict_timeout_us = 3'000'000;  ///< a conflict is shown this long after its orders
};

/// One command as the sheriff sees it.
struct CommandView {
  std::string deputy;
  std::string id;
  std::string group;
  std::string exec;
  bool auto_respawn = false;
  int stop_signal = 2;
  double stop_time_allowed = 7;
  bool in_sheet = false;  ///< false: only known from reports or other sheriffs' orders
  // desired
  int32_t desired_runid = 0;
  bool force_quit = false;
  // reported (valid when `reported`)
  bool reported = false;
  int32_t pid = 0;
  int32_t actual_runid = 0;
  int32_t exit_code = 0;
  double cpu_usage = 0;  ///< share of one CPU, [0, 1]
  int64_t mem_vsize_bytes = 0;
  int64_t mem_rss_bytes = 0;
  CommandStatus status = CommandStatus::kUnknown;

  /// "group/id", or "id" at the top level.
  std::string path() const { return group.empty() ? id : group + "/" + id; }
};

struct DeputyView {
  std::string id;
  bool in_sheet = false;  ///< the sheet names it
  bool heard = false;     ///< at least one deputy_info_t received
  bool responding = false;
  int64_t last_info_us = 0;  ///< when the last report arrived (the caller's clock)
  double cpu_load = 0;
  int64_t phys_mem_total_bytes = 0;
  int64_t phys_mem_free_bytes = 0;
  int ncmds_reported = 0;
};

/// Another sheriff giving orders to a deputy this one commands (or, observing, two sheriffs
/// giving orders to the same deputy).
struct Conflict {
  std::string deputy;
  std::string other_sheriff;
  int64_t last_seen_us = 0;
};

class Sheriff : public ScriptHost {
 public:
  explicit Sheriff(Sheet sheet, SheriffOptions options = {});

  const std::string& id() const { return options_.sheriff_id; }
  bool observer() const { return options_.observer; }
  const Sheet& sheet() const { return sheet_; }

  // ---- input ----
  /// A PM_INFO message received at `now_us`. Malformed content (no deputy id, duplicate or empty
  /// command ids, negative pids or run ids) is skipped with a note, never trusted. Commanding,
  /// reports of deputies the sheet does not name are ignored with a note; commands a sheet
  /// deputy reports that the sheet does not have are shown as Removing (our orders omit them).
  void handleInfo(const procman_lcm::deputy_info_t& info, int64_t now_us);
  /// A PM_ORDERS message received at `now_us`. Our own orders are ignored; another sheriff's
  /// orders for a deputy we command are a conflict; observing, they are the desired state.
  void handleOrders(const procman_lcm::orders_t& orders, int64_t now_us);

  // ---- operator actions (ScriptHost) ----
  std::string checkTarget(const SheetTarget& target) const override;
  /// start: a new run unless the command runs or is starting (clears force_quit); restart: a
  /// new run; stop: force_quit. Refused in observer mode. A command whose deputy was never heard
  /// from keeps the operation and applies it after adopting the deputy's first report.
  std::string apply(SheetAction::Kind kind, const SheetTarget& target) override;
  /// kRunning: every command is Running, or has stopped after running its current run id
  /// without being told to stop. kStopped: every command is Stopped (OK) or Stopped (Error).
  bool satisfied(const SheetTarget& target, SheetAction::WaitFor wait,
                 std::string* pending) const override;
  /// A console name: a command id, else a group path; empty with `error` set when neither or
  /// ambiguous.
  std::optional<SheetTarget> resolve(const std::string& name, std::string* error) const;

  /// Quitting: force_quit on every sheet command.
  void stopEverything();
  /// Every sheet command whose deputy responds and reports it has pid 0.
  bool everythingStopped(int64_t now_us) const;
  /// Operations are held for commands of deputies never heard from (see makeOrders).
  bool hasHeldOperations() const;
  /// The longest stop_time_allowed of the sheet [s].
  double maxStopTimeAllowed() const;

  // ---- output ----
  /// One orders_t per deputy of the sheet that was heard from (sheet order), stamped `utime`
  /// (wall clock); none in observer mode. Deputies never heard from get no orders, so that a
  /// restarted sheriff first adopts the run ids they report instead of restarting everything;
  /// deputies the sheet does not name get none, so that another sheriff's commands survive.
  std::vector<procman_lcm::orders_t> makeOrders(int64_t utime) const;
  /// True once after every change of the desired state, or a new deputy: send orders at once.
  bool takeOrdersChanged();

  /// Sheet commands in sheet order, then the others by deputy and id.
  std::vector<CommandView> commands() const;
  std::optional<CommandView> command(const std::string& deputy, const std::string& id) const;
  /// Deputies named in the sheet (sheet order), then (observing) the others heard of, by id.
  std::vector<DeputyView> deputies(int64_t now_us) const;
  /// Conflicts seen within the last conflict_timeout_us.
  std::vector<Conflict> conflicts(int64_t now_us) const;
  /// Notes for the operator since the last call (each distinct problem once).
  std::vector<std::string> takeNotes();

 private:
  struct Command {
    CommandView view;  // spec, desired and reported state; view.status is filled on output
    bool stop_requested = false;  // force_quit came from stop(), not from a completed run
    bool removing = false;  // reported but not wanted: not in the sheet, or not in seen orders
    std::vector<SheetAction::Kind> pending;  // applied when the deputy is first heard from
  };
  struct Deputy {
    DeputyView view;
    bool orders_seen = false;  // observing: another sheriff's orders arrived for it
    std::string last_orders_sheriff;
    int64_t last_orders_us = 0;
  };
  using Key = std::pair<std::string, std::string>;  // deputy, command id

  CommandStatus statusOf(const Command& command) const;
  bool completedCurrentRun(const Command& command) const;
  std::vector<Command*> targetCommands(const SheetTarget& target);
  std::vector<const Command*> targetCommands(const SheetTarget& target) const;
  void applyOne(Command& command, SheetAction::Kind kind);
  Deputy& deputy(const std::string& id);
  Command& addCommand(const std::string& deputy, const std::string& id, bool in_sheet);
  void removeCommand(const Key& key);
  bool deputyResponding(const Deputy& deputy, int64_t now_us) const;
  void note(const std::string& key, const std::string& text);
  void noteConflict(const std::string& deputy, const std::string& other, int64_t now_us);

  Sheet sheet_;
  SheriffOptions options_;
  std::vector<std::string> sheet_deputies_;  // in order of first mention
  std::map<std::string, Deputy> deputies_;
  std::map<Key, Command> commands_;
  std::vector<Key> sheet_order_;
  std::map<std::pair<std::string, std::string>, Conflict> conflicts_;
  bool orders_changed_ = false;
  std::set<std::string> noted_;
  std::vector<std::string> notes_;
};

/// The status table: one line per command (group/id, deputy, status, pid, run id, CPU %, RSS MB,
/// exit code), then deputies that are not responding or not heard from, then conflicts. Without
/// `usage` the CPU and RSS columns are left out: what the program compares to decide whether
/// something changed.
std::string formatStatusTable(const Sheriff& sheriff, int64_t now_us, bool usage = true);

/// One line typed on the console.
struct ConsoleCommand {
  enum class Kind { kNone, kAction, kRun, kStatus, kQuit, kHelp, kError };
  Kind kind = Kind::kNone;
  SheetAction::Kind action = SheetAction::Kind::kStart;  ///< kAction
  SheetTarget target;                                    ///< kAction
  std::string script;                                    ///< kRun
  std::string error;                                     ///< kError, in words
};
/// `start|stop|restart cmd NAME | group PATH | everything | NAME`, `run SCRIPT`, `status`,
/// `quit` (or `exit`), `help`; blank lines and `#` comments are kNone.
ConsoleCommand parseConsoleCommand(const std::string& line, const Sheriff& sheriff);
/// The console help text.
std::string consoleHelp();

}  // namespace thicket::procman
