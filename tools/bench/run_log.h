// The run log (DIR/run_log.csv): one line per run or merge, with the machine it ran on.
#pragma once

#include <cstddef>
#include <ctime>
#include <string>
#include <vector>

namespace thicket::bench {

// The CPUs online on this machine.
int onlineCpus();

// The columns of run_log.csv.
const std::vector<std::string>& runLogColumns();

// Appends `lines` (complete CSV lines) to DIR/run_log.csv, with the header when it is new.
void appendRunLog(const std::string& dir, const std::string& lines);

// A run log line: when and how long the command ran, how, and on what machine.
std::string runLogLine(std::time_t started, double wall_s, const std::string& command, int jobs,
                       const std::string& shard, size_t run, size_t skipped);

// "thicket-bench <subcommand> <args>": how the run log names a command.
std::string commandLine(const std::string& subcommand, const std::vector<std::string>& args);

}  // namespace thicket::bench
