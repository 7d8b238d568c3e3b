// Runs sheet scripts (docs/procman.md "Scripts"): actions in order; start/stop/restart
// without a wait go on at once; waits block until the targets reach a state, or until `wait ms`
// has passed; run_script runs another script to completion; starting a script aborts the active
// one. A core with time passed in: it never reads a clock and never sleeps, so tests drive it
// with made-up times and a fake host.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "thicket/procman/sheet.h"

namespace thicket::procman {

/// What a script acts on: the sheriff (or a fake in tests).
class ScriptHost {
 public:
  virtual ~ScriptHost() = default;
  /// Empty when `target` names something that exists, else why not ("no command 'x'").
  virtual std::string checkTarget(const SheetTarget& target) const = 0;
  /// Starts, stops or restarts every command of `target` (kind is kStart, kStop or kRestart).
  /// Empty on success, else why it could not.
  virtual std::string apply(SheetAction::Kind kind, const SheetTarget& target) = 0;
  /// Whether every command of `target` is in state `wait` (kNothing: always). When not, and
  /// `pending` is given, it gets the commands still waited for, with their status.
  virtual bool satisfied(const SheetTarget& target, SheetAction::WaitFor wait,
                         std::string* pending) const = 0;
};

/// "cmd 'x'", "group 'a/b'", "everything".
std::string describeTarget(const SheetTarget& target);

class ScriptRunner {
 public:
  enum class State {
    kIdle,       ///< no script was run yet
    kRunning,    ///< a script is active
    kCompleted,  ///< the last script ran every action
    kFailed,     ///< the last script stopped on an error or a timed-out wait
    kAborted,    ///< the last script was aborted (by another script, or abort())
  };

  /// `wait_timeout_us` bounds every status wait (start/stop/restart ... wait, and wait
  /// cmd|group ... status); 0 waits forever, as upstream procman does. `wait ms` is not bounded.
  /// `sheet` and `host` must outlive the runner.
  ScriptRunner(const Sheet& sheet, ScriptHost& host, int64_t wait_timeout_us = 0);

  /// Empty when script `name` can run: it exists, every command, group and script it names
  /// (through run_script too) exists, no script eventually runs itself, and waits are sane.
  std::string check(const std::string& name) const;

  /// Checks `name` and, when it can run, aborts the active script and starts `name` at `now_us`
  /// (executing its first actions at once). Returns check()'s error, and then changes nothing.
  std::string run(const std::string& name, int64_t now_us);

  /// Aborts the active script, if any (state kAborted, message `reason`).
  void abort(const std::string& reason);

  /// Executes actions until one must wait or the script ends. Call it whenever the host's state
  /// may have changed (after status reports) and when nextDeadline() has passed.
  void step(int64_t now_us);

  State state() const { return state_; }
  bool active() const { return state_ == State::kRunning; }
  /// The active or last script.
  const std::string& scriptName() const { return script_name_; }
  /// Why the last script failed or was aborted.
  const std::string& message() const { return message_; }
  /// One line about the active script and what it waits for, or empty when none is active.
  std::string describe(int64_t now_us) const;
  /// When step() must run next even without a state change: the end of a `wait ms`, or the
  /// timeout of a status wait.
  std::optional<int64_t> nextDeadline() const;
  /// What happened since the last call, one line per event ("script 'up': start cmd 'x'").
  std::vector<std::string> takeLog();

 private:
  struct Frame {
    const SheetScript* script;
    size_t next = 0;
  };
  enum class WaitKind { kNone, kMs, kStatus };
  struct Wait {
    WaitKind kind = WaitKind::kNone;
    int64_t since_us = 0;
    int64_t until_us = 0;  // kMs
    SheetTarget target;    // kStatus
    SheetAction::WaitFor wait_for = SheetAction::WaitFor::kNothing;
    int line = 0;
  };

  const SheetScript* findScript(const std::string& name) const;
  void checkScript(const SheetScript& script, std::vector<const SheetScript*>& path,
                   std::vector<std::string>& errors) const;
  void execute(const SheetAction& action, int64_t now_us);
  void fail(const std::string& message);
  void finish(State state, const std::string& message);
  std::string where(int line) const;

  const Sheet& sheet_;
  ScriptHost& host_;
  int64_t wait_timeout_us_;
  State state_ = State::kIdle;
  std::string script_name_;
  std::string message_;
  std::vector<Frame> frames_;
  Wait wait_;
  std::vector<std::string> log_;
};

const char* scriptStateName(ScriptRunner::State state);

}  // namespace thicket::procman
