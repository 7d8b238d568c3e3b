// The run log: its columns, its lines (start, wall time, command, CPU model, cores), appending.
#include "run_log.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "csv.h"
#include "flags.h"
#include "trials.h"

namespace thicket::bench {

namespace fs = std::filesystem;

namespace {

std::string cpuModel() {
  std::ifstream cpuinfo("/proc/cpuinfo");
  for (std::string line; std::getline(cpuinfo, line);) {
    if (line.rfind("model name", 0) != 0) continue;
    const size_t colon = line.find(':');
    if (colon == std::string::npos) break;
    const size_t first = line.find_first_not_of(" \t", colon + 1);
    return first == std::string::npos ? "unknown" : line.substr(first);
  }
  return "unknown";
}

std::string utcNow(std::time_t when) {
  std::tm utc{};
  ::gmtime_r(&when, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

}  // namespace

int onlineCpus() {
  const long cpus = ::sysconf(_SC_NPROCESSORS_ONLN);
  return cpus > 0 ? static_cast<int>(cpus) : 1;
}

const std::vector<std::string>& runLogColumns() {
  static const std::vector<std::string> columns = {"started_utc",    "wall_s", "command",
                                                   "jobs",           "shard",  "trials_run",
                                                   "trials_skipped", "cpu",    "cores"};
  return columns;
}

void appendRunLog(const std::string& dir, const std::string& lines) {
  const std::string path = dir + "/run_log.csv";
  std::string text;
  if (fs::exists(path)) {
    const CsvText csv = parseCsv(readWholeFile(path));
    if (!csv.records.empty() && csv.records[0].cells != runLogColumns()) {
      throw std::runtime_error(path + " is not a run log of this thicket-bench (header '" +
                               joined(csv.records[0].cells, ",") + "')");
    }
    if (csv.records.empty()) text = csvLine(runLogColumns());
  } else {
    text = csvLine(runLogColumns());
  }
  std::ofstream file(path, std::ios::binary | std::ios::app);
  file << text << lines;
  file.close();
  if (!file) throw std::runtime_error("cannot write " + path);
}

std::string runLogLine(std::time_t started, double wall_s, const std::string& command, int jobs,
                       const std::string& shard, size_t run, size_t skipped) {
  return csvLine({utcNow(started), formatNumber("%.1f", wall_s), command, std::to_string(jobs),
                  shard, std::to_string(run), std::to_string(skipped), cpuModel(),
                  std::to_string(onlineCpus())});
}

std::string commandLine(const std::string& subcommand, const std::vector<std::string>& args) {
  std::string text = "thicket-bench " + subcommand;
  for (const std::string& arg : args) text += " " + arg;
  return text;
}

}  // namespace thicket::bench
