#include "thicket/procman/sheriff.h"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <climits>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <utility>

namespace thicket::procman {
namespace {

// Garbage on PM_INFO must not grow the sheriff without bound.
constexpr size_t kMaxExtraDeputies = 256;
constexpr size_t kMaxNotes = 1000;

int32_t nextRunId(int32_t runid) {
  return runid >= INT32_MAX || runid < 0 ? 1 : runid + 1;
}

double finiteOrZero(double value) {
  return std::isfinite(value) ? value : 0.0;
}

std::string normalizeGroup(const std::string& path) {
  std::string out;
  for (char c : path) {
    if (c == '/' && (out.empty() || out.back() == '/')) continue;
    out += c;
  }
  while (!out.empty() && out.back() == '/') out.pop_back();
  return out;
}

bool inGroup(const std::string& command_group, const std::string& group) {
  return command_group == group ||
         (command_group.size() > group.size() &&
          command_group.compare(0, group.size(), group) == 0 && command_group[group.size()] == '/');
}

std::string trim(const std::string& text) {
  const size_t begin = text.find_first_not_of(" \t\r\n");
  if (begin == std::string::npos) return {};
  const size_t end = text.find_last_not_of(" \t\r\n");
  return text.substr(begin, end - begin + 1);
}

std::string unquote(const std::string& text) {
  if (text.size() >= 2 && text.front() == '"' && text.back() == '"') {
    return text.substr(1, text.size() - 2);
  }
  return text;
}

std::string fixed(double value, int decimals) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", decimals, value);
  return text;
}

std::string pad(const std::string& text, size_t width, bool right = false) {
  if (text.size() >= width) return text;
  const std::string fill(width - text.size(), ' ');
  return right ? fill + text : text + fill;
}

}  // namespace

const char* statusName(CommandStatus status) {
  switch (status) {
    case CommandStatus::kUnknown:
      return "Unknown";
    case CommandStatus::kStarting:
      return "Starting (Command Sent)";
    case CommandStatus::kRestarting:
      return "Restarting (Command Sent)";
    case CommandStatus::kRunning:
      return "Running";
    case CommandStatus::kStopping:
      return "Stopping (Command Sent)";
    case CommandStatus::kRemoving:
      return "Removing (Command Sent)";
    case CommandStatus::kStoppedOk:
      return "Stopped (OK)";
    case CommandStatus::kStoppedError:
      return "Stopped (Error)";
  }
  return "Unknown";
}

std::string describeExitCode(int32_t exit_code) {
  const int status = exit_code;
  if (WIFEXITED(status)) return std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) {
    const int signal = WTERMSIG(status);
    const char* abbrev = ::sigabbrev_np(signal);
    std::string text =
        abbrev != nullptr ? std::string("SIG") + abbrev : "signal " + std::to_string(signal);
    if (WCOREDUMP(status)) text += " (core dumped)";
    return text;
  }
  char text[32];
  std::snprintf(text, sizeof(text), "status 0x%x", static_cast<unsigned>(exit_code));
  return text;
}

std::string makeSheriffId() {
  char host[256] = {};
  if (::gethostname(host, sizeof(host) - 1) != 0 || host[0] == '\0') {
    std::snprintf(host, sizeof(host), "localhost");
  }
  const int64_t utime = std::chrono::duration_cast<std::chrono::microseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count();
  return std::string(host) + ":" + std::to_string(::getpid()) + ":" + std::to_string(utime);
}

// ---------------------------------------------------------------------------------------------

Sheriff::Sheriff(Sheet sheet, SheriffOptions options)
    : sheet_(std::move(sheet)), options_(std::move(options)) {
  if (options_.sheriff_id.empty()) options_.sheriff_id = makeSheriffId();
  for (const SheetCommand& spec : sheet_.commands) {
    if (spec.id.empty() || spec.deputy.empty()) {
      note("sheet-empty:" + spec.id, "sheet command '" + spec.id + "' (line " +
                                         std::to_string(spec.line) +
                                         ") has no id or no deputy: ignored");
      continue;
    }
    const Key key{spec.deputy, spec.id};
    if (commands_.count(key) != 0) {
      note("sheet-dup:" + spec.id, "sheet command '" + spec.id + "' appears twice for deputy '" +
                                       spec.deputy + "': the second is ignored");
      continue;
    }
    Command& command = addCommand(spec.deputy, spec.id, true);
    CommandView& view = command.view;
    view.group = normalizeGroup(spec.group);
    view.exec = spec.exec;
    view.auto_respawn = spec.auto_respawn;
    view.stop_signal = spec.stop_signal;
    if (spec.stop_signal < 1 || spec.stop_signal > 64) {
      note("sheet-signal:" + spec.id, "command '" + spec.id + "': stop_signal " +
                                          std::to_string(spec.stop_signal) +
                                          " is not a signal; using 2 (SIGINT)");
      view.stop_signal = 2;
    }
    view.stop_time_allowed = std::max(0, spec.stop_time_allowed);
    sheet_order_.push_back(key);
    if (std::find(sheet_deputies_.begin(), sheet_deputies_.end(), spec.deputy) ==
        sheet_deputies_.end()) {
      sheet_deputies_.push_back(spec.deputy);
    }
    deputy(spec.deputy).view.in_sheet = true;
  }
}

Sheriff::Deputy& Sheriff::deputy(const std::string& id) {
  auto [it, inserted] = deputies_.try_emplace(id);
  if (inserted) it->second.view.id = id;
  return it->second;
}

Sheriff::Command& Sheriff::addCommand(const std::string& deputy, const std::string& id,
                                      bool in_sheet) {
  Command& command = commands_[Key{deputy, id}];
  command.view.deputy = deputy;
  command.view.id = id;
  command.view.in_sheet = in_sheet;
  return command;
}

void Sheriff::removeCommand(const Key& key) {
  commands_.erase(key);
}

void Sheriff::note(const std::string& key, const std::string& text) {
  if (noted_.size() >= kMaxNotes) {
    if (noted_.insert("\x01too-many").second) {
      notes_.push_back("too many distinct problems; further ones are not reported");
    }
    return;
  }
  if (noted_.insert(key).second) notes_.push_back(text);
}

std::vector<std::string> Sheriff::takeNotes() {
  std::vector<std::string> notes;
  notes.swap(notes_);
  return notes;
}

bool Sheriff::deputyResponding(const Deputy& deputy, int64_t now_us) const {
  return deputy.view.heard && now_us - deputy.view.last_info_us <= options_.deputy_timeout_us;
}

// ---- input ----------------------------------------------------------------------------------

void Sheriff::handleInfo(const procman_lcm::deputy_info_t& info, int64_t now_us) {
  const std::string& deputy_id = info.deputy_id;
  if (deputy_id.empty()) {
    note("info-no-id", "ignored a deputy_info_t without deputy_id");
    return;
  }
  const auto known = deputies_.find(deputy_id);
  if (!observer() && (known == deputies_.end() || !known->second.view.in_sheet)) {
    // Not ours: no orders (empty orders would make it remove another sheriff's commands).
    note("info-other:" + deputy_id, "deputy '" + deputy_id +
                                        "' is not in the sheet: its reports are ignored and it "
                                        "gets no orders");
    return;
  }
  if (known == deputies_.end() && deputies_.size() >= sheet_deputies_.size() + kMaxExtraDeputies) {
    note("info-too-many", "too many deputies: ignoring deputy '" + deputy_id + "' and others");
    return;
  }
  Deputy& dep = deputy(deputy_id);
  const bool first = !dep.view.heard;
  dep.view.heard = true;
  dep.view.last_info_us = now_us;
  dep.view.cpu_load = finiteOrZero(info.cpu_load);
  dep.view.phys_mem_total_bytes = std::max<int64_t>(0, info.phys_mem_total_bytes);
  dep.view.phys_mem_free_bytes = std::max<int64_t>(0, info.phys_mem_free_bytes);
  if (first && !observer()) orders_changed_ = true;
  if (info.ncmds != static_cast<int64_t>(info.cmds.size())) {
    note("info-ncmds:" + deputy_id, "deputy '" + deputy_id + "' reports ncmds " +
                                        std::to_string(info.ncmds) + " but " +
                                        std::to_string(info.cmds.size()) + " commands");
  }

  std::set<std::string> present;
  for (const procman_lcm::cmd_status_t& status : info.cmds) {
    const std::string& id = status.cmd.command_id;
    const std::string where = "deputy '" + deputy_id + "' command '" + id + "'";
    if (id.empty()) {
      note("info-empty-id:" + deputy_id,
           "deputy '" + deputy_id + "' reports a command without id: ignored");
      continue;
    }
    if (!present.insert(id).second) {
      note("info-dup:" + deputy_id + "/" + id,
           where + " is reported twice: the first report is used");
      continue;
    }
    if (status.pid < 0 || status.actual_runid < 0) {
      note("info-negative:" + deputy_id + "/" + id,
           where + " reported with pid " + std::to_string(status.pid) + " and run id " +
               std::to_string(status.actual_runid) + ": negative values ignored");
      // Known but unusable: keep the last good report.
      continue;
    }
    const Key key{deputy_id, id};
    auto it = commands_.find(key);
    if (it == commands_.end()) {
      Command& added = addCommand(deputy_id, id, false);
      if (observer()) {
        added.removing = dep.orders_seen;  // the orders we saw for this deputy do not have it
      } else {
        added.removing = true;
        note("info-unknown:" + deputy_id + "/" + id,
             where + " is not in the sheet: shown as Removing; the deputy removes it");
      }
      it = commands_.find(key);
    }
    Command& command = it->second;
    CommandView& view = command.view;
    if (!view.in_sheet) {
      view.exec = status.cmd.exec_str;
      view.group = normalizeGroup(status.cmd.group);
      view.auto_respawn = status.cmd.auto_respawn;
      view.stop_signal = status.cmd.stop_signal;
      view.stop_time_allowed = std::max(0.0, finiteOrZero(status.cmd.stop_time_allowed));
    }
    view.reported = true;
    view.pid = status.pid;
    view.actual_runid = status.actual_runid;
    view.exit_code = status.exit_code;
    view.cpu_usage = std::max(0.0, finiteOrZero(status.cpu_usage));
    view.mem_vsize_bytes = std::max<int64_t>(0, status.mem_vsize_bytes);
    view.mem_rss_bytes = std::max<int64_t>(0, status.mem_rss_bytes);

    // A fresh sheriff adopts the run the deputy has, so that it does not restart it.
    const bool may_adopt = observer() ? !dep.orders_seen : view.in_sheet;
    if (may_adopt && view.desired_runid == 0 && view.actual_runid != 0) {
      view.desired_runid = view.actual_runid;
      if (!observer()) orders_changed_ = true;
    }
    // A run that completed is not run again (when the deputy restarts, say).
    if (!observer() && view.in_sheet && view.pid == 0 && view.actual_runid == view.desired_runid &&
        view.desired_runid != 0 && !view.auto_respawn && !view.force_quit) {
      view.force_quit = true;
      command.stop_requested = false;
      orders_changed_ = true;
    }
  }

  // Full state: what the deputy no longer reports, it does not have.
  std::vector<Key> gone;
  for (auto& [key, command] : commands_) {
    if (key.first != deputy_id || present.count(key.second) != 0) continue;
    command.view.reported = false;
    if (!command.view.in_sheet && (command.removing || !observer())) gone.push_back(key);
  }
  for (const Key& key : gone) removeCommand(key);
  dep.view.ncmds_reported = static_cast<int>(present.size());

  if (first && !observer()) {
    for (auto& [key, command] : commands_) {
      if (key.first != deputy_id || command.pending.empty()) continue;
      const std::vector<SheetAction::Kind> pending = std::move(command.pending);
      command.pending.clear();
      for (SheetAction::Kind kind : pending) applyOne(command, kind);
    }
  }
}

void Sheriff::noteConflict(const std::string& deputy_id, const std::string& other, int64_t now_us) {
  Conflict& conflict = conflicts_[{deputy_id, other}];
  conflict.deputy = deputy_id;
  conflict.other_sheriff = other;
  conflict.last_seen_us = now_us;
  note("conflict:" + deputy_id + "/" + other,
       "CONFLICT: sheriff '" + other + "' also sends orders to deputy '" + deputy_id + "'");
}

void Sheriff::handleOrders(const procman_lcm::orders_t& orders, int64_t now_us) {
  if (orders.sheriff_id == id()) return;  // our own, looped back
  const std::string& deputy_id = orders.deputy_id;
  if (deputy_id.empty()) {
    note("orders-no-id", "ignored an orders_t without deputy_id");
    return;
  }
  if (!observer()) {
    // We command the deputies of the sheet: another sheriff ordering one of them fights us.
    auto it = deputies_.find(deputy_id);
    if (it != deputies_.end() && it->second.view.in_sheet) {
      noteConflict(deputy_id, orders.sheriff_id, now_us);
    }
    return;
  }

  if (deputies_.count(deputy_id) == 0 &&
      deputies_.size() >= sheet_deputies_.size() + kMaxExtraDeputies) {
    note("orders-too-many",
         "too many deputies: ignoring orders for '" + deputy_id + "' and others");
    return;
  }
  Deputy& dep = deputy(deputy_id);
  if (dep.orders_seen && dep.last_orders_sheriff != orders.sheriff_id &&
      now_us - dep.last_orders_us <= options_.conflict_timeout_us) {
    noteConflict(deputy_id, dep.last_orders_sheriff, dep.last_orders_us);
    noteConflict(deputy_id, orders.sheriff_id, now_us);
  }
  dep.orders_seen = true;
  dep.last_orders_sheriff = orders.sheriff_id;
  dep.last_orders_us = now_us;

  std::set<std::string> ordered;
  for (const procman_lcm::cmd_desired_t& desired : orders.cmds) {
    const std::string& id = desired.cmd.command_id;
    if (id.empty() || desired.desired_runid < 0 || !ordered.insert(id).second) {
      note("orders-bad:" + deputy_id + "/" + id,
           "orders from '" + orders.sheriff_id + "' for deputy '" + deputy_id + "' command '" + id +
               "' are unusable (empty or duplicate id, or negative run id): ignored");
      continue;
    }
    const Key key{deputy_id, id};
    auto it = commands_.find(key);
    Command& command = it != commands_.end() ? it->second : addCommand(deputy_id, id, false);
    CommandView& view = command.view;
    view.exec = desired.cmd.exec_str;
    view.group = normalizeGroup(desired.cmd.group);
    view.auto_respawn = desired.cmd.auto_respawn;
    view.stop_signal = desired.cmd.stop_signal;
    view.stop_time_allowed = std::max(0.0, finiteOrZero(desired.cmd.stop_time_allowed));
    view.desired_runid = desired.desired_runid;
    view.force_quit = desired.force_quit;
    command.stop_requested = desired.force_quit;
    command.removing = false;
  }
  std::vector<Key> gone;
  for (auto& [key, command] : commands_) {
    if (key.first != deputy_id || ordered.count(key.second) != 0) continue;
    if (command.view.reported) {
      command.removing = true;
    } else if (!command.view.in_sheet) {
      gone.push_back(key);
    }
  }
  for (const Key& key : gone) removeCommand(key);
}

// ---- operator actions -----------------------------------------------------------------------

std::string Sheriff::checkTarget(const SheetTarget& target) const {
  switch (target.kind) {
    case SheetTarget::Kind::kEverything:
      return {};
    case SheetTarget::Kind::kCommand:
      for (const Key& key : sheet_order_) {
        if (key.second == target.name) return {};
      }
      return "no command '" + target.name + "' in the sheet";
    case SheetTarget::Kind::kGroup: {
      const std::string group = normalizeGroup(target.name);
      if (group.empty()) return "no group '" + target.name + "' in the sheet";
      for (const std::string& path : sheet_.groups) {
        if (inGroup(normalizeGroup(path), group)) return {};
      }
      for (const Key& key : sheet_order_) {
        if (inGroup(commands_.at(key).view.group, group)) return {};
      }
      return "no group '" + target.name + "' in the sheet";
    }
  }
  return "bad target";
}

std::vector<const Sheriff::Command*> Sheriff::targetCommands(const SheetTarget& target) const {
  std::vector<const Command*> result;
  const std::string group = normalizeGroup(target.name);
  for (const Key& key : sheet_order_) {
    const Command& command = commands_.at(key);
    bool match = false;
    switch (target.kind) {
      case SheetTarget::Kind::kEverything:
        match = true;
        break;
      case SheetTarget::Kind::kCommand:
        match = key.second == target.name;
        break;
      case SheetTarget::Kind::kGroup:
        match = !group.empty() && inGroup(command.view.group, group);
        break;
    }
    if (match) result.push_back(&command);
  }
  return result;
}

std::vector<Sheriff::Command*> Sheriff::targetCommands(const SheetTarget& target) {
  std::vector<Command*> result;
  for (const Command* command : std::as_const(*this).targetCommands(target)) {
    result.push_back(const_cast<Command*>(command));
  }
  return result;
}

void Sheriff::applyOne(Command& command, SheetAction::Kind kind) {
  CommandView& view = command.view;
  if (!deputy(view.deputy).view.heard) {
    // Nothing is sent to the deputy before its first report (see makeOrders): remember the
    // operation, collapsed so that it stays short, and apply it after adopting its run ids.
    std::vector<SheetAction::Kind>& pending = command.pending;
    if (kind == SheetAction::Kind::kStop || kind == SheetAction::Kind::kRestart) {
      pending.assign(1, kind);
    } else if (pending.empty() || pending.back() == SheetAction::Kind::kStop) {
      pending.push_back(kind);
    }
    return;
  }
  const int32_t actual = view.reported ? view.actual_runid : 0;
  switch (kind) {
    case SheetAction::Kind::kStart: {
      const bool running = view.reported && view.pid > 0;
      const bool starting = view.desired_runid != actual;
      if (!view.force_quit && (running || starting)) return;
      view.desired_runid = nextRunId(view.desired_runid);
      view.force_quit = false;
      command.stop_requested = false;
      break;
    }
    case SheetAction::Kind::kRestart:
      view.desired_runid = nextRunId(view.desired_runid);
      view.force_quit = false;
      command.stop_requested = false;
      break;
    case SheetAction::Kind::kStop:
      if (view.force_quit) return;
      view.force_quit = true;
      command.stop_requested = true;
      break;
    default:
      return;
  }
  orders_changed_ = true;
}

std::string Sheriff::apply(SheetAction::Kind kind, const SheetTarget& target) {
  if (observer()) return "observer mode sends no orders";
  if (kind != SheetAction::Kind::kStart && kind != SheetAction::Kind::kStop &&
      kind != SheetAction::Kind::kRestart) {
    return "not a start, stop or restart";
  }
  const std::string problem = checkTarget(target);
  if (!problem.empty()) return problem;
  for (Command* command : targetCommands(target)) applyOne(*command, kind);
  return {};
}

bool Sheriff::completedCurrentRun(const Command& command) const {
  const CommandView& view = command.view;
  return view.reported && !command.removing && view.pid == 0 && view.desired_runid != 0 &&
         view.actual_runid == view.desired_runid && !command.stop_requested;
}

bool Sheriff::satisfied(const SheetTarget& target, SheetAction::WaitFor wait,
                        std::string* pending) const {
  bool all = true;
  int listed = 0;
  for (const Command* command : targetCommands(target)) {
    const CommandStatus status = statusOf(*command);
    bool ok = true;
    if (wait == SheetAction::WaitFor::kRunning) {
      ok =
          status == CommandStatus::kRunning || (isStopped(status) && completedCurrentRun(*command));
    } else if (wait == SheetAction::WaitFor::kStopped) {
      ok = isStopped(status);
    }
    if (ok) continue;
    all = false;
    if (pending == nullptr) break;
    if (listed < 4) {
      *pending += (listed == 0 ? "" : ", ") + command->view.id + ": " + statusName(status);
    } else if (listed == 4) {
      *pending += ", ...";
    }
    ++listed;
  }
  return all;
}

std::optional<SheetTarget> Sheriff::resolve(const std::string& name, std::string* error) const {
  const bool is_command = checkTarget(SheetTarget{SheetTarget::Kind::kCommand, name}).empty();
  const bool is_group = checkTarget(SheetTarget{SheetTarget::Kind::kGroup, name}).empty();
  if (is_command && is_group) {
    if (error != nullptr) {
      *error = "'" + name + "' is both a command and a group: say 'cmd " + name + "' or 'group " +
               name + "'";
    }
    return std::nullopt;
  }
  if (is_command) return SheetTarget{SheetTarget::Kind::kCommand, name};
  if (is_group) return SheetTarget{SheetTarget::Kind::kGroup, name};
  if (error != nullptr) *error = "no command or group '" + name + "' in the sheet";
  return std::nullopt;
}

void Sheriff::stopEverything() {
  if (observer()) return;
  for (const Key& key : sheet_order_) {
    Command& command = commands_.at(key);
    command.pending.clear();
    if (!deputies_[key.first].view.heard) continue;
    applyOne(command, SheetAction::Kind::kStop);
  }
}

bool Sheriff::everythingStopped(int64_t now_us) const {
  for (const Key& key : sheet_order_) {
    const Command& command = commands_.at(key);
    auto dep = deputies_.find(key.first);
    if (dep == deputies_.end() || !deputyResponding(dep->second, now_us)) continue;
    if (command.view.reported && command.view.pid > 0) return false;
  }
  return true;
}

bool Sheriff::hasHeldOperations() const {
  for (const auto& [key, command] : commands_) {
    if (!command.pending.empty()) return true;
  }
  return false;
}

double Sheriff::maxStopTimeAllowed() const {
  double longest = 0;
  for (const Key& key : sheet_order_) {
    longest = std::max(longest, commands_.at(key).view.stop_time_allowed);
  }
  return longest;
}

// ---- output ---------------------------------------------------------------------------------

CommandStatus Sheriff::statusOf(const Command& command) const {
  const CommandView& view = command.view;
  if (!view.reported) return CommandStatus::kUnknown;
  if (command.removing) return CommandStatus::kRemoving;
  const bool running = view.pid > 0;
  const auto stopped = [&] {
    const int status = view.exit_code;
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return CommandStatus::kStoppedOk;
    if (WIFSIGNALED(status) && view.force_quit && command.stop_requested) {
      const int signal = WTERMSIG(status);
      if (signal == SIGTERM || signal == SIGINT || signal == SIGKILL) {
        return CommandStatus::kStoppedOk;
      }
    }
    return CommandStatus::kStoppedError;
  };
  if (view.force_quit) return running ? CommandStatus::kStopping : stopped();
  if (view.desired_runid != view.actual_runid) {
    return running ? CommandStatus::kRestarting : CommandStatus::kStarting;
  }
  return running ? CommandStatus::kRunning : stopped();
}

std::vector<procman_lcm::orders_t> Sheriff::makeOrders(int64_t utime) const {
  std::vector<procman_lcm::orders_t> all;
  if (observer()) return all;
  for (const std::string& deputy_id : sheet_deputies_) {
    const Deputy& dep = deputies_.at(deputy_id);
    if (!dep.view.heard) continue;
    procman_lcm::orders_t orders;
    orders.utime = utime;
    orders.deputy_id = deputy_id;
    orders.sheriff_id = id();
    for (const Key& key : sheet_order_) {
      if (key.first != deputy_id) continue;
      const CommandView& view = commands_.at(key).view;
      procman_lcm::cmd_desired_t desired;
      desired.cmd.command_id = view.id;
      desired.cmd.exec_str = view.exec;
      desired.cmd.group = view.group;
      desired.cmd.auto_respawn = view.auto_respawn;
      desired.cmd.stop_signal = static_cast<int8_t>(view.stop_signal);
      desired.cmd.stop_time_allowed = static_cast<float>(view.stop_time_allowed);
      desired.desired_runid = view.desired_runid;
      desired.force_quit = view.force_quit;
      orders.cmds.push_back(std::move(desired));
    }
    orders.ncmds = static_cast<int32_t>(orders.cmds.size());
    all.push_back(std::move(orders));
  }
  return all;
}

bool Sheriff::takeOrdersChanged() {
  const bool changed = orders_changed_;
  orders_changed_ = false;
  return changed;
}

std::vector<CommandView> Sheriff::commands() const {
  std::vector<CommandView> result;
  for (const Key& key : sheet_order_) {
    const Command& command = commands_.at(key);
    result.push_back(command.view);
    result.back().status = statusOf(command);
  }
  for (const auto& [key, command] : commands_) {
    if (command.view.in_sheet) continue;
    result.push_back(command.view);
    result.back().status = statusOf(command);
  }
  return result;
}

std::optional<CommandView> Sheriff::command(const std::string& deputy_id,
                                            const std::string& id) const {
  auto it = commands_.find(Key{deputy_id, id});
  if (it == commands_.end()) return std::nullopt;
  CommandView view = it->second.view;
  view.status = statusOf(it->second);
  return view;
}

std::vector<DeputyView> Sheriff::deputies(int64_t now_us) const {
  std::vector<DeputyView> result;
  for (const std::string& id : sheet_deputies_) {
    const Deputy& dep = deputies_.at(id);
    result.push_back(dep.view);
    result.back().responding = deputyResponding(dep, now_us);
  }
  for (const auto& [id, dep] : deputies_) {
    if (dep.view.in_sheet) continue;
    if (!dep.view.heard && !dep.orders_seen) continue;
    result.push_back(dep.view);
    result.back().responding = deputyResponding(dep, now_us);
  }
  return result;
}

std::vector<Conflict> Sheriff::conflicts(int64_t now_us) const {
  std::vector<Conflict> result;
  for (const auto& [key, conflict] : conflicts_) {
    if (now_us - conflict.last_seen_us <= options_.conflict_timeout_us) result.push_back(conflict);
  }
  return result;
}

// ---- text -----------------------------------------------------------------------------------

std::string formatStatusTable(const Sheriff& sheriff, int64_t now_us, bool usage) {
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> header = {"COMMAND", "DEPUTY", "STATUS", "PID", "RUN"};
  if (usage) {
    header.push_back("CPU%");
    header.push_back("RSS MB");
  }
  header.push_back("EXIT");
  rows.push_back(header);
  std::map<std::string, bool> responding;
  for (const DeputyView& dep : sheriff.deputies(now_us)) responding[dep.id] = dep.responding;

  for (const CommandView& view : sheriff.commands()) {
    std::vector<std::string> row;
    row.push_back(view.path() + (view.in_sheet || sheriff.observer() ? "" : " (not in sheet)"));
    row.push_back(view.deputy + (responding[view.deputy] ? "" : " (!)"));
    row.push_back(statusName(view.status));
    row.push_back(view.reported && view.pid > 0 ? std::to_string(view.pid) : "-");
    row.push_back((view.reported ? std::to_string(view.actual_runid) : "-") + "/" +
                  std::to_string(view.desired_runid));
    if (usage) {
      const bool running = view.reported && view.pid > 0;
      row.push_back(running ? fixed(view.cpu_usage * 100.0, 1) : "-");
      row.push_back(running ? fixed(static_cast<double>(view.mem_rss_bytes) / 1048576.0, 1) : "-");
    }
    row.push_back(view.reported && view.pid == 0 ? describeExitCode(view.exit_code) : "-");
    rows.push_back(std::move(row));
  }

  std::vector<size_t> widths(header.size(), 0);
  for (const auto& row : rows) {
    for (size_t i = 0; i < row.size(); ++i) widths[i] = std::max(widths[i], row[i].size());
  }
  std::string text;
  for (const auto& row : rows) {
    std::string line;
    for (size_t i = 0; i < row.size(); ++i) {
      const bool numeric = i >= 3 && i + 1 < row.size();
      const bool last = i + 1 == row.size();
      line += last ? row[i] : pad(row[i], widths[i], numeric) + "  ";
    }
    while (!line.empty() && line.back() == ' ') line.pop_back();
    text += line + "\n";
  }
  if (rows.size() == 1) text += "(no commands)\n";

  for (const DeputyView& dep : sheriff.deputies(now_us)) {
    if (!dep.heard) {
      text += "deputy '" + dep.id + "': not heard from\n";
    } else if (!dep.responding) {
      text += "deputy '" + dep.id + "': NOT RESPONDING";
      if (usage)
        text += " (last report " + fixed(static_cast<double>(now_us - dep.last_info_us) * 1e-6, 1) +
                " s ago)";
      text += "\n";
    }
  }
  for (const Conflict& conflict : sheriff.conflicts(now_us)) {
    text += "CONFLICT: sheriff '" + conflict.other_sheriff + "' also sends orders to deputy '" +
            conflict.deputy + "'\n";
  }
  return text;
}

std::string consoleHelp() {
  return "commands (one per line):\n"
         "  start|stop|restart cmd NAME     one command\n"
         "  start|stop|restart group PATH   a group and its subgroups\n"
         "  start|stop|restart everything   every command of the sheet\n"
         "  start|stop|restart NAME         a command, else a group\n"
         "  run SCRIPT                      run a script (aborts the active one)\n"
         "  status                          print the status table\n"
         "  quit                            stop every command, then exit\n"
         "  help                            this text\n";
}

ConsoleCommand parseConsoleCommand(const std::string& input, const Sheriff& sheriff) {
  ConsoleCommand result;
  const std::string line = trim(input);
  if (line.empty() || line[0] == '#') return result;
  const size_t space = line.find_first_of(" \t");
  std::string verb = line.substr(0, space);
  std::transform(verb.begin(), verb.end(), verb.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const std::string rest = space == std::string::npos ? "" : trim(line.substr(space));
  const auto error = [&](const std::string& text) {
    result.kind = ConsoleCommand::Kind::kError;
    result.error = text;
    return result;
  };
  const auto noArguments = [&](ConsoleCommand::Kind kind) {
    if (!rest.empty()) return error("'" + verb + "' takes no arguments");
    result.kind = kind;
    return result;
  };

  if (verb == "start" || verb == "stop" || verb == "restart") {
    result.action = verb == "start"  ? SheetAction::Kind::kStart
                    : verb == "stop" ? SheetAction::Kind::kStop
                                     : SheetAction::Kind::kRestart;
    if (rest.empty()) {
      return error(verb + " what? say '" + verb + " cmd NAME', '" + verb + " group PATH', '" +
                   verb + " everything' or '" + verb + " NAME'");
    }
    const size_t gap = rest.find_first_of(" \t");
    const std::string word = rest.substr(0, gap);
    const std::string name = gap == std::string::npos ? "" : unquote(trim(rest.substr(gap)));
    SheetTarget target;
    if ((word == "cmd" || word == "group") && !name.empty()) {
      target.kind = word == "cmd" ? SheetTarget::Kind::kCommand : SheetTarget::Kind::kGroup;
      target.name = name;
      const std::string problem = sheriff.checkTarget(target);
      if (!problem.empty()) return error(problem);
    } else if (rest == "everything") {
      target.kind = SheetTarget::Kind::kEverything;
    } else {
      std::string problem;
      const auto resolved = sheriff.resolve(unquote(rest), &problem);
      if (!resolved) return error(problem);
      target = *resolved;
    }
    result.kind = ConsoleCommand::Kind::kAction;
    result.target = target;
    return result;
  }
  if (verb == "run") {
    if (rest.empty()) return error("run what? say 'run SCRIPT'");
    result.kind = ConsoleCommand::Kind::kRun;
    result.script = unquote(rest);
    return result;
  }
  if (verb == "status") return noArguments(ConsoleCommand::Kind::kStatus);
  if (verb == "quit" || verb == "exit") return noArguments(ConsoleCommand::Kind::kQuit);
  if (verb == "help" || verb == "?") return noArguments(ConsoleCommand::Kind::kHelp);
  return error("unknown command '" + line + "'; type 'help' for the commands");
}

}  // namespace thicket::procman
