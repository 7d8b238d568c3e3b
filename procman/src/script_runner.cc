#include "thicket/procman/script_runner.h"

#include <algorithm>
#include <cstdio>

namespace thicket::procman {
namespace {

const char* actionVerb(SheetAction::Kind kind) {
  switch (kind) {
    case SheetAction::Kind::kStart:
      return "start";
    case SheetAction::Kind::kStop:
      return "stop";
    case SheetAction::Kind::kRestart:
      return "restart";
    case SheetAction::Kind::kWaitMs:
      return "wait ms";
    case SheetAction::Kind::kWaitStatus:
      return "wait status";
    case SheetAction::Kind::kRunScript:
      return "run_script";
  }
  return "?";
}

const char* waitName(SheetAction::WaitFor wait) {
  switch (wait) {
    case SheetAction::WaitFor::kRunning:
      return "running";
    case SheetAction::WaitFor::kStopped:
      return "stopped";
    case SheetAction::WaitFor::kNothing:
      break;
  }
  return "nothing";
}

std::string seconds(int64_t us) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f s", static_cast<double>(us) * 1e-6);
  return text;
}

}  // namespace

std::string describeTarget(const SheetTarget& target) {
  switch (target.kind) {
    case SheetTarget::Kind::kEverything:
      return "everything";
    case SheetTarget::Kind::kCommand:
      return "cmd '" + target.name + "'";
    case SheetTarget::Kind::kGroup:
      return "group '" + target.name + "'";
  }
  return "?";
}

const char* scriptStateName(ScriptRunner::State state) {
  switch (state) {
    case ScriptRunner::State::kIdle:
      return "idle";
    case ScriptRunner::State::kRunning:
      return "running";
    case ScriptRunner::State::kCompleted:
      return "completed";
    case ScriptRunner::State::kFailed:
      return "failed";
    case ScriptRunner::State::kAborted:
      return "aborted";
  }
  return "?";
}

ScriptRunner::ScriptRunner(const Sheet& sheet, ScriptHost& host, int64_t wait_timeout_us)
    : sheet_(sheet), host_(host), wait_timeout_us_(std::max<int64_t>(0, wait_timeout_us)) {}

const SheetScript* ScriptRunner::findScript(const std::string& name) const {
  for (const SheetScript& script : sheet_.scripts) {
    if (script.name == name) return &script;
  }
  return nullptr;
}

void ScriptRunner::checkScript(const SheetScript& script, std::vector<const SheetScript*>& path,
                               std::vector<std::string>& errors) const {
  if (std::find(path.begin(), path.end(), &script) != path.end()) {
    std::string chain;
    for (const SheetScript* s : path) chain += "'" + s->name + "' -> ";
    errors.push_back("script '" + script.name + "' eventually runs itself (" + chain + "'" +
                     script.name + "')");
    return;
  }
  path.push_back(&script);
  for (const SheetAction& action : script.actions) {
    const std::string at = "script '" + script.name + "' line " + std::to_string(action.line);
    switch (action.kind) {
      case SheetAction::Kind::kStart:
      case SheetAction::Kind::kStop:
      case SheetAction::Kind::kRestart:
      case SheetAction::Kind::kWaitStatus: {
        const std::string problem = host_.checkTarget(action.target);
        if (!problem.empty()) errors.push_back(at + ": " + problem);
        if (action.kind == SheetAction::Kind::kWaitStatus &&
            action.wait == SheetAction::WaitFor::kNothing) {
          errors.push_back(at + ": wait status needs \"running\" or \"stopped\"");
        }
        break;
      }
      case SheetAction::Kind::kWaitMs:
        if (action.ms < 0) errors.push_back(at + ": wait ms must not be negative");
        break;
      case SheetAction::Kind::kRunScript: {
        const SheetScript* callee = findScript(action.script);
        if (callee == nullptr) {
          errors.push_back(at + ": no script '" + action.script + "'");
        } else {
          checkScript(*callee, path, errors);
        }
        break;
      }
    }
    // A cycle is reported once, not once per action that leads into it.
    if (errors.size() > 20) break;
  }
  path.pop_back();
}

std::string ScriptRunner::check(const std::string& name) const {
  const SheetScript* script = findScript(name);
  if (script == nullptr) return "no script '" + name + "' in the sheet";
  std::vector<const SheetScript*> path;
  std::vector<std::string> errors;
  checkScript(*script, path, errors);
  std::sort(errors.begin(), errors.end());
  errors.erase(std::unique(errors.begin(), errors.end()), errors.end());
  std::string text;
  for (const std::string& error : errors) text += (text.empty() ? "" : "; ") + error;
  return text;
}

std::string ScriptRunner::run(const std::string& name, int64_t now_us) {
  const std::string problem = check(name);
  if (!problem.empty()) return problem;
  if (active()) {
    finish(State::kAborted, "script '" + script_name_ + "' aborted: script '" + name + "' started");
  }
  state_ = State::kRunning;
  script_name_ = name;
  message_.clear();
  frames_.assign(1, Frame{findScript(name), 0});
  wait_ = Wait{};
  log_.push_back("script '" + name + "' started");
  step(now_us);
  return {};
}

void ScriptRunner::abort(const std::string& reason) {
  if (!active()) return;
  finish(State::kAborted, "script '" + script_name_ + "' aborted: " + reason);
}

void ScriptRunner::finish(State state, const std::string& message) {
  state_ = state;
  message_ = message;
  frames_.clear();
  wait_ = Wait{};
  if (state == State::kCompleted) {
    log_.push_back("script '" + script_name_ + "' completed");
  } else {
    log_.push_back(message);
  }
}

void ScriptRunner::fail(const std::string& message) {
  finish(State::kFailed, message);
}

std::string ScriptRunner::where(int line) const {
  std::string text = "script '" + script_name_ + "'";
  if (!frames_.empty() && frames_.back().script->name != script_name_) {
    text += " (in '" + frames_.back().script->name + "')";
  }
  if (line > 0) text += " line " + std::to_string(line);
  return text;
}

void ScriptRunner::execute(const SheetAction& action, int64_t now_us) {
  switch (action.kind) {
    case SheetAction::Kind::kStart:
    case SheetAction::Kind::kStop:
    case SheetAction::Kind::kRestart: {
      std::string text =
          where(action.line) + ": " + actionVerb(action.kind) + " " + describeTarget(action.target);
      if (action.wait != SheetAction::WaitFor::kNothing) {
        text += std::string(" wait \"") + waitName(action.wait) + "\"";
      }
      log_.push_back(text);
      const std::string problem = host_.apply(action.kind, action.target);
      if (!problem.empty()) {
        fail(where(action.line) + ": " + problem);
        return;
      }
      if (action.wait != SheetAction::WaitFor::kNothing) {
        wait_ = Wait{WaitKind::kStatus, now_us, 0, action.target, action.wait, action.line};
      }
      return;
    }
    case SheetAction::Kind::kWaitMs:
      log_.push_back(where(action.line) + ": wait ms " + std::to_string(action.ms));
      if (action.ms > 0) {
        wait_ = Wait{WaitKind::kMs, now_us, now_us + action.ms * 1000, {}, {}, action.line};
      }
      return;
    case SheetAction::Kind::kWaitStatus:
      log_.push_back(where(action.line) + ": wait " + describeTarget(action.target) + " status \"" +
                     waitName(action.wait) + "\"");
      wait_ = Wait{WaitKind::kStatus, now_us, 0, action.target, action.wait, action.line};
      return;
    case SheetAction::Kind::kRunScript: {
      const SheetScript* callee = findScript(action.script);
      // check() refused unknown scripts and cycles; stay safe if the sheet changed under us.
      if (callee == nullptr || frames_.size() > sheet_.scripts.size()) {
        fail(where(action.line) + ": cannot run script '" + action.script + "'");
        return;
      }
      log_.push_back(where(action.line) + ": run_script '" + action.script + "'");
      frames_.push_back(Frame{callee, 0});
      return;
    }
  }
}

void ScriptRunner::step(int64_t now_us) {
  while (active()) {
    if (wait_.kind == WaitKind::kMs) {
      if (now_us < wait_.until_us) return;
      wait_ = Wait{};
    } else if (wait_.kind == WaitKind::kStatus) {
      std::string pending;
      if (!host_.satisfied(wait_.target, wait_.wait_for, &pending)) {
        if (wait_timeout_us_ > 0 && now_us - wait_.since_us >= wait_timeout_us_) {
          std::string text = where(wait_.line) + ": timed out after " + seconds(wait_timeout_us_) +
                             " waiting for " + describeTarget(wait_.target) + " to be " +
                             waitName(wait_.wait_for);
          if (!pending.empty()) text += " (still " + pending + ")";
          fail(text);
        }
        return;
      }
      wait_ = Wait{};
    }
    if (frames_.empty()) {
      finish(State::kCompleted, {});
      return;
    }
    Frame& frame = frames_.back();
    if (frame.next >= frame.script->actions.size()) {
      frames_.pop_back();
      continue;
    }
    const SheetAction& action = frame.script->actions[frame.next++];
    execute(action, now_us);
  }
}

std::string ScriptRunner::describe(int64_t now_us) const {
  if (!active()) return {};
  std::string text = "script '" + script_name_ + "'";
  if (!frames_.empty() && frames_.back().script->name != script_name_) {
    text += " (in '" + frames_.back().script->name + "')";
  }
  switch (wait_.kind) {
    case WaitKind::kNone:
      text += ": running";
      break;
    case WaitKind::kMs:
      text += ": waiting " + seconds(std::max<int64_t>(0, wait_.until_us - now_us)) + " more";
      break;
    case WaitKind::kStatus: {
      text += ": waiting for " + describeTarget(wait_.target) + " to be " +
              waitName(wait_.wait_for) + " (" + seconds(now_us - wait_.since_us);
      if (wait_timeout_us_ > 0) text += " of " + seconds(wait_timeout_us_);
      text += ")";
      std::string pending;
      if (!host_.satisfied(wait_.target, wait_.wait_for, &pending) && !pending.empty()) {
        text += ": " + pending;
      }
      break;
    }
  }
  return text;
}

std::optional<int64_t> ScriptRunner::nextDeadline() const {
  if (!active()) return std::nullopt;
  if (wait_.kind == WaitKind::kMs) return wait_.until_us;
  if (wait_.kind == WaitKind::kStatus && wait_timeout_us_ > 0) {
    return wait_.since_us + wait_timeout_us_;
  }
  return std::nullopt;
}

std::vector<std::string> ScriptRunner::takeLog() {
  std::vector<std::string> log;
  log.swap(log_);
  return log;
}

}  // namespace thicket::procman
