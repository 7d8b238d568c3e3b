// The deputy's decisions (deputy.h): orders → starts and stops, exits → respawns and restarts,
// deadlines → SIGKILL. No system calls here; ProcessControl does them.
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstring>
#include <set>

#include "thicket/common/time.h"
#include "thicket/procman/command_line.h"
#include "thicket/procman/deputy.h"

namespace thicket::procman {
namespace {

// A stop_time_allowed beyond this is taken as this (an hour is "never" for a stop).
constexpr float kMaxStopTimeAllowed = 3600.0f;

CommandSpec specOf(const procman_lcm::cmd_t& cmd) {
  CommandSpec spec;
  spec.id = cmd.command_id;
  spec.exec = cmd.exec_str;
  spec.group = cmd.group;
  spec.auto_respawn = cmd.auto_respawn;
  spec.stop_signal = cmd.stop_signal;
  spec.stop_time_allowed = cmd.stop_time_allowed;
  return spec;
}

std::string signalName(int signal) {
  const char* description = ::strsignal(signal);
  return "signal " + std::to_string(signal) +
         (description != nullptr ? std::string(" (") + description + ")" : std::string());
}

}  // namespace

int64_t RespawnBackoff::next(int64_t ran_us) {
  if (ran_us >= kStableRunUs) delay_us_ = kMinDelayUs;
  const int64_t delay = delay_us_;
  delay_us_ = std::min(kMaxDelayUs, delay_us_ * 2);
  return delay;
}

DeputyCore::DeputyCore(std::string deputy_id, ProcessControl& control, Say say)
    : id_(std::move(deputy_id)), control_(control), say_(std::move(say)) {}

DeputyCommand* DeputyCore::find(const std::string& id) {
  for (DeputyCommand& command : commands_) {
    if (command.spec.id == id) return &command;
  }
  return nullptr;
}

const DeputyCommand* DeputyCore::command(const std::string& id) const {
  return const_cast<DeputyCore*>(this)->find(id);
}

bool DeputyCore::takeChanged() {
  const bool changed = changed_;
  changed_ = false;
  return changed;
}

std::string DeputyCore::validate(const procman_lcm::cmd_desired_t& entry) const {
  const procman_lcm::cmd_t& cmd = entry.cmd;
  auto split = splitCommandLine(cmd.exec_str, Environment{});
  if (!split) return "exec '" + cmd.exec_str + "': " + split.error();
  if (!std::isfinite(cmd.stop_time_allowed) || cmd.stop_time_allowed < 0) {
    return "stop_time_allowed " + std::to_string(cmd.stop_time_allowed) +
           " is not a duration in seconds";
  }
  if (cmd.stop_signal < 1 || cmd.stop_signal >= NSIG) {
    return "stop_signal " + std::to_string(cmd.stop_signal) + " is not a signal";
  }
  return {};
}

void DeputyCore::handleOrders(const procman_lcm::orders_t& orders, int64_t wall_utime,
                              int64_t now) {
  if (exiting_ || orders.deputy_id != id_) return;
  if (wall_utime - orders.utime > kMaxOrdersAgeUs) {
    say_("", "ignoring stale orders from sheriff '" + orders.sheriff_id + "': sent " +
                 std::to_string((wall_utime - orders.utime) / kMicrosPerSecond) +
                 " s ago by this deputy's clock (check the clocks)\n");
    return;
  }

  std::set<std::string> present;
  std::map<std::string, std::string> refusals;
  const size_t count = std::min(orders.cmds.size(), static_cast<size_t>(std::max(0, orders.ncmds)));
  for (size_t i = 0; i < count; ++i) {
    const procman_lcm::cmd_desired_t& entry = orders.cmds[i];
    const std::string& id = entry.cmd.command_id;
    if (id.empty()) {
      refusals["#" + std::to_string(i)] = "refusing command " + std::to_string(i) +
                                          " of the orders: empty command id (exec '" +
                                          entry.cmd.exec_str + "')\n";
      continue;
    }
    if (!present.insert(id).second) {
      refusals["dup:" + id] = "refusing a second command '" + id +
                              "' in the orders: duplicate id (the first one applies)\n";
      continue;
    }
    const std::string problem = validate(entry);
    if (!problem.empty()) {
      refusals[id] = "refusing command '" + id + "': " + problem + "\n";
      continue;
    }

    DeputyCommand* command = find(id);
    const CommandSpec spec = specOf(entry.cmd);
    if (command == nullptr) {
      commands_.push_back(DeputyCommand{});
      command = &commands_.back();
      command->spec = spec;
      changed_ = true;
    } else if (!(command->spec == spec)) {
      if (!spec.auto_respawn) command->respawn_at.reset();
      command->spec = spec;
      changed_ = true;
    }
    if (command->removing) {
      command->removing = false;
      changed_ = true;
    }
    command->desired_runid = entry.desired_runid;
    command->force_quit = entry.force_quit;
    reconcile(*command, now);
  }

  for (const auto& [key, text] : refusals) {
    const auto said = refusals_.find(key);
    if (said == refusals_.end() || said->second != text) say_("", text);
  }
  refusals_ = std::move(refusals);

  for (auto it = commands_.begin(); it != commands_.end();) {
    if (present.count(it->spec.id) != 0) {
      ++it;
      continue;
    }
    changed_ = true;
    if (it->pid == 0) {
      it = commands_.erase(it);
      continue;
    }
    it->removing = true;
    it->respawn_at.reset();
    if (!it->stop_sent) stop(*it, now);
    ++it;
  }
}

void DeputyCore::reconcile(DeputyCommand& command, int64_t now) {
  if (command.pid != 0) {
    if (!command.stop_sent &&
        (command.force_quit || command.removing || command.desired_runid != command.actual_runid)) {
      stop(command, now);
    }
    return;
  }
  if (command.removing) return;
  if (!command.force_quit && command.desired_runid != command.actual_runid) {
    if (!exiting_) start(command, command.desired_runid, now);
    return;
  }
  if (command.force_quit) command.respawn_at.reset();
  if (command.actual_runid != command.desired_runid) {
    command.actual_runid = command.desired_runid;
    changed_ = true;
  }
}

void DeputyCore::start(DeputyCommand& command, int32_t runid, int64_t now) {
  command.respawn_at.reset();
  command.stop_sent = false;
  command.kill_at.reset();
  command.actual_runid = runid;
  command.started_at = now;
  changed_ = true;
  Expected<int> pid = control_.start(command.spec);
  if (!pid) {
    command.pid = 0;
    command.exit_status = W_EXITCODE(127, 0);
    say_(command.spec.id,
         "thicket-deputy: cannot start '" + command.spec.exec + "': " + pid.error() + "\n");
    if (command.spec.auto_respawn && !command.force_quit) scheduleRespawn(command, now);
    return;
  }
  command.pid = *pid;
  command.exit_status = 0;
}

void DeputyCore::stop(DeputyCommand& command, int64_t now) {
  command.stop_sent = true;
  command.respawn_at.reset();
  const float allowed = std::min(command.spec.stop_time_allowed, kMaxStopTimeAllowed);
  command.kill_at = now + secondsToUtime(allowed);
  control_.signalTree(command.pid, command.spec.stop_signal);
  changed_ = true;
}

void DeputyCore::scheduleRespawn(DeputyCommand& command, int64_t now) {
  command.respawn_at = now + command.backoff.next(now - command.started_at);
}

void DeputyCore::handleExit(int pid, int status, int64_t now) {
  if (pid <= 0) return;
  auto it = std::find_if(commands_.begin(), commands_.end(),
                         [pid](const DeputyCommand& c) { return c.pid == pid; });
  if (it == commands_.end()) return;
  DeputyCommand& command = *it;
  const bool was_stopping = command.stop_sent;
  if (was_stopping && command.kill_at && control_.treeAlive(pid)) {
    leftovers_.push_back({pid, *command.kill_at});
  }
  command.pid = 0;
  command.exit_status = status;
  command.stop_sent = false;
  command.kill_at.reset();
  changed_ = true;
  if (WIFSIGNALED(status)) {
    say_(command.spec.id, "thicket-deputy: terminated by " + signalName(WTERMSIG(status)) +
                              (WCOREDUMP(status) ? ", core dumped\n" : "\n"));
  }
  if (command.removing) {
    commands_.erase(it);
    return;
  }
  if (exiting_) return;
  if (!command.force_quit && command.desired_runid != command.actual_runid) {
    start(command, command.desired_runid, now);  // the second half of a restart
  } else if (!was_stopping && !command.force_quit && command.spec.auto_respawn) {
    scheduleRespawn(command, now);
  }
}

void DeputyCore::handleTimers(int64_t now) {
  for (DeputyCommand& command : commands_) {
    if (command.pid != 0 && command.kill_at && now >= *command.kill_at) {
      command.kill_at.reset();
      say_(command.spec.id, "thicket-deputy: still running after " +
                                signalName(command.spec.stop_signal) + "; sending SIGKILL\n");
      control_.signalTree(command.pid, SIGKILL);
    }
    if (command.pid == 0 && command.respawn_at && now >= *command.respawn_at) {
      command.respawn_at.reset();
      if (!exiting_ && !command.removing && !command.force_quit && command.spec.auto_respawn) {
        start(command, command.actual_runid, now);
      }
    }
  }
  for (auto it = leftovers_.begin(); it != leftovers_.end();) {
    if (now < it->kill_at) {
      ++it;
      continue;
    }
    // A pid reused by a command started since must not be taken for the old tree.
    const int root = it->root;
    const bool reused = std::any_of(commands_.begin(), commands_.end(),
                                    [root](const DeputyCommand& c) { return c.pid == root; });
    if (!reused) control_.signalTree(root, SIGKILL);
    it = leftovers_.erase(it);
  }
}

std::optional<int64_t> DeputyCore::nextTimer() const {
  std::optional<int64_t> next;
  auto consider = [&next](const std::optional<int64_t>& t) {
    if (t && (!next || *t < *next)) next = t;
  };
  for (const DeputyCommand& command : commands_) {
    if (command.pid != 0) consider(command.kill_at);
    if (command.pid == 0) consider(command.respawn_at);
  }
  for (const Leftover& leftover : leftovers_) consider(leftover.kill_at);
  return next;
}

void DeputyCore::beginShutdown(int64_t now) {
  if (exiting_) return;
  exiting_ = true;
  exit_deadline_ = now + kShutdownLimitUs;
  const int64_t kill_at = now + kShutdownGraceUs;
  for (DeputyCommand& command : commands_) {
    command.respawn_at.reset();
    if (command.pid == 0) continue;
    if (!command.stop_sent) {
      command.stop_sent = true;
      command.kill_at = kill_at;
      control_.signalTree(command.pid, command.spec.stop_signal);
    } else if (command.kill_at) {  // a stop in progress; none left when SIGKILL already went
      command.kill_at = std::min(*command.kill_at, kill_at);
    }
  }
  for (Leftover& leftover : leftovers_) leftover.kill_at = std::min(leftover.kill_at, kill_at);
  changed_ = true;
}

bool DeputyCore::shutdownComplete(int64_t now) {
  if (!exiting_) return false;
  if (now >= exit_deadline_) return true;
  for (const DeputyCommand& command : commands_) {
    if (command.pid != 0) return false;
  }
  std::erase_if(leftovers_, [this](const Leftover& l) { return !control_.treeAlive(l.root); });
  return leftovers_.empty();
}

// ---- OutputBatcher ----

void OutputBatcher::add(const std::string& command_id, std::string_view text, int64_t now) {
  if (text.empty()) return;
  for (Pending& pending : pending_) {
    if (pending.command_id == command_id) {
      pending.text.append(text);
      return;
    }
  }
  pending_.push_back({command_id, std::string(text), now});
}

std::optional<int64_t> OutputBatcher::nextDue() const {
  std::optional<int64_t> next;
  for (const Pending& pending : pending_) {
    const int64_t due =
        pending.text.size() >= kMaxBatchBytes ? pending.first_at : pending.first_at + kMaxDelayUs;
    if (!next || due < *next) next = due;
  }
  return next;
}

std::vector<std::pair<std::string, std::string>> OutputBatcher::take(int64_t now, bool all) {
  std::vector<std::pair<std::string, std::string>> batches;
  for (auto it = pending_.begin(); it != pending_.end();) {
    const bool due = all || it->text.size() >= kMaxBatchBytes || now >= it->first_at + kMaxDelayUs;
    if (!due) {
      ++it;
      continue;
    }
    for (size_t at = 0; at < it->text.size(); at += kMaxBatchBytes) {
      batches.emplace_back(it->command_id, it->text.substr(at, kMaxBatchBytes));
    }
    it = pending_.erase(it);
  }
  return batches;
}

}  // namespace thicket::procman
