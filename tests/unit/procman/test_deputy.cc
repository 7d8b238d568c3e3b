// The deputy: its decisions with injected time and a fake process control (DeputyCore), its
// helpers (backoff, output batching, /proc parsing), and the real thicket-deputy driven over
// udpm by this test acting as a sheriff, inside a private network namespace.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>
#include <procman_lcm/deputy_info_t.hpp>
#include <procman_lcm/orders_t.hpp>
#include <procman_lcm/output_t.hpp>

#include "child_process.h"
#include "proc_stats.h"
#include "procman_test_support.h"
#include "thicket/procman/deputy.h"

namespace thicket::procman {
namespace {

using test_support::isolatedUrl;
using test_support::processAlive;
using test_support::readFile;
using test_support::wallMicros;

constexpr int64_t kSecond = 1'000'000;
constexpr int64_t kWall = 1'700'000'000'000'000;  // the deputy's wall clock in core tests

// ---------------------------------------------------------------------------------------------
// Core logic with a fake ProcessControl.

class FakeControl : public ProcessControl {
 public:
  struct Signal {
    int root;
    int signal;
  };
  Expected<int> start(const CommandSpec& spec) override {
    if (fail_starts) return unexpected("no more processes");
    starts.push_back(spec);
    alive.insert(next_pid);
    return next_pid++;
  }
  void signalTree(int root, int signal) override { signals.push_back({root, signal}); }
  bool treeAlive(int root) override { return alive.count(root) != 0; }

  std::vector<CommandSpec> starts;
  std::vector<Signal> signals;
  std::set<int> alive;  // roots whose tree is alive
  int next_pid = 100;
  bool fail_starts = false;
};

procman_lcm::cmd_desired_t entry(const std::string& id, const std::string& exec, int32_t runid,
                                 bool force_quit = false, bool respawn = false) {
  procman_lcm::cmd_desired_t d;
  d.cmd.command_id = id;
  d.cmd.exec_str = exec;
  d.cmd.group = "g";
  d.cmd.auto_respawn = respawn;
  d.cmd.stop_signal = SIGINT;
  d.cmd.stop_time_allowed = 2;
  d.desired_runid = runid;
  d.force_quit = force_quit;
  return d;
}

procman_lcm::orders_t orders(const std::vector<procman_lcm::cmd_desired_t>& cmds,
                             int64_t utime = kWall, const std::string& deputy = "dep") {
  procman_lcm::orders_t o;
  o.utime = utime;
  o.deputy_id = deputy;
  o.sheriff_id = "sheriff";
  o.cmds = cmds;
  o.ncmds = static_cast<int32_t>(cmds.size());
  return o;
}

struct DeputyCoreTest : ::testing::Test {
  FakeControl control;
  std::vector<std::pair<std::string, std::string>> said;
  DeputyCore core{"dep", control, [this](const std::string& id, const std::string& text) {
                    said.emplace_back(id, text);
                  }};
  int64_t now = 5 * kSecond;

  void apply(const std::vector<procman_lcm::cmd_desired_t>& cmds) {
    core.handleOrders(orders(cmds), kWall, now);
  }
  const DeputyCommand& cmd(const std::string& id) {
    const DeputyCommand* c = core.command(id);
    EXPECT_NE(c, nullptr) << id;
    static const DeputyCommand none;
    return c != nullptr ? *c : none;
  }
  // The process of `id` exits with `status` after `after_us`.
  void exit(const std::string& id, int status, int64_t after_us = 0) {
    now += after_us;
    const int pid = cmd(id).pid;
    control.alive.erase(pid);
    core.handleExit(pid, status, now);
  }
  bool saidSomething(const std::string& id, const std::string& fragment) const {
    for (const auto& [command_id, text] : said) {
      if (command_id == id && text.find(fragment) != std::string::npos) return true;
    }
    return false;
  }
};

TEST(DeputyBackoff, DoublesFromTenMillisecondsToOneSecondAndResets) {
  RespawnBackoff backoff;
  std::vector<int64_t> delays;
  for (int i = 0; i < 9; ++i) delays.push_back(backoff.next(200'000));
  EXPECT_EQ(delays, (std::vector<int64_t>{10'000, 20'000, 40'000, 80'000, 160'000, 320'000, 640'000,
                                          1'000'000, 1'000'000}));
  EXPECT_EQ(backoff.next(1'000'000), 10'000) << "a run of a second starts over";
  EXPECT_EQ(backoff.next(0), 20'000);
}

TEST_F(DeputyCoreTest, StartsAWantedCommandAndAdoptsItsRunId) {
  apply({entry("a", "sleep 100", 1)});
  ASSERT_EQ(control.starts.size(), 1u);
  EXPECT_EQ(control.starts[0].exec, "sleep 100");
  EXPECT_EQ(control.starts[0].group, "g");
  EXPECT_EQ(cmd("a").pid, 100);
  EXPECT_EQ(cmd("a").actual_runid, 1);
  EXPECT_TRUE(core.takeChanged());
  EXPECT_FALSE(core.takeChanged());

  apply({entry("a", "sleep 100", 1)});  // the same orders again: nothing to do
  EXPECT_EQ(control.starts.size(), 1u);
  EXPECT_TRUE(control.signals.empty());
  EXPECT_FALSE(core.takeChanged());
}

TEST_F(DeputyCoreTest, IgnoresOrdersForOtherDeputies) {
  core.handleOrders(orders({entry("a", "sleep 100", 1)}, kWall, "other"), kWall, now);
  EXPECT_TRUE(control.starts.empty());
  EXPECT_TRUE(core.commands().empty());
  EXPECT_TRUE(said.empty());
}

TEST_F(DeputyCoreTest, RefusesStaleOrdersAndSaysSo) {
  core.handleOrders(orders({entry("a", "sleep 100", 1)}, kWall - 61 * kSecond), kWall, now);
  EXPECT_TRUE(control.starts.empty());
  EXPECT_TRUE(saidSomething("", "stale orders")) << (said.empty() ? "" : said[0].second);
  core.handleOrders(orders({entry("a", "sleep 100", 1)}, kWall - 59 * kSecond), kWall, now);
  EXPECT_EQ(control.starts.size(), 1u) << "59 s old is still fresh";
}

TEST_F(DeputyCoreTest, StopSendsTheStopSignalThenSigkillOnATimer) {
  apply({entry("a", "sleep 100", 1)});
  apply({entry("a", "sleep 100", 1, /*force_quit=*/true)});
  ASSERT_EQ(control.signals.size(), 1u);
  EXPECT_EQ(control.signals[0].root, 100);
  EXPECT_EQ(control.signals[0].signal, SIGINT);
  ASSERT_TRUE(core.nextTimer().has_value());
  EXPECT_EQ(*core.nextTimer(), now + 2 * kSecond);

  apply({entry("a", "sleep 100", 1, true)});  // repeated orders do not signal again
  core.handleTimers(now + 2 * kSecond - 1);
  EXPECT_EQ(control.signals.size(), 1u);
  core.handleTimers(now + 2 * kSecond);
  ASSERT_EQ(control.signals.size(), 2u);
  EXPECT_EQ(control.signals[1].signal, SIGKILL);
  EXPECT_FALSE(core.nextTimer().has_value());

  exit("a", W_EXITCODE(0, SIGKILL), 2 * kSecond + 10);
  EXPECT_EQ(cmd("a").pid, 0);
  EXPECT_EQ(cmd("a").exit_status, W_EXITCODE(0, SIGKILL));
  EXPECT_EQ(cmd("a").actual_runid, 1);
  EXPECT_FALSE(core.nextTimer().has_value()) << "stopped on purpose: no respawn";
  EXPECT_EQ(control.starts.size(), 1u);
}

TEST_F(DeputyCoreTest, ARunIdChangeRestartsOnceTheProcessHasExited) {
  apply({entry("a", "sleep 100", 1)});
  apply({entry("a", "sleep 100", 2)});
  ASSERT_EQ(control.signals.size(), 1u);
  EXPECT_EQ(control.starts.size(), 1u) << "not before the old process is gone";
  EXPECT_EQ(cmd("a").actual_runid, 1);
  exit("a", W_EXITCODE(0, SIGINT), 1000);
  ASSERT_EQ(control.starts.size(), 2u);
  EXPECT_EQ(cmd("a").pid, 101);
  EXPECT_EQ(cmd("a").actual_runid, 2);
  EXPECT_FALSE(cmd("a").stop_sent);
}

TEST_F(DeputyCoreTest, AStoppedCommandWithForceQuitAdoptsTheDesiredRunId) {
  apply({entry("a", "true", 7, /*force_quit=*/true)});
  EXPECT_TRUE(control.starts.empty());
  EXPECT_EQ(cmd("a").actual_runid, 7);
  apply({entry("a", "true", 8)});
  EXPECT_EQ(control.starts.size(), 1u);
}

TEST_F(DeputyCoreTest, ACommandThatRanToCompletionIsNotRerun) {
  apply({entry("a", "true", 1)});
  exit("a", 0, 3 * kSecond);
  apply({entry("a", "true", 1)});
  EXPECT_EQ(control.starts.size(), 1u);
  EXPECT_FALSE(core.nextTimer().has_value());
}

TEST_F(DeputyCoreTest, RespawnsWithBackoffWhileItKeepsDying) {
  apply({entry("a", "crash", 1, false, /*respawn=*/true)});
  std::vector<int64_t> delays;
  for (int i = 0; i < 9; ++i) {
    exit("a", W_EXITCODE(1, 0), 100'000);
    EXPECT_EQ(cmd("a").exit_status, 256);
    ASSERT_TRUE(core.nextTimer().has_value());
    delays.push_back(*core.nextTimer() - now);
    core.handleTimers(*core.nextTimer() - 1);
    EXPECT_EQ(cmd("a").pid, 0) << "not before its time";
    now = *core.nextTimer();
    core.handleTimers(now);
    EXPECT_NE(cmd("a").pid, 0);
    EXPECT_EQ(cmd("a").actual_runid, 1) << "a respawn keeps the run id";
  }
  EXPECT_EQ(delays, (std::vector<int64_t>{10'000, 20'000, 40'000, 80'000, 160'000, 320'000, 640'000,
                                          1'000'000, 1'000'000}));
  exit("a", W_EXITCODE(1, 0), 5 * kSecond);
  EXPECT_EQ(*core.nextTimer() - now, 10'000) << "it ran long enough: the backoff starts over";

  // Stopping it cancels the pending respawn.
  apply({entry("a", "crash", 1, /*force_quit=*/true, true)});
  EXPECT_FALSE(core.nextTimer().has_value());
  core.handleTimers(now + 10 * kSecond);
  EXPECT_EQ(cmd("a").pid, 0);
}

TEST_F(DeputyCoreTest, CommandsMissingFromTheOrdersAreStoppedThenRemoved) {
  apply({entry("a", "sleep 100", 1), entry("b", "sleep 100", 1), entry("c", "true", 1, true)});
  ASSERT_EQ(core.commands().size(), 3u);
  apply({entry("a", "sleep 100", 1)});
  EXPECT_EQ(core.command("c"), nullptr) << "not running: removed at once";
  ASSERT_NE(core.command("b"), nullptr) << "running: removed once it has exited";
  EXPECT_TRUE(cmd("b").removing);
  ASSERT_EQ(control.signals.size(), 1u);
  EXPECT_EQ(control.signals[0].root, cmd("b").pid);
  exit("b", W_EXITCODE(0, SIGINT), 1000);
  EXPECT_EQ(core.command("b"), nullptr);
  ASSERT_EQ(core.commands().size(), 1u);
  EXPECT_EQ(core.commands()[0].spec.id, "a");
}

TEST_F(DeputyCoreTest, ADefinitionChangeAppliesFromTheNextStart) {
  apply({entry("a", "sleep 100", 1)});
  auto changed = entry("a", "sleep 200", 1);
  changed.cmd.group = "h";
  changed.cmd.stop_signal = SIGTERM;
  apply({changed});
  EXPECT_TRUE(control.signals.empty()) << "the running process is left alone";
  EXPECT_EQ(cmd("a").spec.exec, "sleep 200");
  EXPECT_EQ(cmd("a").spec.group, "h");
  changed.desired_runid = 2;
  apply({changed});
  ASSERT_EQ(control.signals.size(), 1u);
  EXPECT_EQ(control.signals[0].signal, SIGTERM) << "the new stop signal";
  exit("a", W_EXITCODE(0, SIGTERM), 1000);
  ASSERT_EQ(control.starts.size(), 2u);
  EXPECT_EQ(control.starts[1].exec, "sleep 200");
}

TEST_F(DeputyCoreTest, InvalidEntriesAreRefusedOnceAndLeaveTheCommandAlone) {
  apply({entry("a", "sleep 100", 1)});
  auto empty_id = entry("", "x", 1);
  auto empty_exec = entry("a", "   ", 2);
  auto duplicate = entry("b", "sleep 1", 1);
  auto negative = entry("c", "sleep 1", 1);
  negative.cmd.stop_time_allowed = -1;
  auto not_a_number = entry("d", "sleep 1", 1);
  not_a_number.cmd.stop_time_allowed = std::nanf("");
  auto bad_signal = entry("e", "sleep 1", 1);
  bad_signal.cmd.stop_signal = 0;
  auto bad_signal2 = entry("f", "sleep 1", 1);
  bad_signal2.cmd.stop_signal = 100;
  auto quote = entry("g", "echo 'oops", 1);
  const std::vector<procman_lcm::cmd_desired_t> all = {empty_id,   empty_exec,  duplicate,
                                                       duplicate,  negative,    not_a_number,
                                                       bad_signal, bad_signal2, quote};
  apply(all);
  EXPECT_EQ(said.size(), 8u);
  for (const auto& [id, text] : said) {
    EXPECT_EQ(id, "");
    EXPECT_NE(text.find("refusing"), std::string::npos) << text;
  }
  EXPECT_TRUE(saidSomething("", "empty command id"));
  EXPECT_TRUE(saidSomething("", "duplicate"));
  EXPECT_TRUE(saidSomething("", "empty command"));
  EXPECT_TRUE(saidSomething("", "stop_time_allowed"));
  EXPECT_TRUE(saidSomething("", "stop_signal 100"));
  EXPECT_TRUE(saidSomething("", "unterminated single quote"));
  // "a" keeps running as it was; "b" (first of the duplicates) starts; nothing else does.
  EXPECT_EQ(cmd("a").pid, 100);
  EXPECT_EQ(cmd("a").spec.exec, "sleep 100");
  EXPECT_TRUE(control.signals.empty());
  ASSERT_EQ(control.starts.size(), 2u);
  EXPECT_EQ(control.starts[1].id, "b");
  EXPECT_EQ(core.commands().size(), 2u);

  said.clear();
  apply(all);
  EXPECT_TRUE(said.empty()) << "said once, not at every orders message";
  apply({entry("a", "sleep 100", 1), duplicate});
  apply(all);
  EXPECT_EQ(said.size(), 8u) << "said again after it had gone away";
}

TEST_F(DeputyCoreTest, AStartFailureIsReportedAndRetriedWhenRespawning) {
  control.fail_starts = true;
  apply({entry("a", "prog", 1, false, true)});
  EXPECT_EQ(cmd("a").pid, 0);
  EXPECT_EQ(cmd("a").actual_runid, 1);
  EXPECT_TRUE(WIFEXITED(cmd("a").exit_status));
  EXPECT_EQ(WEXITSTATUS(cmd("a").exit_status), 127);
  EXPECT_TRUE(saidSomething("a", "no more processes"));
  ASSERT_TRUE(core.nextTimer().has_value());
  control.fail_starts = false;
  now = *core.nextTimer();
  core.handleTimers(now);
  EXPECT_EQ(cmd("a").pid, 100);
}

TEST_F(DeputyCoreTest, ATreeLeftAfterTheMainProcessExitsIsKilledAtTheDeadline) {
  apply({entry("a", "sh", 1)});
  const int pid = cmd("a").pid;
  apply({entry("a", "sh", 1, true)});
  // The shell dies of SIGINT, its background children ignore it.
  now += 1000;
  core.handleExit(pid, W_EXITCODE(0, SIGINT), now);  // the tree is still alive
  EXPECT_EQ(cmd("a").pid, 0);
  ASSERT_TRUE(core.nextTimer().has_value());
  EXPECT_EQ(*core.nextTimer(), now - 1000 + 2 * kSecond);
  core.handleTimers(*core.nextTimer());
  ASSERT_EQ(control.signals.size(), 2u);
  EXPECT_EQ(control.signals[1].root, pid);
  EXPECT_EQ(control.signals[1].signal, SIGKILL);
  EXPECT_FALSE(core.nextTimer().has_value());
}

TEST_F(DeputyCoreTest, ShutdownStopsEverythingAndKillsWhatIsLeftAfterASecond) {
  apply({entry("a", "sleep 100", 1), entry("b", "sleep 100", 1, false, true),
         entry("c", "true", 1, true)});
  core.beginShutdown(now);
  EXPECT_TRUE(core.shuttingDown());
  ASSERT_EQ(control.signals.size(), 2u);
  EXPECT_FALSE(core.shutdownComplete(now));
  EXPECT_EQ(*core.nextTimer(), now + DeputyCore::kShutdownGraceUs);
  exit("a", W_EXITCODE(0, SIGINT), 1000);
  EXPECT_FALSE(core.nextTimer().has_value() && *core.nextTimer() < now) << "no respawn";
  core.handleTimers(now - 1000 + DeputyCore::kShutdownGraceUs);
  ASSERT_EQ(control.signals.size(), 3u);
  EXPECT_EQ(control.signals[2].root, cmd("b").pid);
  EXPECT_EQ(control.signals[2].signal, SIGKILL);
  core.handleOrders(orders({entry("d", "sleep 1", 1)}), kWall, now);
  EXPECT_EQ(core.command("d"), nullptr) << "no orders while exiting";
  exit("b", W_EXITCODE(0, SIGKILL), kSecond);
  EXPECT_TRUE(core.shutdownComplete(now));
  EXPECT_EQ(control.starts.size(), 2u);
}

TEST_F(DeputyCoreTest, ShutdownGivesUpOnProcessesThatNeverDie) {
  apply({entry("a", "sleep 100", 1)});
  core.beginShutdown(now);
  EXPECT_FALSE(core.shutdownComplete(now + DeputyCore::kShutdownLimitUs - 1));
  EXPECT_TRUE(core.shutdownComplete(now + DeputyCore::kShutdownLimitUs));
}

// ---------------------------------------------------------------------------------------------
// Helpers.

TEST(DeputyOutputBatcher, BatchesPerCommandBySizeAndAge) {
  OutputBatcher batcher;
  EXPECT_FALSE(batcher.nextDue().has_value());
  batcher.add("a", "hello ", 0);
  batcher.add("b", "x", 3000);
  batcher.add("a", "world\n", 5000);
  EXPECT_EQ(*batcher.nextDue(), OutputBatcher::kMaxDelayUs);
  EXPECT_TRUE(batcher.take(OutputBatcher::kMaxDelayUs - 1).empty());
  auto batches = batcher.take(OutputBatcher::kMaxDelayUs);
  ASSERT_EQ(batches.size(), 1u);
  EXPECT_EQ(batches[0], (std::pair<std::string, std::string>{"a", "hello world\n"}));

  batcher.add("c", std::string(OutputBatcher::kMaxBatchBytes * 2 + 5, 'z'), 20'000);
  EXPECT_EQ(*batcher.nextDue(), 3000 + OutputBatcher::kMaxDelayUs) << "b is older";
  batches = batcher.take(20'000);
  ASSERT_EQ(batches.size(), 4u) << "b by age, c at once because it is full, in pieces";
  EXPECT_EQ(batches[0].first, "b");
  EXPECT_EQ(batches[1].second.size(), OutputBatcher::kMaxBatchBytes);
  EXPECT_EQ(batches[3].second.size(), 5u);
  batcher.add("d", "tail", 30'000);
  EXPECT_EQ(batcher.take(30'000, /*all=*/true).size(), 1u);
  EXPECT_TRUE(batcher.empty());
}

TEST(DeputyProcStats, ParsesProcessStat) {
  const auto entry = parseProcessStat(
      "4242 (my (odd) prog) S 4000 4242 4242 34816 4242 4194560 300 0 0 0 "
      "150 25 7 3 20 0 1 0 123456 10485760 256 18446744073709551615 1 1 0 0 0 0 0 0 0 0 0 0 17 "
      "1 0 0 0 0 0");
  ASSERT_TRUE(entry.has_value());
  EXPECT_EQ(entry->pid, 4242);
  EXPECT_EQ(entry->state, 'S');
  EXPECT_EQ(entry->ppid, 4000);
  EXPECT_EQ(entry->pgrp, 4242);
  EXPECT_EQ(entry->session, 4242);
  EXPECT_EQ(entry->cpu_ticks, 150u + 25u + 7u + 3u);
  EXPECT_EQ(entry->vsize_bytes, 10485760);
  EXPECT_EQ(entry->rss_pages, 256);
  EXPECT_FALSE(parseProcessStat("").has_value());
  EXPECT_FALSE(parseProcessStat("12 (x) S 1 2").has_value());
}

TEST(DeputyProcStats, TreeIsDescendantsSessionAndGroup) {
  auto p = [](int pid, int ppid, int pgrp, int session, char state = 'S') {
    ProcessEntry e;
    e.pid = pid;
    e.ppid = ppid;
    e.pgrp = pgrp;
    e.session = session;
    e.state = state;
    return e;
  };
  const std::vector<ProcessEntry> table = {
      p(1, 0, 1, 1),         p(50, 1, 50, 50),       // init, the deputy
      p(100, 50, 100, 100),                          // the command
      p(101, 100, 100, 100), p(102, 101, 102, 102),  // child; grandchild in its own session
      p(103, 50, 100, 100),                          // orphan adopted by the deputy, same session
      p(104, 103, 104, 104),                         // its child, elsewhere
      p(105, 1, 105, 100),                           // orphan of init, same session
      p(200, 50, 200, 200),  p(201, 200, 200, 200, 'Z')};  // another command
  std::set<int> tree;
  for (const ProcessEntry* e : processTree(table, 100, 50)) tree.insert(e->pid);
  EXPECT_EQ(tree, (std::set<int>{100, 101, 102, 103, 104, 105}));
  tree.clear();
  for (const ProcessEntry* e : processTree(table, 999, 50)) tree.insert(e->pid);
  EXPECT_TRUE(tree.empty());
  EXPECT_FALSE(table.back().alive());
}

TEST(DeputyProcStats, TreesRememberMembersThatEscaped) {
  auto p = [](int pid, int ppid, int session, uint64_t start) {
    ProcessEntry e;
    e.pid = pid;
    e.ppid = ppid;
    e.pgrp = session;
    e.session = session;
    e.state = 'S';
    e.start_ticks = start;
    return e;
  };
  ProcessTrees trees;
  // 101 has its own session but is a child of the command 100: a member.
  auto pids = [&](const std::vector<ProcessEntry>& table) {
    std::set<int> result;
    for (const ProcessEntry& e : trees.members(100, table)) result.insert(e.pid);
    return result;
  };
  EXPECT_EQ(pids({p(100, 50, 100, 7), p(101, 100, 101, 8), p(102, 101, 101, 9)}),
            (std::set<int>{100, 101, 102}));
  // 100 is gone; 101 was adopted elsewhere and links to nothing, but is remembered.
  EXPECT_EQ(pids({p(101, 50, 101, 8), p(102, 101, 101, 9), p(103, 102, 101, 10)}),
            (std::set<int>{101, 102, 103}));
  // A pid reused by another process (another start time) is not a member.
  EXPECT_EQ(pids({p(101, 50, 101, 99)}), (std::set<int>{}));
  EXPECT_EQ(pids({p(101, 50, 101, 8)}), (std::set<int>{})) << "forgotten once empty";

  // Pruning forgets the members that are gone, so trees of long-gone commands do not pile up.
  EXPECT_EQ(pids({p(100, 50, 100, 7), p(101, 100, 101, 8)}), (std::set<int>{100, 101}));
  trees.prune({p(101, 50, 101, 8)});
  EXPECT_EQ(pids({p(101, 50, 101, 8)}), (std::set<int>{101}));
  trees.prune({});
  EXPECT_EQ(pids({p(101, 50, 101, 8)}), (std::set<int>{}));
}

TEST(DeputyProcStats, ParsesCpuTimesAndMemory) {
  const auto cpu =
      parseCpuTimes("cpu  100 5 50 1000 20 3 2 1 0 0\ncpu0 50 2 25 500 10 1 1 0 0 0\nintr 1 2 3\n");
  ASSERT_TRUE(cpu.has_value());
  EXPECT_EQ(cpu->busy, 100u + 5u + 50u + 3u + 2u + 1u);
  EXPECT_EQ(cpu->total, cpu->busy + 1000u + 20u);
  EXPECT_FALSE(parseCpuTimes("nothing here").has_value());

  const MemoryInfo mem = parseMemoryInfo(
      "MemTotal:       16000000 kB\nMemFree:         1000000 kB\nMemAvailable:    8000000 kB\n"
      "SwapTotal:       2000000 kB\nSwapFree:        1500000 kB\n");
  EXPECT_EQ(mem.phys_total_bytes, 16000000LL * 1024);
  EXPECT_EQ(mem.phys_free_bytes, 8000000LL * 1024);
  EXPECT_EQ(mem.swap_total_bytes, 2000000LL * 1024);
  EXPECT_EQ(mem.swap_free_bytes, 1500000LL * 1024);
  EXPECT_EQ(parseMemoryInfo("MemTotal: 4 kB\nMemFree: 2 kB\n").phys_free_bytes, 2048);
}

// ---------------------------------------------------------------------------------------------
// The real thicket-deputy, with this test as its sheriff.

// A thicket-deputy process; terminated and reaped when the test ends.
class DeputyChild : public test_support::ChildProcess {
 public:
  DeputyChild(const std::string& id, const std::string& url, const std::string& log_path = "")
      : ChildProcess(argv(id, url, log_path), test_support::uniqueTempPath("deputy")) {}

 private:
  static std::vector<std::string> argv(const std::string& id, const std::string& url,
                                       const std::string& log_path) {
    std::vector<std::string> words = {THICKET_DEPUTY, "-i", id, "--lcm-url", url};
    if (!log_path.empty()) {
      words.push_back("-l");
      words.push_back(log_path);
    }
    return words;
  }
};

// The sheriff side: sends orders (again every 200 ms, as UDP may drop and the deputy may still
// be discovering) and collects info and output.
class Sheriff {
 public:
  explicit Sheriff(const std::string& url, std::string deputy_id)
      : lcm_(url), deputy_id_(std::move(deputy_id)) {
    lcm_.subscribe("PM_INFO", &Sheriff::onInfo, this);
    lcm_.subscribe("PM_OUTPUT", &Sheriff::onOutput, this);
  }
  bool good() { return lcm_.good(); }

  void order(const std::vector<procman_lcm::cmd_desired_t>& cmds, int64_t age_us = 0) {
    orders_ = orders(cmds, 0, deputy_id_);
    orders_.sheriff_id = "test-sheriff";
    age_us_ = age_us;
    ordering_ = true;
    send();
  }

  // Handles messages until `condition` holds (true) or `seconds` pass (false).
  bool waitFor(const std::function<bool()>& condition, double seconds = 10.0) {
    using Clock = std::chrono::steady_clock;
    const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
    auto next_send = Clock::now() + std::chrono::milliseconds(200);
    while (!condition()) {
      const auto now = Clock::now();
      if (now >= deadline) return false;
      if (ordering_ && now >= next_send) {
        send();
        next_send = now + std::chrono::milliseconds(200);
      }
      lcm_.handleTimeout(20);
    }
    return true;
  }

  bool haveInfo() const { return info_count_ > 0; }
  const procman_lcm::deputy_info_t& info() const { return info_; }
  const procman_lcm::cmd_status_t* status(const std::string& id) const {
    for (const auto& s : info_.cmds) {
      if (s.cmd.command_id == id) return &s;
    }
    return nullptr;
  }
  int pid(const std::string& id) const {
    const auto* s = status(id);
    return s != nullptr ? s->pid : -1;
  }
  // Every pid `id` was reported with, in order.
  const std::vector<int>& pids(const std::string& id) { return pids_[id]; }
  const std::vector<int>& exitCodes(const std::string& id) { return exit_codes_[id]; }
  std::string output(const std::string& id) const {
    const auto it = output_.find(id);
    return it == output_.end() ? std::string() : it->second;
  }

 private:
  void send() {
    orders_.utime = wallMicros() - age_us_;
    lcm_.publish("PM_ORDERS", &orders_);
  }
  void onInfo(const lcm::ReceiveBuffer*, const std::string&, const procman_lcm::deputy_info_t* m) {
    if (m->deputy_id != deputy_id_) return;
    info_ = *m;
    ++info_count_;
    for (const auto& s : m->cmds) {
      auto& pids = pids_[s.cmd.command_id];
      if (s.pid != 0 && (pids.empty() || pids.back() != s.pid)) pids.push_back(s.pid);
      if (s.pid == 0) exit_codes_[s.cmd.command_id].push_back(s.exit_code);
    }
  }
  void onOutput(const lcm::ReceiveBuffer*, const std::string&, const procman_lcm::output_t* m) {
    if (m->deputy_id != deputy_id_) return;
    for (int i = 0; i < m->num_commands; ++i) output_[m->command_ids[i]] += m->text[i];
  }

  lcm::LCM lcm_;
  std::string deputy_id_;
  procman_lcm::orders_t orders_;
  int64_t age_us_ = 0;
  bool ordering_ = false;
  procman_lcm::deputy_info_t info_;
  int info_count_ = 0;
  std::map<std::string, std::vector<int>> pids_;
  std::map<std::string, std::vector<int>> exit_codes_;
  std::map<std::string, std::string> output_;
};

procman_lcm::cmd_desired_t command(const std::string& id, const std::string& exec, int32_t runid,
                                   bool force_quit = false, bool respawn = false,
                                   float stop_time_allowed = 7) {
  auto d = entry(id, exec, runid, force_quit, respawn);
  d.cmd.stop_time_allowed = stop_time_allowed;
  return d;
}

// One deputy and its sheriff in a private network; the deputy is serving when this returns.
struct DeputyProcessTest : ::testing::Test {
  std::string url = isolatedUrl();
  std::string id = "test-deputy";
  std::string log_path =
      ::testing::TempDir() + "/deputy_log_" + std::to_string(::getpid()) + ".txt";
  Sheriff sheriff{url, id};
  DeputyChild deputy{id, url, log_path};

  void SetUp() override {
    ASSERT_TRUE(sheriff.good()) << url;
    ASSERT_TRUE(sheriff.waitFor([&] { return sheriff.haveInfo(); })) << "no info from the deputy:\n"
                                                                     << deputy.output();
  }
  void TearDown() override {
    if (HasFailure()) std::fprintf(stderr, "deputy log:\n%s\n", deputy.output().c_str());
  }
  bool running(const std::string& cmd, int32_t runid) {
    const auto* s = sheriff.status(cmd);
    return s != nullptr && s->pid > 0 && s->actual_runid == runid;
  }
  bool stopped(const std::string& cmd) {
    const auto* s = sheriff.status(cmd);
    return s != nullptr && s->pid == 0;
  }
};

TEST_F(DeputyProcessTest, StartsAndStopsACommand) {
  sheriff.order({command("sleeper", "sleep 1000", 1)});
  ASSERT_TRUE(sheriff.waitFor([&] { return running("sleeper", 1); }));
  const int pid = sheriff.pid("sleeper");
  EXPECT_TRUE(processAlive(pid));
  EXPECT_EQ(sheriff.status("sleeper")->cmd.exec_str, "sleep 1000");
  EXPECT_EQ(sheriff.status("sleeper")->cmd.group, "g");
  EXPECT_GT(sheriff.info().phys_mem_total_bytes, 0);
  // Memory is reported once the 1 Hz sample has seen the process.
  ASSERT_TRUE(sheriff.waitFor([&] { return sheriff.status("sleeper")->mem_rss_bytes > 0; }));

  sheriff.order({command("sleeper", "sleep 1000", 1, /*force_quit=*/true)});
  ASSERT_TRUE(sheriff.waitFor([&] { return stopped("sleeper"); }));
  const int status = sheriff.status("sleeper")->exit_code;
  EXPECT_TRUE(WIFSIGNALED(status)) << status;
  EXPECT_EQ(WTERMSIG(status), SIGINT);
  EXPECT_EQ(sheriff.status("sleeper")->actual_runid, 1);
  EXPECT_TRUE(sheriff.waitFor([&] { return !processAlive(pid); }));
}

TEST_F(DeputyProcessTest, ANewRunIdRestartsWithANewProcess) {
  sheriff.order({command("sleeper", "sleep 1000", 1)});
  ASSERT_TRUE(sheriff.waitFor([&] { return running("sleeper", 1); }));
  const int first = sheriff.pid("sleeper");
  sheriff.order({command("sleeper", "sleep 1000", 2)});
  ASSERT_TRUE(sheriff.waitFor([&] { return running("sleeper", 2); }));
  EXPECT_NE(sheriff.pid("sleeper"), first);
  EXPECT_TRUE(sheriff.waitFor([&] { return !processAlive(first); }));
}

TEST_F(DeputyProcessTest, RespawnsACommandThatExits) {
  sheriff.order({command("crasher", "sh -c 'sleep 0.2; exit 1'", 1, false, /*respawn=*/true)});
  ASSERT_TRUE(sheriff.waitFor([&] { return sheriff.pids("crasher").size() >= 2; }));
  const std::vector<int> pids = sheriff.pids("crasher");
  EXPECT_NE(pids[0], pids[1]);
  EXPECT_EQ(sheriff.status("crasher")->actual_runid, 1);
  ASSERT_TRUE(sheriff.waitFor([&] { return !sheriff.exitCodes("crasher").empty(); }));
  EXPECT_EQ(sheriff.exitCodes("crasher")[0], W_EXITCODE(1, 0));

  sheriff.order({command("crasher", "sh -c 'sleep 0.2; exit 1'", 1, true, true)});
  ASSERT_TRUE(sheriff.waitFor([&] { return stopped("crasher"); }));
}

TEST_F(DeputyProcessTest, EscalatesToSigkillWhenTheStopSignalIsIgnored) {
  const std::string exec = "sh -c 'trap \"\" INT; echo ready; while :; do sleep 0.1; done'";
  sheriff.order({command("stubborn", exec, 1, false, false, /*stop_time_allowed=*/1)});
  ASSERT_TRUE(sheriff.waitFor([&] {
    return running("stubborn", 1) && sheriff.output("stubborn").find("ready") != std::string::npos;
  }));
  sheriff.order({command("stubborn", exec, 1, /*force_quit=*/true, false, 1)});
  ASSERT_TRUE(sheriff.waitFor([&] {
    return stopped("stubborn") &&
           sheriff.output("stubborn").find("sending SIGKILL") != std::string::npos;
  })) << sheriff.output("stubborn");
  const int status = sheriff.status("stubborn")->exit_code;
  EXPECT_TRUE(WIFSIGNALED(status)) << status;
  EXPECT_EQ(WTERMSIG(status), SIGKILL);
}

TEST_F(DeputyProcessTest, KillsTheWholeProcessTree) {
  // Background children of a non-interactive shell ignore SIGINT: they outlive the shell and
  // must still go, at the SIGKILL deadline.
  const std::string exec =
      "sh -c 'sleep 1000 & echo child $!; setsid sleep 1000 & echo child $!; wait'";
  sheriff.order({command("tree", exec, 1, false, false, 1)});
  std::vector<int> children;
  ASSERT_TRUE(sheriff.waitFor([&] {
    std::istringstream text(sheriff.output("tree"));
    children.clear();
    for (std::string word; text >> word;) {
      if (word == "child" && text >> word) children.push_back(std::atoi(word.c_str()));
    }
    return running("tree", 1) && children.size() == 2;
  })) << sheriff.output("tree");
  for (int child : children) EXPECT_TRUE(processAlive(child)) << child;
  const int shell = sheriff.pid("tree");

  sheriff.order({command("tree", exec, 1, /*force_quit=*/true, false, 1)});
  ASSERT_TRUE(sheriff.waitFor([&] { return stopped("tree"); }));
  ASSERT_TRUE(sheriff.waitFor([&] {
    return !processAlive(shell) && !processAlive(children[0]) && !processAlive(children[1]);
  })) << "still alive: "
      << processAlive(shell) << processAlive(children[0]) << processAlive(children[1]);
}

TEST_F(DeputyProcessTest, CapturesOutput) {
  sheriff.order({command("talker", "sh -c 'echo hello from \"$0\"; echo to stderr >&2' x", 1)});
  ASSERT_TRUE(sheriff.waitFor([&] {
    const std::string out = sheriff.output("talker");
    return out.find("hello from x\n") != std::string::npos &&
           out.find("to stderr\n") != std::string::npos;
  })) << sheriff.output("talker");
  ASSERT_TRUE(sheriff.waitFor([&] { return stopped("talker"); }));
  EXPECT_EQ(sheriff.status("talker")->exit_code, 0);
  EXPECT_EQ(sheriff.status("talker")->actual_runid, 1) << "ran to completion, not rerun";
}

TEST_F(DeputyProcessTest, RunsWithoutAShellWithAssignmentsAndTheDeputysEnvironment) {
  sheriff.order(
      {command("env", "GREETING='hi there' sh -c 'echo \"[$GREETING]\" \"$0\"' $HOME", 1)});
  const std::string home = std::getenv("HOME") != nullptr ? std::getenv("HOME") : "$HOME";
  ASSERT_TRUE(sheriff.waitFor([&] {
    return sheriff.output("env").find("[hi there] " + home + "\n") != std::string::npos;
  })) << sheriff.output("env");
}

TEST_F(DeputyProcessTest, AProgramThatCannotBeExecutedIsReported) {
  sheriff.order({command("missing", "/nonexistent/thicket-program --flag", 1)});
  ASSERT_TRUE(sheriff.waitFor([&] {
    return stopped("missing") && sheriff.status("missing")->actual_runid == 1 &&
           sheriff.output("missing").find("cannot execute") != std::string::npos;
  })) << sheriff.output("missing");
  const int status = sheriff.status("missing")->exit_code;
  EXPECT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 127);
}

TEST_F(DeputyProcessTest, RemovesCommandsMissingFromTheOrders) {
  sheriff.order({command("keep", "sleep 1000", 1), command("drop", "sleep 1000", 1)});
  ASSERT_TRUE(sheriff.waitFor([&] { return running("keep", 1) && running("drop", 1); }));
  const int dropped = sheriff.pid("drop");
  const int kept = sheriff.pid("keep");
  sheriff.order({command("keep", "sleep 1000", 1)});
  ASSERT_TRUE(sheriff.waitFor([&] { return sheriff.status("drop") == nullptr; }));
  EXPECT_EQ(sheriff.pid("keep"), kept);
  EXPECT_TRUE(sheriff.waitFor([&] { return !processAlive(dropped); }));
  EXPECT_TRUE(processAlive(kept));
}

TEST_F(DeputyProcessTest, RefusesStaleAndInvalidOrders) {
  sheriff.order({command("late", "sleep 1000", 1)}, /*age_us=*/120 * kSecond);
  ASSERT_TRUE(sheriff.waitFor(
      [&] { return sheriff.output("").find("stale orders") != std::string::npos; }));
  EXPECT_EQ(sheriff.status("late"), nullptr);

  sheriff.order({command("ok", "sleep 1000", 1), command("bad", "echo 'unterminated", 1)});
  ASSERT_TRUE(sheriff.waitFor([&] {
    return running("ok", 1) &&
           sheriff.output("").find("refusing command 'bad'") != std::string::npos;
  })) << sheriff.output("");
  EXPECT_EQ(sheriff.status("bad"), nullptr);
}

TEST_F(DeputyProcessTest, ASecondDeputyWithTheSameIdRefusesToRun) {
  DeputyChild twin(id, url);
  ASSERT_TRUE(twin.waitExit(10.0));
  EXPECT_TRUE(WIFEXITED(twin.status()));
  EXPECT_EQ(WEXITSTATUS(twin.status()), kDeputyExitConflict);
  EXPECT_NE(twin.output().find("another deputy with id 'test-deputy'"), std::string::npos)
      << twin.output();
  // The first one still serves.
  sheriff.order({command("sleeper", "sleep 1000", 1)});
  EXPECT_TRUE(sheriff.waitFor([&] { return running("sleeper", 1); }));
}

TEST_F(DeputyProcessTest, SigtermStopsEveryCommandAndExitsCleanly) {
  const std::string stubborn = "sh -c 'trap \"\" INT; echo ready; while :; do sleep 0.1; done'";
  sheriff.order({command("sleeper", "sleep 1000", 1), command("stubborn", stubborn, 1)});
  ASSERT_TRUE(sheriff.waitFor([&] {
    return running("sleeper", 1) && running("stubborn", 1) &&
           sheriff.output("stubborn").find("ready") != std::string::npos;
  }));
  const int sleeper = sheriff.pid("sleeper");
  const int shell = sheriff.pid("stubborn");
  ASSERT_EQ(::kill(deputy.pid(), SIGTERM), 0);
  ASSERT_TRUE(deputy.waitExit(10.0));
  EXPECT_TRUE(WIFEXITED(deputy.status()));
  EXPECT_EQ(WEXITSTATUS(deputy.status()), kDeputyExitOk);
  EXPECT_TRUE(sheriff.waitFor([&] { return !processAlive(sleeper) && !processAlive(shell); }));
  const std::string log = readFile(log_path);
  EXPECT_NE(log.find("received signal 15"), std::string::npos) << log;
  EXPECT_NE(log.find("[sleeper] started pid " + std::to_string(sleeper)), std::string::npos) << log;
}

TEST_F(DeputyProcessTest, ReportsCpuAndMemoryOfTheProcessTree) {
  // The shell waits; its background child does the work, and counts for the command.
  sheriff.order({command("busy", "sh -c 'sh -c \"while :; do :; done\" & wait'", 1)});
  ASSERT_TRUE(sheriff.waitFor([&] {
    const auto* s = sheriff.status("busy");
    return s != nullptr && s->pid > 0 && s->cpu_usage > 0.05f && s->mem_rss_bytes > 0 &&
           s->mem_vsize_bytes >= s->mem_rss_bytes;
  }));
  EXPECT_GT(sheriff.info().phys_mem_total_bytes, 0);
  EXPECT_GE(sheriff.info().cpu_load, 0.0f);
  EXPECT_LE(sheriff.info().cpu_load, 1.0f);
}

}  // namespace
}  // namespace thicket::procman
