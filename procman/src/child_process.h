// Starting a command on a new pty and signalling process trees: the system calls behind the
// deputy's ProcessControl.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "proc_stats.h"
#include "thicket/common/expected.h"
#include "thicket/procman/command_line.h"

namespace thicket::procman {

struct StartedChild {
  int pid = 0;
  int pty_fd = -1;         ///< the pty master (non-blocking, close-on-exec); the caller owns it
  std::string exec_error;  ///< set when execve failed: the child is exiting with 127
};

/// Forks `command` as the leader of a new session whose controlling terminal, stdin, stdout
/// and stderr are a new pty (output post-processing off, so "\n" stays "\n"). The program is
/// looked up in the PATH of the child's environment (`base` plus the command's assignments) and
/// executed without a shell; signal mask and dispositions are reset and no other descriptor is
/// inherited. Errors: no pty or no fork.
Expected<StartedChild> startChild(const CommandLine& command, const Environment& base);

/// The process trees of commands, with a memory: a process once seen in the tree of a root stays
/// a member while it lives (same pid and start time), even after it left the session and lost
/// the parent that linked it to the root. The deputy looks at each running tree every second and
/// at every signal, so only what escapes faster than that is missed.
class ProcessTrees {
 public:
  /// The live members of the tree of `root` in `table` (proc_stats.h processTree plus the
  /// remembered members), never the calling process. Remembers them; forgets `root` when none is
  /// left.
  std::vector<ProcessEntry> members(int root, const std::vector<ProcessEntry>& table);

  /// Sends `signal` to every member, each once, after signalling the process group `root` as a
  /// whole (which catches members forked meanwhile); a second look catches the rest.
  void signal(int root, int signal);

  /// Whether the tree has a live member.
  bool alive(int root);

  /// Forgets members that are gone from `table`, and roots left without members.
  void prune(const std::vector<ProcessEntry>& table);

 private:
  std::map<int, std::map<int, uint64_t>> remembered_;  // root → pid → start ticks
};

}  // namespace thicket::procman
