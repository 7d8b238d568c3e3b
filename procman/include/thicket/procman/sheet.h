// Process sheets (.pmd): the grammar shared by libbot2 bot-procman and ashuang/procman
// (docs/procman.md), parsed into commands in groups and scripts of actions. Every error
// names the source, line and column ("sim.pmd:12:7: ..."), both 1-based; a column counts
// characters (UTF-8 code points, a tab is one).
//
// Command ids and script names are global to the sheet. A group that appears twice at the same
// path is one group (as in upstream procman): the later block adds its commands to it. Scripts may
// name commands, groups and scripts defined further down.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thicket/common/expected.h"

namespace thicket::procman {

/// One `cmd` block.
struct SheetCommand {
  std::string id;             ///< the quoted name after `cmd`; never contains '/'
  std::string group;          ///< path of the enclosing groups, "outer/inner"; "" at the top level
  std::string exec;           ///< the command line (attribute `exec`, required)
  std::string deputy;         ///< attribute `host` or `deputy` (required; both spellings accepted)
  bool auto_respawn = false;  ///< `auto_respawn` "true"/"yes" in any case
  int stop_signal = 2;        ///< `stop_signal`, default SIGINT
  int stop_time_allowed = 7;  ///< `stop_time_allowed` [s] before SIGKILL
  int line = 0;               ///< where the block starts, for messages

  bool operator==(const SheetCommand&) const = default;
};

/// What an action applies to.
struct SheetTarget {
  enum class Kind { kEverything, kCommand, kGroup };
  Kind kind = Kind::kEverything;
  std::string name;  ///< command id or group path; empty for everything

  bool operator==(const SheetTarget&) const = default;
};

/// One action of a script.
struct SheetAction {
  enum class Kind {
    kStart,       ///< start target [wait "running"|"stopped"]
    kStop,        ///< stop target [wait ...]
    kRestart,     ///< restart target [wait ...]
    kWaitMs,      ///< wait ms N
    kWaitStatus,  ///< wait cmd|group X status "running"|"stopped"
    kRunScript,   ///< run_script "name"
  };
  enum class WaitFor { kNothing, kRunning, kStopped };
  Kind kind = Kind::kStart;
  SheetTarget target;                ///< start/stop/restart and wait status (kCommand or kGroup)
  WaitFor wait = WaitFor::kNothing;  ///< start/stop/restart: the optional wait; wait status: S
  int64_t ms = 0;                    ///< wait ms
  std::string script;                ///< run_script
  int line = 0;                      ///< where the action's keyword is
  int column = 0;

  bool operator==(const SheetAction&) const = default;
};

struct SheetScript {
  std::string name;
  std::vector<SheetAction> actions;
  int line = 0;  ///< where the block starts

  bool operator==(const SheetScript&) const = default;
};

struct Sheet {
  std::vector<SheetCommand> commands;  ///< in sheet order
  std::vector<SheetScript> scripts;    ///< in sheet order
  /// Every group path that exists, outer groups before inner ones ("a", "a/b"), including
  /// empty groups.
  std::vector<std::string> groups;

  const SheetCommand* command(const std::string& id) const;
  const SheetScript* script(const std::string& name) const;
  /// Commands in `group` and its subgroups, in sheet order ("" is the whole sheet).
  std::vector<const SheetCommand*> commandsInGroup(const std::string& group) const;

  /// Member-wise, line and column fields included.
  bool operator==(const Sheet&) const = default;
};

/// Parses a sheet. Syntax errors, unknown or missing attributes, wrong value types, duplicate
/// command ids or script names, and scripts that name unknown commands, groups or scripts or
/// that eventually run themselves are errors "<source>:<line>:<column>: <what>". The position is
/// that of the offending token: the quoted name for unknown names and for the run_script that
/// closes a cycle, the `cmd` keyword for a missing required attribute, the end of the text for
/// an unexpected end of file. Only the first error is reported.
Expected<Sheet> parseSheet(const std::string& text, const std::string& source = "<sheet>");
/// Reads and parses a file ("<path>: cannot read" when it cannot be opened).
Expected<Sheet> loadSheet(const std::string& path);

/// The sheet written back in the canonical grammar (double-quoted strings escaped, `deputy`
/// attribute, attributes at their default left out, groups nested, scripts last), such that
/// parseSheet(formatSheet(s)) == s up to line and column fields. A group whose commands are not
/// contiguous in `sheet.commands` is written as several blocks, which parse back merged.
std::string formatSheet(const Sheet& sheet);

}  // namespace thicket::procman
