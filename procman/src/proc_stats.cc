#include "proc_stats.h"

#include <dirent.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace thicket::procman {

std::optional<ProcessEntry> parseProcessStat(const std::string& text) {
  const size_t open = text.find('(');
  const size_t close = text.rfind(')');
  if (open == std::string::npos || close == std::string::npos || close < open) return {};
  ProcessEntry entry;
  char* end = nullptr;
  entry.pid = static_cast<int>(std::strtol(text.c_str(), &end, 10));
  if (end == text.c_str() || entry.pid <= 0) return {};

  // Fields after the command name, from field 3 (state) on.
  std::istringstream fields(text.substr(close + 1));
  std::vector<std::string> f;
  for (std::string field; fields >> field;) f.push_back(field);
  if (f.size() < 22 || f[0].size() != 1) return {};
  auto number = [&f](size_t i) { return std::strtoll(f[i].c_str(), nullptr, 10); };
  entry.state = f[0][0];
  entry.ppid = static_cast<int>(number(1));
  entry.pgrp = static_cast<int>(number(2));
  entry.session = static_cast<int>(number(3));
  entry.cpu_ticks = static_cast<uint64_t>(number(11) + number(12) + number(13) + number(14));
  entry.vsize_bytes = number(20);
  entry.rss_pages = number(21);
  entry.start_ticks = static_cast<uint64_t>(number(19));
  return entry;
}

std::string readTextFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return {};
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::vector<ProcessEntry> readProcessTable() {
  std::vector<ProcessEntry> table;
  DIR* proc = ::opendir("/proc");
  if (proc == nullptr) return table;
  while (const dirent* entry = ::readdir(proc)) {
    const char* name = entry->d_name;
    if (name[0] < '1' || name[0] > '9') continue;
    // A process that exits meanwhile leaves an empty read: skipped.
    if (auto parsed = parseProcessStat(readTextFile(std::string("/proc/") + name + "/stat"))) {
      table.push_back(*parsed);
    }
  }
  ::closedir(proc);
  return table;
}

std::vector<const ProcessEntry*> processTree(const std::vector<ProcessEntry>& table, int root,
                                             int exclude, const std::vector<int>& also) {
  const std::set<int> extra(also.begin(), also.end());
  std::multimap<int, const ProcessEntry*> children;
  std::vector<const ProcessEntry*> pending;
  for (const ProcessEntry& entry : table) {
    children.emplace(entry.ppid, &entry);
    if (entry.pid == root || entry.session == root || entry.pgrp == root ||
        extra.count(entry.pid) != 0) {
      pending.push_back(&entry);
    }
  }
  std::set<int> seen;
  std::vector<const ProcessEntry*> tree;
  while (!pending.empty()) {
    const ProcessEntry* entry = pending.back();
    pending.pop_back();
    if (entry->pid == 1 || entry->pid == exclude || !seen.insert(entry->pid).second) continue;
    tree.push_back(entry);
    const auto [first, last] = children.equal_range(entry->pid);
    for (auto it = first; it != last; ++it) pending.push_back(it->second);
  }
  return tree;
}

std::optional<CpuTimes> parseCpuTimes(const std::string& proc_stat) {
  std::istringstream lines(proc_stat);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream fields(line);
    std::string label;
    fields >> label;
    if (label != "cpu") continue;
    uint64_t v[8] = {};
    for (uint64_t& value : v) fields >> value;
    if (!fields && !fields.eof()) return {};
    // user nice system idle iowait irq softirq steal
    CpuTimes times;
    times.busy = v[0] + v[1] + v[2] + v[5] + v[6] + v[7];
    times.total = times.busy + v[3] + v[4];
    return times;
  }
  return {};
}

MemoryInfo parseMemoryInfo(const std::string& meminfo) {
  std::map<std::string, int64_t> kib;
  std::istringstream lines(meminfo);
  for (std::string line; std::getline(lines, line);) {
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    kib[line.substr(0, colon)] = std::strtoll(line.c_str() + colon + 1, nullptr, 10);
  }
  auto bytes = [&kib](const char* key) {
    const auto it = kib.find(key);
    return it == kib.end() ? int64_t{0} : it->second * 1024;
  };
  MemoryInfo info;
  info.phys_total_bytes = bytes("MemTotal");
  info.phys_free_bytes = kib.count("MemAvailable") ? bytes("MemAvailable") : bytes("MemFree");
  info.swap_total_bytes = bytes("SwapTotal");
  info.swap_free_bytes = bytes("SwapFree");
  return info;
}

}  // namespace thicket::procman
