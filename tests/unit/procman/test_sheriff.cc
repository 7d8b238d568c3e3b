// The sheriff core, fed with made-up deputy reports and other sheriffs' orders: run-id
// semantics, adoption, status strings, orders per deputy, observer mode, conflicts, input
// validation and the console grammar. No LCM, no clock, no processes.
#include <signal.h>
#include <unistd.h>

#include <limits>
#include <regex>

#include <gtest/gtest.h>

#include "thicket/procman/sheriff.h"

namespace thicket::procman {
namespace {

constexpr int64_t kSecond = 1'000'000;

SheetCommand sheetCommand(const std::string& id, const std::string& group, const std::string& exec,
                          const std::string& deputy, bool auto_respawn = false) {
  SheetCommand command;
  command.id = id;
  command.group = group;
  command.exec = exec;
  command.deputy = deputy;
  command.auto_respawn = auto_respawn;
  return command;
}

// alpha runs sim/world and sim/inner/echo (auto-respawn); beta runs the top-level solo.
Sheet testSheet() {
  Sheet sheet;
  sheet.commands.push_back(sheetCommand("world", "sim", "sim-world --fast", "alpha"));
  sheet.commands.push_back(sheetCommand("echo", "sim/inner", "echo hi", "alpha", true));
  sheet.commands.push_back(sheetCommand("solo", "", "true", "beta"));
  sheet.commands.back().stop_signal = 15;
  sheet.commands.back().stop_time_allowed = 3;
  sheet.groups = {"sim", "sim/inner", "empty"};
  return sheet;
}

SheriffOptions options(bool observer = false) {
  SheriffOptions o;
  o.sheriff_id = "test-host:1:2";
  o.observer = observer;
  return o;
}

procman_lcm::cmd_status_t status(const std::string& id, int32_t pid, int32_t runid,
                                 int32_t exit_code = 0) {
  procman_lcm::cmd_status_t s{};
  s.cmd.command_id = id;
  s.cmd.exec_str = "exec of " + id;
  s.cmd.group = "";
  s.cmd.stop_signal = 2;
  s.cmd.stop_time_allowed = 7;
  s.pid = pid;
  s.actual_runid = runid;
  s.exit_code = exit_code;
  s.cpu_usage = 0.25f;
  s.mem_vsize_bytes = 100 << 20;
  s.mem_rss_bytes = 10 << 20;
  return s;
}

procman_lcm::deputy_info_t info(const std::string& deputy,
                                std::vector<procman_lcm::cmd_status_t> cmds = {}) {
  procman_lcm::deputy_info_t msg{};
  msg.utime = 1;
  msg.deputy_id = deputy;
  msg.cpu_load = 0.5f;
  msg.phys_mem_total_bytes = 8LL << 30;
  msg.phys_mem_free_bytes = 4LL << 30;
  msg.ncmds = static_cast<int32_t>(cmds.size());
  msg.cmds = std::move(cmds);
  return msg;
}

procman_lcm::orders_t orders(const std::string& sheriff, const std::string& deputy,
                             std::vector<procman_lcm::cmd_desired_t> cmds = {}) {
  procman_lcm::orders_t msg{};
  msg.utime = 1;
  msg.deputy_id = deputy;
  msg.sheriff_id = sheriff;
  msg.ncmds = static_cast<int32_t>(cmds.size());
  msg.cmds = std::move(cmds);
  return msg;
}

procman_lcm::cmd_desired_t desired(const std::string& id, int32_t runid, bool force_quit) {
  procman_lcm::cmd_desired_t d{};
  d.cmd.command_id = id;
  d.cmd.exec_str = "exec of " + id;
  d.cmd.group = "other/group";
  d.cmd.stop_signal = 2;
  d.cmd.stop_time_allowed = 7;
  d.desired_runid = runid;
  d.force_quit = force_quit;
  return d;
}

SheetTarget cmd(const std::string& name) {
  return SheetTarget{SheetTarget::Kind::kCommand, name};
}
SheetTarget group(const std::string& name) {
  return SheetTarget{SheetTarget::Kind::kGroup, name};
}
SheetTarget everything() {
  return SheetTarget{SheetTarget::Kind::kEverything, ""};
}

CommandView view(const Sheriff& sheriff, const std::string& deputy, const std::string& id) {
  auto found = sheriff.command(deputy, id);
  EXPECT_TRUE(found.has_value()) << deputy << "/" << id;
  return found.value_or(CommandView{});
}

const procman_lcm::cmd_desired_t* findOrder(const std::vector<procman_lcm::orders_t>& all,
                                            const std::string& deputy, const std::string& id) {
  for (const auto& o : all) {
    if (o.deputy_id != deputy) continue;
    for (const auto& c : o.cmds) {
      if (c.cmd.command_id == id) return &c;
    }
  }
  return nullptr;
}

bool notesMention(const std::vector<std::string>& notes, const std::string& word) {
  for (const std::string& n : notes) {
    if (n.find(word) != std::string::npos) return true;
  }
  return false;
}

// The sheriff after both deputies reported an empty state (fresh deputies).
Sheriff heardSheriff() {
  Sheriff sheriff(testSheet(), options());
  sheriff.handleInfo(info("alpha"), 0);
  sheriff.handleInfo(info("beta"), 0);
  sheriff.takeOrdersChanged();
  return sheriff;
}

TEST(SheriffStatus, NamesAreTheUpstreamStrings) {
  EXPECT_STREQ(statusName(CommandStatus::kUnknown), "Unknown");
  EXPECT_STREQ(statusName(CommandStatus::kStarting), "Starting (Command Sent)");
  EXPECT_STREQ(statusName(CommandStatus::kRestarting), "Restarting (Command Sent)");
  EXPECT_STREQ(statusName(CommandStatus::kRunning), "Running");
  EXPECT_STREQ(statusName(CommandStatus::kStopping), "Stopping (Command Sent)");
  EXPECT_STREQ(statusName(CommandStatus::kRemoving), "Removing (Command Sent)");
  EXPECT_STREQ(statusName(CommandStatus::kStoppedOk), "Stopped (OK)");
  EXPECT_STREQ(statusName(CommandStatus::kStoppedError), "Stopped (Error)");
}

TEST(SheriffStatus, ExitCodesAreWaitpidStatusWords) {
  EXPECT_EQ(describeExitCode(0), "0");
  EXPECT_EQ(describeExitCode(3 << 8), "3");
  EXPECT_EQ(describeExitCode(SIGKILL), "SIGKILL");
  EXPECT_EQ(describeExitCode(SIGSEGV | 0x80), "SIGSEGV (core dumped)");
  EXPECT_EQ(describeExitCode(0x137f), "status 0x137f");  // stopped, not exited
}

TEST(SheriffId, IsHostPidUtime) {
  const std::string id = makeSheriffId();
  std::smatch match;
  ASSERT_TRUE(std::regex_match(id, match, std::regex("([^:]+):([0-9]+):([0-9]+)"))) << id;
  EXPECT_EQ(match[2].str(), std::to_string(::getpid()));
  Sheriff sheriff(testSheet());
  EXPECT_FALSE(sheriff.id().empty());
}

TEST(SheriffStatus, EveryStateFromDesiredAndReported) {
  Sheriff sheriff = heardSheriff();
  // Known to the sheriff, not reported by the deputy: Unknown.
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kUnknown);

  ASSERT_EQ(sheriff.apply(SheetAction::Kind::kStart, cmd("world")), "");
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kUnknown);  // still no report
  sheriff.handleInfo(info("alpha", {status("world", 0, 0)}), 1);
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kStarting);
  sheriff.handleInfo(info("alpha", {status("world", 100, 1)}), 2);
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kRunning);

  sheriff.apply(SheetAction::Kind::kRestart, cmd("world"));
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kRestarting);
  sheriff.handleInfo(info("alpha", {status("world", 0, 1, SIGINT)}), 3);
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kStarting);
  sheriff.handleInfo(info("alpha", {status("world", 101, 2)}), 4);
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kRunning);

  sheriff.apply(SheetAction::Kind::kStop, cmd("world"));
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kStopping);
  sheriff.handleInfo(info("alpha", {status("world", 0, 2, SIGINT)}), 5);
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kStoppedOk);

  // Reported by the deputy but not in the sheet: Removing.
  sheriff.handleInfo(info("alpha", {status("world", 0, 2, SIGINT), status("ghost", 7, 1)}), 6);
  EXPECT_EQ(view(sheriff, "alpha", "ghost").status, CommandStatus::kRemoving);
}

TEST(SheriffStatus, StoppedOkOnlyForExitZeroOrAStopSignalAfterAStop) {
  const auto stoppedStatus = [](int32_t exit_code, bool stop_first) {
    Sheriff sheriff = heardSheriff();
    sheriff.apply(SheetAction::Kind::kStart, cmd("echo"));
    sheriff.handleInfo(info("alpha", {status("echo", 10, 1)}), 1);
    if (stop_first) sheriff.apply(SheetAction::Kind::kStop, cmd("echo"));
    sheriff.handleInfo(info("alpha", {status("echo", 0, 1, exit_code)}), 2);
    return view(sheriff, "alpha", "echo").status;
  };
  EXPECT_EQ(stoppedStatus(0, false), CommandStatus::kStoppedOk);
  EXPECT_EQ(stoppedStatus(0, true), CommandStatus::kStoppedOk);
  EXPECT_EQ(stoppedStatus(1 << 8, false), CommandStatus::kStoppedError);
  EXPECT_EQ(stoppedStatus(1 << 8, true), CommandStatus::kStoppedError);
  for (int signal : {SIGINT, SIGTERM, SIGKILL}) {
    EXPECT_EQ(stoppedStatus(signal, true), CommandStatus::kStoppedOk) << signal;
    EXPECT_EQ(stoppedStatus(signal, false), CommandStatus::kStoppedError) << signal;
  }
  EXPECT_EQ(stoppedStatus(SIGSEGV, true), CommandStatus::kStoppedError);
  EXPECT_EQ(stoppedStatus(SIGKILL | 0x80, true), CommandStatus::kStoppedOk);
}

TEST(SheriffRunIds, StartIncrementsUnlessRunningOrStarting) {
  Sheriff sheriff = heardSheriff();
  sheriff.apply(SheetAction::Kind::kStart, cmd("world"));
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 1);
  EXPECT_FALSE(view(sheriff, "alpha", "world").force_quit);
  EXPECT_TRUE(sheriff.takeOrdersChanged());
  // Starting already: a second start changes nothing (no needless restart by the deputy).
  sheriff.apply(SheetAction::Kind::kStart, cmd("world"));
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 1);
  EXPECT_FALSE(sheriff.takeOrdersChanged());
  sheriff.handleInfo(info("alpha", {status("world", 100, 1)}), 1);
  sheriff.takeOrdersChanged();
  sheriff.apply(SheetAction::Kind::kStart, cmd("world"));
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 1);
  EXPECT_FALSE(sheriff.takeOrdersChanged());
}

TEST(SheriffRunIds, RestartIncrementsUnconditionallyAndClearsForceQuit) {
  Sheriff sheriff = heardSheriff();
  sheriff.apply(SheetAction::Kind::kRestart, cmd("world"));
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 1);
  sheriff.apply(SheetAction::Kind::kRestart, cmd("world"));
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 2);
  sheriff.apply(SheetAction::Kind::kStop, cmd("world"));
  EXPECT_TRUE(view(sheriff, "alpha", "world").force_quit);
  sheriff.apply(SheetAction::Kind::kRestart, cmd("world"));
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 3);
  EXPECT_FALSE(view(sheriff, "alpha", "world").force_quit);
}

TEST(SheriffRunIds, StopSetsForceQuitAndStartClearsItWithANewRun) {
  Sheriff sheriff = heardSheriff();
  sheriff.apply(SheetAction::Kind::kStart, cmd("world"));
  sheriff.handleInfo(info("alpha", {status("world", 100, 1)}), 1);
  sheriff.takeOrdersChanged();
  sheriff.apply(SheetAction::Kind::kStop, cmd("world"));
  EXPECT_TRUE(sheriff.takeOrdersChanged());
  auto all = sheriff.makeOrders(5);
  ASSERT_NE(findOrder(all, "alpha", "world"), nullptr);
  EXPECT_TRUE(findOrder(all, "alpha", "world")->force_quit);
  EXPECT_EQ(findOrder(all, "alpha", "world")->desired_runid, 1);
  // Stopping twice is no change.
  sheriff.apply(SheetAction::Kind::kStop, cmd("world"));
  EXPECT_FALSE(sheriff.takeOrdersChanged());
  // Start while it is still stopping: a new run, force_quit cleared.
  sheriff.apply(SheetAction::Kind::kStart, cmd("world"));
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 2);
  EXPECT_FALSE(view(sheriff, "alpha", "world").force_quit);
}

TEST(SheriffRunIds, FreshSheriffAdoptsTheRunIdsDeputiesReport) {
  Sheriff sheriff(testSheet(), options());
  sheriff.handleInfo(info("alpha", {status("world", 4321, 7), status("echo", 0, 3, 0)}), 0);
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 7);
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kRunning);
  auto all = sheriff.makeOrders(1);
  ASSERT_NE(findOrder(all, "alpha", "world"), nullptr);
  EXPECT_EQ(findOrder(all, "alpha", "world")->desired_runid, 7);
  EXPECT_FALSE(findOrder(all, "alpha", "world")->force_quit);
  // echo is auto-respawn, so its stopped run is not marked done; its run id is adopted too.
  EXPECT_EQ(findOrder(all, "alpha", "echo")->desired_runid, 3);
  EXPECT_FALSE(findOrder(all, "alpha", "echo")->force_quit);
  // Later reports do not re-adopt: the desired state is the sheriff's now.
  sheriff.apply(SheetAction::Kind::kRestart, cmd("world"));
  sheriff.handleInfo(info("alpha", {status("world", 4321, 7)}), 1);
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 8);
}

TEST(SheriffRunIds, OperationsBeforeTheFirstReportApplyAfterAdoption) {
  Sheriff sheriff(testSheet(), options());
  ASSERT_EQ(sheriff.apply(SheetAction::Kind::kStart, everything()), "");
  EXPECT_TRUE(sheriff.makeOrders(1).empty());  // nobody heard from: nothing sent, nothing lost
  EXPECT_TRUE(sheriff.hasHeldOperations());
  // alpha still runs world (run 7) from an earlier sheriff: start must not restart it.
  sheriff.handleInfo(info("alpha", {status("world", 4321, 7)}), 0);
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 7);
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kRunning);
  EXPECT_EQ(view(sheriff, "alpha", "echo").desired_runid, 1);  // new to the deputy: run 1
  EXPECT_TRUE(sheriff.hasHeldOperations());                    // beta's solo still waits
  // beta's solo ran to completion as run 3 under the earlier sheriff; start runs it again.
  sheriff.handleInfo(info("beta", {status("solo", 0, 3, 0)}), 0);
  EXPECT_EQ(view(sheriff, "beta", "solo").desired_runid, 4);
  EXPECT_FALSE(view(sheriff, "beta", "solo").force_quit);
  EXPECT_FALSE(sheriff.hasHeldOperations());
}

TEST(SheriffRunIds, StopBeforeTheFirstReportStopsWhatRuns) {
  Sheriff sheriff(testSheet(), options());
  sheriff.apply(SheetAction::Kind::kStart, cmd("world"));
  sheriff.apply(SheetAction::Kind::kStop, cmd("world"));
  sheriff.handleInfo(info("alpha", {status("world", 4321, 7)}), 0);
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 7);
  EXPECT_TRUE(view(sheriff, "alpha", "world").force_quit);
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kStopping);
}

TEST(SheriffRunIds, ACompletedCommandIsNotRerun) {
  Sheriff sheriff = heardSheriff();
  sheriff.apply(SheetAction::Kind::kStart, cmd("solo"));
  sheriff.handleInfo(info("beta", {status("solo", 55, 1)}), 1);
  sheriff.takeOrdersChanged();
  EXPECT_FALSE(view(sheriff, "beta", "solo").force_quit);
  sheriff.handleInfo(info("beta", {status("solo", 0, 1, 0)}), 2);
  EXPECT_TRUE(view(sheriff, "beta", "solo").force_quit);
  EXPECT_TRUE(sheriff.takeOrdersChanged());  // sent at once
  EXPECT_TRUE(findOrder(sheriff.makeOrders(3), "beta", "solo")->force_quit);
  EXPECT_EQ(view(sheriff, "beta", "solo").status, CommandStatus::kStoppedOk);
  // A run that completed still counts as "running" for a wait (it has already stopped).
  EXPECT_TRUE(sheriff.satisfied(cmd("solo"), SheetAction::WaitFor::kRunning, nullptr));
  // A new start runs it again.
  sheriff.apply(SheetAction::Kind::kStart, cmd("solo"));
  EXPECT_EQ(view(sheriff, "beta", "solo").desired_runid, 2);
  EXPECT_FALSE(view(sheriff, "beta", "solo").force_quit);

  // An auto-respawn command that exited is left to respawn.
  sheriff.apply(SheetAction::Kind::kStart, cmd("echo"));
  sheriff.handleInfo(info("alpha", {status("echo", 0, 1, 1 << 8)}), 4);
  EXPECT_FALSE(view(sheriff, "alpha", "echo").force_quit);
  EXPECT_EQ(view(sheriff, "alpha", "echo").status, CommandStatus::kStoppedError);
}

TEST(SheriffOrders, OnlyForDeputiesHeardFromWithTheirFullDesiredState) {
  Sheriff sheriff(testSheet(), options());
  EXPECT_TRUE(sheriff.makeOrders(42).empty());
  sheriff.handleInfo(info("alpha"), 0);
  EXPECT_TRUE(sheriff.takeOrdersChanged());  // a new deputy gets its orders at once
  auto all = sheriff.makeOrders(42);
  ASSERT_EQ(all.size(), 1u);
  const procman_lcm::orders_t& o = all[0];
  EXPECT_EQ(o.utime, 42);
  EXPECT_EQ(o.deputy_id, "alpha");
  EXPECT_EQ(o.sheriff_id, "test-host:1:2");
  ASSERT_EQ(o.ncmds, 2);
  ASSERT_EQ(o.cmds.size(), 2u);
  EXPECT_EQ(o.cmds[0].cmd.command_id, "world");
  EXPECT_EQ(o.cmds[0].cmd.exec_str, "sim-world --fast");
  EXPECT_EQ(o.cmds[0].cmd.group, "sim");
  EXPECT_FALSE(o.cmds[0].cmd.auto_respawn);
  EXPECT_EQ(o.cmds[0].cmd.stop_signal, 2);
  EXPECT_FLOAT_EQ(o.cmds[0].cmd.stop_time_allowed, 7.0f);
  EXPECT_EQ(o.cmds[0].desired_runid, 0);
  EXPECT_FALSE(o.cmds[0].force_quit);
  EXPECT_EQ(o.cmds[1].cmd.command_id, "echo");
  EXPECT_EQ(o.cmds[1].cmd.group, "sim/inner");
  EXPECT_TRUE(o.cmds[1].cmd.auto_respawn);

  sheriff.handleInfo(info("beta"), 0);
  all = sheriff.makeOrders(43);
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[1].deputy_id, "beta");
  ASSERT_EQ(all[1].cmds.size(), 1u);
  EXPECT_EQ(all[1].cmds[0].cmd.stop_signal, 15);
  EXPECT_FLOAT_EQ(all[1].cmds[0].cmd.stop_time_allowed, 3.0f);

  // A deputy the sheet does not name gets no orders (empty ones would make it remove another
  // sheriff's commands); its reports are ignored with a note.
  sheriff.takeNotes();
  sheriff.handleInfo(info("gamma", {status("theirs", 5, 1)}), 0);
  EXPECT_EQ(sheriff.makeOrders(44).size(), 2u);
  EXPECT_FALSE(sheriff.command("gamma", "theirs").has_value());
  EXPECT_EQ(sheriff.deputies(0).size(), 2u);
  EXPECT_TRUE(notesMention(sheriff.takeNotes(), "deputy 'gamma' is not in the sheet"));
}

TEST(SheriffGroups, GroupOperationsCoverSubgroups) {
  Sheriff sheriff = heardSheriff();
  ASSERT_EQ(sheriff.apply(SheetAction::Kind::kStart, group("sim")), "");
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 1);
  EXPECT_EQ(view(sheriff, "alpha", "echo").desired_runid, 1);
  EXPECT_EQ(view(sheriff, "beta", "solo").desired_runid, 0);
  ASSERT_EQ(sheriff.apply(SheetAction::Kind::kRestart, group("sim/inner")), "");
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 1);
  EXPECT_EQ(view(sheriff, "alpha", "echo").desired_runid, 2);
  EXPECT_EQ(sheriff.apply(SheetAction::Kind::kStart, group("empty")), "");  // exists, no commands
  EXPECT_NE(sheriff.apply(SheetAction::Kind::kStart, group("si")), "");     // not a prefix match
  EXPECT_NE(sheriff.apply(SheetAction::Kind::kStart, group("nope")), "");
  EXPECT_NE(sheriff.apply(SheetAction::Kind::kStart, cmd("nope")), "");
  EXPECT_EQ(sheriff.apply(SheetAction::Kind::kStop, everything()), "");
  for (const CommandView& c : sheriff.commands()) EXPECT_TRUE(c.force_quit) << c.id;
}

TEST(SheriffWaits, RunningAndStoppedAcrossAGroup) {
  Sheriff sheriff = heardSheriff();
  sheriff.apply(SheetAction::Kind::kStart, group("sim"));
  std::string pending;
  EXPECT_FALSE(sheriff.satisfied(group("sim"), SheetAction::WaitFor::kRunning, &pending));
  EXPECT_NE(pending.find("world: Unknown"), std::string::npos) << pending;
  sheriff.handleInfo(info("alpha", {status("world", 10, 1), status("echo", 0, 0)}), 1);
  pending.clear();
  EXPECT_FALSE(sheriff.satisfied(group("sim"), SheetAction::WaitFor::kRunning, &pending));
  EXPECT_EQ(pending, "echo: Starting (Command Sent)");
  sheriff.handleInfo(info("alpha", {status("world", 10, 1), status("echo", 11, 1)}), 2);
  EXPECT_TRUE(sheriff.satisfied(group("sim"), SheetAction::WaitFor::kRunning, nullptr));
  EXPECT_FALSE(sheriff.satisfied(group("sim"), SheetAction::WaitFor::kStopped, nullptr));
  EXPECT_TRUE(sheriff.satisfied(group("sim"), SheetAction::WaitFor::kNothing, nullptr));

  sheriff.apply(SheetAction::Kind::kStop, group("sim"));
  EXPECT_FALSE(sheriff.satisfied(group("sim"), SheetAction::WaitFor::kStopped, nullptr));
  sheriff.handleInfo(info("alpha", {status("world", 0, 1, SIGINT), status("echo", 11, 1)}), 3);
  EXPECT_FALSE(sheriff.satisfied(group("sim"), SheetAction::WaitFor::kStopped, nullptr));
  EXPECT_TRUE(sheriff.satisfied(cmd("world"), SheetAction::WaitFor::kStopped, nullptr));
  // A command told to stop does not satisfy "running".
  EXPECT_FALSE(sheriff.satisfied(cmd("world"), SheetAction::WaitFor::kRunning, nullptr));
  sheriff.handleInfo(info("alpha", {status("world", 0, 1, SIGINT), status("echo", 0, 1, SIGKILL)}),
                     4);
  EXPECT_TRUE(sheriff.satisfied(group("sim"), SheetAction::WaitFor::kStopped, nullptr));
  EXPECT_TRUE(sheriff.satisfied(group("empty"), SheetAction::WaitFor::kRunning, nullptr));
}

TEST(SheriffInput, UnknownCommandsAreShownAsRemovingWithANoteAndNotOrdered) {
  Sheriff sheriff = heardSheriff();
  sheriff.takeNotes();
  sheriff.handleInfo(info("alpha", {status("ghost", 99, 4)}), 1);
  const auto notes = sheriff.takeNotes();
  EXPECT_TRUE(notesMention(notes, "ghost")) << ::testing::PrintToString(notes);
  const CommandView ghost = view(sheriff, "alpha", "ghost");
  EXPECT_FALSE(ghost.in_sheet);
  EXPECT_EQ(ghost.status, CommandStatus::kRemoving);
  EXPECT_EQ(findOrder(sheriff.makeOrders(1), "alpha", "ghost"), nullptr);
  // Said once, not on every report.
  sheriff.handleInfo(info("alpha", {status("ghost", 99, 4)}), 2);
  EXPECT_TRUE(sheriff.takeNotes().empty());
  // A sheet id reported by the wrong deputy is unknown there, too.
  sheriff.handleInfo(info("beta", {status("world", 5, 1)}), 2);
  EXPECT_EQ(view(sheriff, "beta", "world").status, CommandStatus::kRemoving);
  EXPECT_EQ(view(sheriff, "alpha", "world").status, CommandStatus::kUnknown);
  // Gone once the deputy no longer reports it.
  sheriff.handleInfo(info("alpha"), 3);
  EXPECT_FALSE(sheriff.command("alpha", "ghost").has_value());
}

TEST(SheriffInput, MalformedReportsAreSkippedWithNotes) {
  Sheriff sheriff = heardSheriff();
  sheriff.takeNotes();
  sheriff.handleInfo(info(""), 1);
  EXPECT_TRUE(notesMention(sheriff.takeNotes(), "without deputy_id"));
  EXPECT_EQ(sheriff.deputies(1).size(), 2u);

  sheriff.apply(SheetAction::Kind::kStart, cmd("world"));
  sheriff.handleInfo(info("alpha", {status("world", 10, 1)}), 1);
  // Duplicate ids: the first is used. Negative pid or run id: ignored, the last good report
  // stays. Empty id: ignored.
  sheriff.handleInfo(info("alpha", {status("world", 11, 1), status("world", 0, 1, 9),
                                    status("echo", -5, 1), status("", 3, 1)}),
                     2);
  const auto notes = sheriff.takeNotes();
  EXPECT_TRUE(notesMention(notes, "twice")) << ::testing::PrintToString(notes);
  EXPECT_TRUE(notesMention(notes, "pid -5")) << ::testing::PrintToString(notes);
  EXPECT_TRUE(notesMention(notes, "without id")) << ::testing::PrintToString(notes);
  EXPECT_EQ(view(sheriff, "alpha", "world").pid, 11);
  EXPECT_EQ(view(sheriff, "alpha", "echo").status, CommandStatus::kUnknown);

  auto bad = info("alpha", {status("world", 11, 1)});
  bad.ncmds = 5;
  bad.cmds[0].cpu_usage = std::numeric_limits<float>::quiet_NaN();
  bad.cmds[0].mem_rss_bytes = -1;
  sheriff.handleInfo(bad, 3);
  EXPECT_TRUE(notesMention(sheriff.takeNotes(), "ncmds 5"));
  EXPECT_EQ(view(sheriff, "alpha", "world").cpu_usage, 0.0);
  EXPECT_EQ(view(sheriff, "alpha", "world").mem_rss_bytes, 0);

  // Orders with garbage are refused as well.
  Sheriff observer(testSheet(), options(true));
  observer.handleOrders(orders("other", "", {desired("x", 1, false)}), 0);
  observer.handleOrders(orders("other", "alpha", {desired("", 1, false), desired("x", -1, false)}),
                        0);
  EXPECT_FALSE(observer.command("alpha", "x").has_value());
  EXPECT_TRUE(notesMention(observer.takeNotes(), "unusable"));
}

TEST(SheriffDeputies, NotRespondingAfterThreeSilentSeconds) {
  Sheriff sheriff(testSheet(), options());
  auto deputies = sheriff.deputies(0);
  ASSERT_EQ(deputies.size(), 2u);
  EXPECT_EQ(deputies[0].id, "alpha");
  EXPECT_FALSE(deputies[0].heard);
  EXPECT_NE(formatStatusTable(sheriff, 0).find("deputy 'alpha': not heard from"),
            std::string::npos);
  sheriff.handleInfo(info("alpha"), 10 * kSecond);
  EXPECT_TRUE(sheriff.deputies(13 * kSecond)[0].responding);
  EXPECT_FALSE(sheriff.deputies(13 * kSecond + 1)[0].responding);
  EXPECT_NE(formatStatusTable(sheriff, 14 * kSecond).find("deputy 'alpha': NOT RESPONDING"),
            std::string::npos);
  sheriff.handleInfo(info("alpha"), 14 * kSecond);
  EXPECT_TRUE(sheriff.deputies(14 * kSecond)[0].responding);
}

TEST(SheriffObserver, SendsNothingAndRefusesActions) {
  Sheriff sheriff(testSheet(), options(true));
  sheriff.handleInfo(info("alpha", {status("world", 10, 3)}), 0);
  EXPECT_TRUE(sheriff.makeOrders(1).empty());
  EXPECT_FALSE(sheriff.takeOrdersChanged());
  EXPECT_NE(sheriff.apply(SheetAction::Kind::kStart, cmd("world")), "");
  sheriff.stopEverything();
  EXPECT_FALSE(view(sheriff, "alpha", "world").force_quit);
  EXPECT_TRUE(sheriff.makeOrders(1).empty());
}

TEST(SheriffObserver, BuildsItsViewFromOtherSheriffsOrdersAndReports) {
  Sheriff sheriff(Sheet{}, options(true));
  sheriff.handleOrders(orders("boss:1:1", "alpha", {desired("x", 2, false)}), 0);
  CommandView x = view(sheriff, "alpha", "x");
  EXPECT_EQ(x.group, "other/group");
  EXPECT_EQ(x.desired_runid, 2);
  EXPECT_EQ(x.status, CommandStatus::kUnknown);
  sheriff.handleInfo(info("alpha", {status("x", 0, 1)}), 1);
  EXPECT_EQ(view(sheriff, "alpha", "x").status, CommandStatus::kStarting);
  sheriff.handleInfo(info("alpha", {status("x", 77, 2)}), 2);
  EXPECT_EQ(view(sheriff, "alpha", "x").status, CommandStatus::kRunning);
  sheriff.handleOrders(orders("boss:1:1", "alpha", {desired("x", 2, true)}), 3);
  EXPECT_EQ(view(sheriff, "alpha", "x").status, CommandStatus::kStopping);
  sheriff.handleInfo(info("alpha", {status("x", 0, 2, SIGINT)}), 4);
  EXPECT_EQ(view(sheriff, "alpha", "x").status, CommandStatus::kStoppedOk);
  // The orders drop it: removing until the deputy drops it too.
  sheriff.handleOrders(orders("boss:1:1", "alpha"), 5);
  EXPECT_EQ(view(sheriff, "alpha", "x").status, CommandStatus::kRemoving);
  sheriff.handleInfo(info("alpha"), 6);
  EXPECT_FALSE(sheriff.command("alpha", "x").has_value());
  // Reports alone (no orders seen): the reported run is taken as the wanted one.
  sheriff.handleInfo(info("beta", {status("y", 5, 9)}), 7);
  EXPECT_EQ(view(sheriff, "beta", "y").status, CommandStatus::kRunning);
  EXPECT_TRUE(sheriff.conflicts(7).empty());
}

TEST(SheriffConflicts, AnotherSheriffOrderingOurDeputyIsReported) {
  Sheriff sheriff(testSheet(), options());
  sheriff.takeNotes();
  sheriff.handleOrders(orders("test-host:1:2", "alpha"), 0);  // our own, looped back
  sheriff.handleOrders(orders("rival:9:9", "delta"), 0);      // not a deputy of ours
  EXPECT_TRUE(sheriff.conflicts(0).empty());
  sheriff.handleOrders(orders("rival:9:9", "alpha", {desired("world", 5, false)}), 10 * kSecond);
  auto conflicts = sheriff.conflicts(10 * kSecond);
  ASSERT_EQ(conflicts.size(), 1u);
  EXPECT_EQ(conflicts[0].deputy, "alpha");
  EXPECT_EQ(conflicts[0].other_sheriff, "rival:9:9");
  EXPECT_TRUE(notesMention(sheriff.takeNotes(), "CONFLICT"));
  EXPECT_NE(formatStatusTable(sheriff, 10 * kSecond)
                .find("CONFLICT: sheriff 'rival:9:9' also sends orders to deputy 'alpha'"),
            std::string::npos);
  // Their orders do not change ours.
  EXPECT_EQ(view(sheriff, "alpha", "world").desired_runid, 0);
  // Shown while it goes on.
  EXPECT_EQ(sheriff.conflicts(13 * kSecond).size(), 1u);
  EXPECT_TRUE(sheriff.conflicts(13 * kSecond + 1).empty());
}

TEST(SheriffConflicts, AnObserverReportsTwoSheriffsOrderingOneDeputy) {
  Sheriff sheriff(Sheet{}, options(true));
  sheriff.handleOrders(orders("a:1:1", "alpha"), 0);
  sheriff.handleOrders(orders("a:1:1", "alpha"), kSecond);
  EXPECT_TRUE(sheriff.conflicts(kSecond).empty());
  sheriff.handleOrders(orders("b:2:2", "alpha"), 2 * kSecond);
  EXPECT_EQ(sheriff.conflicts(2 * kSecond).size(), 2u);
}

TEST(SheriffQuit, StopEverythingAndWaitForTheReports) {
  Sheriff sheriff = heardSheriff();
  sheriff.apply(SheetAction::Kind::kStart, everything());
  sheriff.handleInfo(info("alpha", {status("world", 10, 1), status("echo", 11, 1)}), 0);
  sheriff.handleInfo(info("beta", {status("solo", 12, 1)}), 0);
  EXPECT_FALSE(sheriff.everythingStopped(0));
  sheriff.stopEverything();
  for (const auto& o : sheriff.makeOrders(1)) {
    for (const auto& c : o.cmds) EXPECT_TRUE(c.force_quit) << c.cmd.command_id;
  }
  sheriff.handleInfo(info("alpha", {status("world", 0, 1, SIGINT), status("echo", 0, 1, SIGINT)}),
                     3 * kSecond);
  EXPECT_FALSE(sheriff.everythingStopped(3 * kSecond));  // beta still runs solo
  // beta went silent: not waited for.
  EXPECT_TRUE(sheriff.everythingStopped(4 * kSecond));
  EXPECT_DOUBLE_EQ(sheriff.maxStopTimeAllowed(), 7.0);
}

TEST(SheriffTable, OneLinePerCommandWithEveryColumn) {
  Sheriff sheriff = heardSheriff();
  sheriff.apply(SheetAction::Kind::kStart, cmd("world"));
  sheriff.handleInfo(info("alpha", {status("world", 4242, 1)}), 0);
  sheriff.handleInfo(info("beta", {status("solo", 0, 0, 2 << 8)}), 0);
  const std::string table = formatStatusTable(sheriff, 0);
  EXPECT_NE(table.find("COMMAND"), std::string::npos) << table;
  EXPECT_NE(table.find("CPU%"), std::string::npos) << table;
  EXPECT_NE(table.find("RSS MB"), std::string::npos) << table;
  EXPECT_NE(table.find("EXIT"), std::string::npos) << table;
  EXPECT_TRUE(std::regex_search(
      table, std::regex("sim/world +alpha +Running +4242 +1/1 +25\\.0 +10\\.0 +-\n")))
      << table;
  EXPECT_TRUE(std::regex_search(table, std::regex("sim/inner/echo +alpha +Unknown")));
  EXPECT_TRUE(std::regex_search(table, std::regex("solo +beta +Stopped \\(Error\\) .* 2\n")))
      << table;
  const std::string brief = formatStatusTable(sheriff, 0, false);
  EXPECT_EQ(brief.find("CPU%"), std::string::npos);
}

TEST(SheriffConsole, ParsesEveryForm) {
  Sheriff sheriff = heardSheriff();
  auto c = parseConsoleCommand("start cmd world", sheriff);
  ASSERT_EQ(c.kind, ConsoleCommand::Kind::kAction) << c.error;
  EXPECT_EQ(c.action, SheetAction::Kind::kStart);
  EXPECT_EQ(c.target.kind, SheetTarget::Kind::kCommand);
  EXPECT_EQ(c.target.name, "world");
  c = parseConsoleCommand("  stop group sim/inner ", sheriff);
  ASSERT_EQ(c.kind, ConsoleCommand::Kind::kAction) << c.error;
  EXPECT_EQ(c.action, SheetAction::Kind::kStop);
  EXPECT_EQ(c.target.kind, SheetTarget::Kind::kGroup);
  EXPECT_EQ(c.target.name, "sim/inner");
  c = parseConsoleCommand("restart everything", sheriff);
  ASSERT_EQ(c.kind, ConsoleCommand::Kind::kAction);
  EXPECT_EQ(c.action, SheetAction::Kind::kRestart);
  EXPECT_EQ(c.target.kind, SheetTarget::Kind::kEverything);
  c = parseConsoleCommand("start solo", sheriff);  // bare command
  ASSERT_EQ(c.kind, ConsoleCommand::Kind::kAction);
  EXPECT_EQ(c.target.kind, SheetTarget::Kind::kCommand);
  c = parseConsoleCommand("start \"sim\"", sheriff);  // bare group, quoted
  ASSERT_EQ(c.kind, ConsoleCommand::Kind::kAction) << c.error;
  EXPECT_EQ(c.target.kind, SheetTarget::Kind::kGroup);
  c = parseConsoleCommand("run bringup", sheriff);
  ASSERT_EQ(c.kind, ConsoleCommand::Kind::kRun);
  EXPECT_EQ(c.script, "bringup");
  EXPECT_EQ(parseConsoleCommand("status", sheriff).kind, ConsoleCommand::Kind::kStatus);
  EXPECT_EQ(parseConsoleCommand("quit", sheriff).kind, ConsoleCommand::Kind::kQuit);
  EXPECT_EQ(parseConsoleCommand("help", sheriff).kind, ConsoleCommand::Kind::kHelp);
  EXPECT_EQ(parseConsoleCommand("", sheriff).kind, ConsoleCommand::Kind::kNone);
  EXPECT_EQ(parseConsoleCommand("# note", sheriff).kind, ConsoleCommand::Kind::kNone);
}

TEST(SheriffConsole, RefusesWithAClearMessage) {
  Sheet sheet = testSheet();
  sheet.commands.push_back(sheetCommand("sim", "", "x", "beta"));  // a command named like a group
  Sheriff sheriff(sheet, options());
  const auto error = [&](const std::string& line) {
    const ConsoleCommand c = parseConsoleCommand(line, sheriff);
    EXPECT_EQ(c.kind, ConsoleCommand::Kind::kError) << line;
    return c.error;
  };
  EXPECT_NE(error("frobnicate").find("unknown command 'frobnicate'"), std::string::npos);
  EXPECT_NE(error("start").find("start what?"), std::string::npos);
  EXPECT_NE(error("start cmd nope").find("no command 'nope'"), std::string::npos);
  EXPECT_NE(error("stop group nope").find("no group 'nope'"), std::string::npos);
  EXPECT_NE(error("restart nope").find("no command or group 'nope'"), std::string::npos);
  EXPECT_NE(error("start sim").find("both a command and a group"), std::string::npos);
  EXPECT_NE(error("status now").find("takes no arguments"), std::string::npos);
  EXPECT_NE(error("run").find("run what?"), std::string::npos);
}

TEST(SheriffSheet, BadSheetValuesAreRepairedWithNotes) {
  Sheet sheet;
  sheet.commands.push_back(sheetCommand("a", "", "x", "alpha"));
  sheet.commands.back().stop_signal = 300;
  sheet.commands.push_back(sheetCommand("a", "", "y", "alpha"));  // duplicate
  sheet.commands.push_back(sheetCommand("b", "", "z", ""));       // no deputy
  Sheriff sheriff(sheet, options());
  const auto notes = sheriff.takeNotes();
  EXPECT_EQ(notes.size(), 3u) << ::testing::PrintToString(notes);
  ASSERT_EQ(sheriff.commands().size(), 1u);
  EXPECT_EQ(sheriff.commands()[0].exec, "x");
  EXPECT_EQ(sheriff.commands()[0].stop_signal, 2);
}

}  // namespace
}  // namespace thicket::procman
