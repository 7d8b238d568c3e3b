// The script runner with made-up time: a fake host records the operations and says when waits
// are satisfied; a few tests drive the real sheriff core with fake deputy reports instead.
#include <map>
#include <set>

#include <gtest/gtest.h>

#include "thicket/procman/script_runner.h"
#include "thicket/procman/sheriff.h"

namespace thicket::procman {
namespace {

constexpr int64_t kMs = 1000;
constexpr int64_t kSecond = 1'000'000;

class FakeHost : public ScriptHost {
 public:
  std::set<std::string> known = {"cmd 'a'", "cmd 'b'", "cmd 'c'", "group 'g'", "everything"};
  std::vector<std::string> calls;
  std::map<std::string, std::set<SheetAction::WaitFor>> ready;  // target -> states reached
  std::string refuse;                                           // apply fails with this when set

  std::string checkTarget(const SheetTarget& target) const override {
    return known.count(describeTarget(target)) != 0 ? "" : "no " + describeTarget(target);
  }
  std::string apply(SheetAction::Kind kind, const SheetTarget& target) override {
    const char* verb = kind == SheetAction::Kind::kStart  ? "start"
                       : kind == SheetAction::Kind::kStop ? "stop"
                                                          : "restart";
    calls.push_back(std::string(verb) + " " + describeTarget(target));
    return refuse;
  }
  bool satisfied(const SheetTarget& target, SheetAction::WaitFor wait,
                 std::string* pending) const override {
    if (wait == SheetAction::WaitFor::kNothing) return true;
    auto it = ready.find(describeTarget(target));
    const bool ok = it != ready.end() && it->second.count(wait) != 0;
    if (!ok && pending != nullptr) *pending = describeTarget(target) + " not yet";
    return ok;
  }
  void reach(const std::string& target, SheetAction::WaitFor wait) { ready[target].insert(wait); }
};

SheetTarget cmd(const std::string& name) {
  return SheetTarget{SheetTarget::Kind::kCommand, name};
}
SheetTarget group(const std::string& name) {
  return SheetTarget{SheetTarget::Kind::kGroup, name};
}

int g_line = 0;

SheetAction act(SheetAction::Kind kind, SheetTarget target,
                SheetAction::WaitFor wait = SheetAction::WaitFor::kNothing) {
  SheetAction a;
  a.kind = kind;
  a.target = std::move(target);
  a.wait = wait;
  a.line = ++g_line;
  return a;
}
SheetAction start(SheetTarget t, SheetAction::WaitFor w = SheetAction::WaitFor::kNothing) {
  return act(SheetAction::Kind::kStart, std::move(t), w);
}
SheetAction stop(SheetTarget t, SheetAction::WaitFor w = SheetAction::WaitFor::kNothing) {
  return act(SheetAction::Kind::kStop, std::move(t), w);
}
SheetAction restart(SheetTarget t, SheetAction::WaitFor w = SheetAction::WaitFor::kNothing) {
  return act(SheetAction::Kind::kRestart, std::move(t), w);
}
SheetAction waitMs(int64_t ms) {
  SheetAction a = act(SheetAction::Kind::kWaitMs, {});
  a.ms = ms;
  return a;
}
SheetAction waitStatus(SheetTarget t, SheetAction::WaitFor w) {
  return act(SheetAction::Kind::kWaitStatus, std::move(t), w);
}
SheetAction runScript(const std::string& name) {
  SheetAction a = act(SheetAction::Kind::kRunScript, {});
  a.script = name;
  return a;
}

Sheet sheetWith(std::vector<SheetScript> scripts) {
  Sheet sheet;
  sheet.scripts = std::move(scripts);
  return sheet;
}

using Calls = std::vector<std::string>;
constexpr auto kRunning = SheetAction::WaitFor::kRunning;
constexpr auto kStopped = SheetAction::WaitFor::kStopped;

TEST(ScriptRunner, ActionsWithoutAWaitGoOnAtOnce) {
  const Sheet sheet =
      sheetWith({{"s", {start(cmd("a")), stop(group("g")), restart({}), start(cmd("b"))}, 1}});
  FakeHost host;
  ScriptRunner runner(sheet, host);
  EXPECT_EQ(runner.state(), ScriptRunner::State::kIdle);
  ASSERT_EQ(runner.run("s", 0), "");
  EXPECT_EQ(host.calls,
            (Calls{"start cmd 'a'", "stop group 'g'", "restart everything", "start cmd 'b'"}));
  EXPECT_EQ(runner.state(), ScriptRunner::State::kCompleted);
  EXPECT_FALSE(runner.active());
  const auto log = runner.takeLog();
  ASSERT_FALSE(log.empty());
  EXPECT_EQ(log.front(), "script 's' started");
  EXPECT_EQ(log.back(), "script 's' completed");
}

TEST(ScriptRunner, WaitRunningBlocksUntilTheTargetsRun) {
  const Sheet sheet = sheetWith({{"s", {start(cmd("a"), kRunning), stop(cmd("b"))}, 1}});
  FakeHost host;
  ScriptRunner runner(sheet, host);
  ASSERT_EQ(runner.run("s", 0), "");
  EXPECT_EQ(host.calls, (Calls{"start cmd 'a'"}));
  runner.step(10 * kSecond);
  EXPECT_TRUE(runner.active());
  EXPECT_EQ(host.calls.size(), 1u);
  EXPECT_NE(runner.describe(10 * kSecond).find("waiting for cmd 'a' to be running"),
            std::string::npos)
      << runner.describe(10 * kSecond);
  EXPECT_FALSE(runner.nextDeadline().has_value());  // no timeout: nothing to wake up for
  host.reach("cmd 'a'", kStopped);                  // the wrong state does not do
  runner.step(11 * kSecond);
  EXPECT_TRUE(runner.active());
  host.reach("cmd 'a'", kRunning);
  runner.step(12 * kSecond);
  EXPECT_EQ(host.calls, (Calls{"start cmd 'a'", "stop cmd 'b'"}));
  EXPECT_EQ(runner.state(), ScriptRunner::State::kCompleted);
}

TEST(ScriptRunner, WaitStoppedAndRestartWaits) {
  const Sheet sheet =
      sheetWith({{"s", {stop(group("g"), kStopped), restart(cmd("a"), kRunning)}, 1}});
  FakeHost host;
  ScriptRunner runner(sheet, host);
  ASSERT_EQ(runner.run("s", 0), "");
  EXPECT_EQ(host.calls, (Calls{"stop group 'g'"}));
  host.reach("group 'g'", kStopped);
  runner.step(1);
  EXPECT_EQ(host.calls, (Calls{"stop group 'g'", "restart cmd 'a'"}));
  EXPECT_TRUE(runner.active());
  host.reach("cmd 'a'", kRunning);
  runner.step(2);
  EXPECT_EQ(runner.state(), ScriptRunner::State::kCompleted);
}

TEST(ScriptRunner, AlreadySatisfiedWaitsDoNotBlock) {
  const Sheet sheet = sheetWith({{"s", {start(cmd("a"), kRunning), start(cmd("b"))}, 1}});
  FakeHost host;
  host.reach("cmd 'a'", kRunning);
  ScriptRunner runner(sheet, host);
  ASSERT_EQ(runner.run("s", 0), "");
  EXPECT_EQ(host.calls.size(), 2u);
  EXPECT_EQ(runner.state(), ScriptRunner::State::kCompleted);
}

TEST(ScriptRunner, WaitMsWaitsForTheGivenTime) {
  const Sheet sheet = sheetWith({{"s", {waitMs(500), start(cmd("a")), waitMs(0)}, 1}});
  FakeHost host;
  ScriptRunner runner(sheet, host);
  ASSERT_EQ(runner.run("s", 7 * kSecond), "");
  EXPECT_TRUE(host.calls.empty());
  ASSERT_TRUE(runner.nextDeadline().has_value());
  EXPECT_EQ(*runner.nextDeadline(), 7 * kSecond + 500 * kMs);
  runner.step(7 * kSecond + 499 * kMs);
  EXPECT_TRUE(host.calls.empty());
  runner.step(7 * kSecond + 500 * kMs);
  EXPECT_EQ(host.calls, (Calls{"start cmd 'a'"}));
  EXPECT_EQ(runner.state(), ScriptRunner::State::kCompleted);
}

TEST(ScriptRunner, WaitStatusWaitsWithoutActing) {
  const Sheet sheet = sheetWith(
      {{"s",
        {waitStatus(cmd("a"), kStopped), waitStatus(group("g"), kRunning), start(cmd("c"))},
        1}});
  FakeHost host;
  ScriptRunner runner(sheet, host);
  ASSERT_EQ(runner.run("s", 0), "");
  runner.step(1);
  EXPECT_TRUE(host.calls.empty());
  host.reach("cmd 'a'", kStopped);
  runner.step(2);
  EXPECT_TRUE(host.calls.empty());
  host.reach("group 'g'", kRunning);
  runner.step(3);
  EXPECT_EQ(host.calls, (Calls{"start cmd 'c'"}));
  EXPECT_EQ(runner.state(), ScriptRunner::State::kCompleted);
}

TEST(ScriptRunner, RunScriptRunsTheOtherScriptToCompletionFirst) {
  const Sheet sheet = sheetWith({{"main", {start(cmd("a")), runScript("sub"), start(cmd("c"))}, 1},
                                 {"sub", {start(cmd("b"), kRunning), runScript("leaf")}, 2},
                                 {"leaf", {waitMs(100), stop(cmd("a"))}, 3}});
  FakeHost host;
  ScriptRunner runner(sheet, host);
  ASSERT_EQ(runner.run("main", 0), "");
  EXPECT_EQ(host.calls, (Calls{"start cmd 'a'", "start cmd 'b'"}));
  EXPECT_NE(runner.describe(0).find("(in 'sub')"), std::string::npos) << runner.describe(0);
  host.reach("cmd 'b'", kRunning);
  runner.step(1 * kMs);
  EXPECT_EQ(host.calls, (Calls{"start cmd 'a'", "start cmd 'b'"}));  // leaf waits 100 ms
  runner.step(101 * kMs);
  EXPECT_EQ(host.calls, (Calls{"start cmd 'a'", "start cmd 'b'", "stop cmd 'a'", "start cmd 'c'"}));
  EXPECT_EQ(runner.state(), ScriptRunner::State::kCompleted);
  EXPECT_EQ(runner.scriptName(), "main");
}

TEST(ScriptRunner, ANewScriptAbortsTheActiveOne) {
  const Sheet sheet = sheetWith({{"first", {start(cmd("a"), kRunning), stop(cmd("a"))}, 1},
                                 {"second", {start(cmd("b"), kRunning), stop(cmd("b"))}, 2}});
  FakeHost host;
  ScriptRunner runner(sheet, host);
  ASSERT_EQ(runner.run("first", 0), "");
  runner.takeLog();
  ASSERT_EQ(runner.run("second", 1), "");
  const auto log = runner.takeLog();
  ASSERT_FALSE(log.empty());
  EXPECT_EQ(log.front(), "script 'first' aborted: script 'second' started");
  EXPECT_EQ(runner.scriptName(), "second");
  host.reach("cmd 'a'", kRunning);
  host.reach("cmd 'b'", kRunning);
  runner.step(2);
  // The first script never goes on.
  EXPECT_EQ(host.calls, (Calls{"start cmd 'a'", "start cmd 'b'", "stop cmd 'b'"}));
  EXPECT_EQ(runner.state(), ScriptRunner::State::kCompleted);
}

TEST(ScriptRunner, AWaitThatTimesOutFailsTheScript) {
  const Sheet sheet =
      sheetWith({{"s", {start(cmd("a")), start(cmd("b"), kRunning), start(cmd("c"))}, 1}});
  const int wait_line = sheet.scripts[0].actions[1].line;
  FakeHost host;
  ScriptRunner runner(sheet, host, 2 * kSecond);
  ASSERT_EQ(runner.run("s", 10 * kSecond), "");
  ASSERT_TRUE(runner.nextDeadline().has_value());
  EXPECT_EQ(*runner.nextDeadline(), 12 * kSecond);
  runner.step(12 * kSecond - 1);
  EXPECT_TRUE(runner.active());
  runner.step(12 * kSecond);
  EXPECT_EQ(runner.state(), ScriptRunner::State::kFailed);
  EXPECT_EQ(runner.message(), "script 's' line " + std::to_string(wait_line) +
                                  ": timed out after 2.0 s waiting for cmd 'b' to be running "
                                  "(still cmd 'b' not yet)");
  EXPECT_EQ(host.calls, (Calls{"start cmd 'a'", "start cmd 'b'"}));  // c never started
  EXPECT_FALSE(runner.nextDeadline().has_value());
  // wait ms is not cut short by the timeout.
  const Sheet slow = sheetWith({{"t", {waitMs(10'000), start(cmd("c"))}, 1}});
  ScriptRunner patient(slow, host, 2 * kSecond);
  ASSERT_EQ(patient.run("t", 0), "");
  patient.step(5 * kSecond);
  EXPECT_TRUE(patient.active());
  patient.step(10 * kSecond);
  EXPECT_EQ(patient.state(), ScriptRunner::State::kCompleted);
}

TEST(ScriptRunner, WithoutATimeoutAWaitLastsForever) {
  const Sheet sheet = sheetWith({{"s", {waitStatus(cmd("a"), kRunning)}, 1}});
  FakeHost host;
  ScriptRunner runner(sheet, host);
  ASSERT_EQ(runner.run("s", 0), "");
  runner.step(1'000'000 * kSecond);
  EXPECT_TRUE(runner.active());
}

TEST(ScriptRunner, RefusesUnknownNamesAndCyclesBeforeRunningAnything) {
  const Sheet sheet = sheetWith({{"ok", {start(cmd("a"), kRunning)}, 1},
                                 {"bad-target", {start(cmd("a")), start(cmd("zzz"))}, 2},
                                 {"bad-script", {start(cmd("a")), runScript("nowhere")}, 3},
                                 {"self", {start(cmd("a")), runScript("self")}, 4},
                                 {"ping", {start(cmd("a")), runScript("pong")}, 5},
                                 {"pong", {runScript("ping")}, 6},
                                 {"negative", {waitMs(-1)}, 7}});
  FakeHost host;
  ScriptRunner runner(sheet, host);
  ASSERT_EQ(runner.run("ok", 0), "");
  host.calls.clear();
  EXPECT_NE(runner.run("nope", 1).find("no script 'nope'"), std::string::npos);
  EXPECT_NE(runner.run("bad-target", 1).find("no cmd 'zzz'"), std::string::npos);
  EXPECT_NE(runner.run("bad-script", 1).find("no script 'nowhere'"), std::string::npos);
  EXPECT_NE(runner.run("self", 1).find("eventually runs itself"), std::string::npos);
  const std::string cycle = runner.run("ping", 1);
  EXPECT_NE(cycle.find("'ping' -> 'pong' -> 'ping'"), std::string::npos) << cycle;
  EXPECT_NE(runner.run("negative", 1).find("must not be negative"), std::string::npos);
  EXPECT_TRUE(host.calls.empty());
  // A refused script leaves the active one alone.
  EXPECT_TRUE(runner.active());
  EXPECT_EQ(runner.scriptName(), "ok");
  EXPECT_EQ(runner.check("ok"), "");
}

TEST(ScriptRunner, AFailingActionFailsTheScript) {
  const Sheet sheet = sheetWith({{"s", {start(cmd("a")), start(cmd("b"))}, 1}});
  FakeHost host;
  host.refuse = "observer mode sends no orders";
  ScriptRunner runner(sheet, host);
  ASSERT_EQ(runner.run("s", 0), "");
  EXPECT_EQ(runner.state(), ScriptRunner::State::kFailed);
  EXPECT_NE(runner.message().find("observer mode sends no orders"), std::string::npos);
  EXPECT_EQ(host.calls.size(), 1u);
}

TEST(ScriptRunner, AbortStopsTheActiveScript) {
  const Sheet sheet = sheetWith({{"s", {waitMs(10), start(cmd("a"))}, 1}});
  FakeHost host;
  ScriptRunner runner(sheet, host);
  runner.abort("nothing to abort");
  EXPECT_EQ(runner.state(), ScriptRunner::State::kIdle);
  ASSERT_EQ(runner.run("s", 0), "");
  runner.abort("quit requested");
  EXPECT_EQ(runner.state(), ScriptRunner::State::kAborted);
  EXPECT_EQ(runner.message(), "script 's' aborted: quit requested");
  runner.step(kSecond);
  EXPECT_TRUE(host.calls.empty());
  EXPECT_EQ(runner.describe(kSecond), "");
}

// ---- with the sheriff core -------------------------------------------------------------------

procman_lcm::cmd_status_t report(const std::string& id, int32_t pid, int32_t runid,
                                 int32_t exit_code = 0) {
  procman_lcm::cmd_status_t s{};
  s.cmd.command_id = id;
  s.pid = pid;
  s.actual_runid = runid;
  s.exit_code = exit_code;
  return s;
}

procman_lcm::deputy_info_t info(const std::string& deputy,
                                std::vector<procman_lcm::cmd_status_t> cmds) {
  procman_lcm::deputy_info_t msg{};
  msg.deputy_id = deputy;
  msg.ncmds = static_cast<int32_t>(cmds.size());
  msg.cmds = std::move(cmds);
  return msg;
}

Sheet sheriffSheet() {
  Sheet sheet;
  for (const auto& [id, group] : std::vector<std::pair<std::string, std::string>>{
           {"world", "sim"}, {"echo", "sim/inner"}, {"once", ""}}) {
    SheetCommand command;
    command.id = id;
    command.group = group;
    command.exec = "run " + id;
    command.deputy = "alpha";
    sheet.commands.push_back(command);
  }
  sheet.groups = {"sim", "sim/inner"};
  sheet.scripts = {{"up", {start(group("sim"), kRunning), start(cmd("once"), kRunning)}, 1},
                   {"down", {stop(SheetTarget{}, kStopped)}, 2}};
  return sheet;
}

TEST(ScriptRunnerWithSheriff, GroupWaitCoversSubgroupsAndCompletedRunsCount) {
  SheriffOptions options;
  options.sheriff_id = "t:1:1";
  Sheriff sheriff(sheriffSheet(), options);
  ScriptRunner runner(sheriff.sheet(), sheriff, 5 * kSecond);
  sheriff.handleInfo(info("alpha", {}), 0);
  ASSERT_EQ(runner.run("up", 0), "");
  EXPECT_EQ(sheriff.command("alpha", "world")->desired_runid, 1);
  EXPECT_EQ(sheriff.command("alpha", "echo")->desired_runid, 1);  // in a subgroup
  EXPECT_EQ(sheriff.command("alpha", "once")->desired_runid, 0);  // not yet
  sheriff.handleInfo(info("alpha", {report("world", 10, 1)}), kSecond);
  runner.step(kSecond);
  EXPECT_EQ(sheriff.command("alpha", "once")->desired_runid, 0);  // echo is not running yet
  sheriff.handleInfo(info("alpha", {report("world", 10, 1), report("echo", 11, 1)}), 2 * kSecond);
  runner.step(2 * kSecond);
  EXPECT_EQ(sheriff.command("alpha", "once")->desired_runid, 1);
  EXPECT_TRUE(runner.active());
  // "once" ran and exited before anyone saw it running: it has already stopped, which counts.
  sheriff.handleInfo(
      info("alpha", {report("world", 10, 1), report("echo", 11, 1), report("once", 0, 1, 0)}),
      3 * kSecond);
  runner.step(3 * kSecond);
  EXPECT_EQ(runner.state(), ScriptRunner::State::kCompleted);

  ASSERT_EQ(runner.run("down", 4 * kSecond), "");
  sheriff.handleInfo(
      info("alpha", {report("world", 0, 1, 2), report("echo", 11, 1), report("once", 0, 1, 0)}),
      5 * kSecond);
  runner.step(5 * kSecond);
  EXPECT_TRUE(runner.active());
  runner.step(9 * kSecond);
  EXPECT_EQ(runner.state(), ScriptRunner::State::kFailed);
  EXPECT_NE(runner.message().find("still echo: Stopping (Command Sent)"), std::string::npos)
      << runner.message();
}

TEST(ScriptRunnerWithSheriff, ChecksTargetsAgainstTheSheet) {
  Sheet sheet = sheriffSheet();
  sheet.scripts.push_back({"typo", {start(group("sim/outer"))}, 3});
  Sheriff sheriff(sheet);
  ScriptRunner runner(sheriff.sheet(), sheriff);
  EXPECT_NE(runner.check("typo").find("no group 'sim/outer'"), std::string::npos);
  EXPECT_EQ(runner.check("up"), "");
}

}  // namespace
}  // namespace thicket::procman
