// What the deputy reads from /proc: the process table (for process trees, CPU time and memory
// per command) and the host's CPU load and memory. Parsers are separate from the reads so that
// tests can feed them text.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace thicket::procman {

/// One line of /proc/<pid>/stat, the fields the deputy uses.
struct ProcessEntry {
  int pid = 0;
  char state = '?';  ///< R, S, D, Z, ...
  int ppid = 0;
  int pgrp = 0;
  int session = 0;
  uint64_t cpu_ticks = 0;  ///< utime + stime + cutime + cstime, clock ticks
  int64_t vsize_bytes = 0;
  int64_t rss_pages = 0;
  uint64_t start_ticks = 0;  ///< start time after boot: tells a reused pid from the original

  bool alive() const { return state != 'Z' && state != 'X' && state != 'x'; }
};

/// Parses the text of /proc/<pid>/stat (the command name may hold spaces and parentheses).
std::optional<ProcessEntry> parseProcessStat(const std::string& text);

/// Every process in /proc that could be read.
std::vector<ProcessEntry> readProcessTable();

/// The tree of `root`: `root`, every process in its session or process group, the processes in
/// `also`, and all their descendants by parent pid; never pid 1 or `exclude` (the deputy
/// itself). Zombies included. Order: unspecified.
std::vector<const ProcessEntry*> processTree(const std::vector<ProcessEntry>& table, int root,
                                             int exclude, const std::vector<int>& also = {});

/// Busy and total jiffies of the "cpu" line of /proc/stat.
struct CpuTimes {
  uint64_t busy = 0;
  uint64_t total = 0;
};
std::optional<CpuTimes> parseCpuTimes(const std::string& proc_stat);

/// From /proc/meminfo. Free physical memory is MemAvailable (what can be used without
/// swapping), MemFree on kernels without it.
struct MemoryInfo {
  int64_t phys_total_bytes = 0;
  int64_t phys_free_bytes = 0;
  int64_t swap_total_bytes = 0;
  int64_t swap_free_bytes = 0;
};
MemoryInfo parseMemoryInfo(const std::string& meminfo);

/// A whole file, or empty when it cannot be read.
std::string readTextFile(const std::string& path);

}  // namespace thicket::procman
