// thicket-sheriff and thicket-deputy together, as a user runs them: the test writes sheets,
// drives the sheriff through its stdin, reads its stdout (status tables, command output, script
// messages), and listens on PM_INFO / PM_ORDERS / PM_OUTPUT itself for the truth (pids, run
// ids, which sheriffs give orders). Everything happens in a private network namespace; every
// wait is for a condition with a deadline; every process started is gone when a test ends.
#include <signal.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>
#include <procman_lcm/deputy_info_t.hpp>
#include <procman_lcm/orders_t.hpp>
#include <procman_lcm/output_t.hpp>

#include "procman_test_support.h"

namespace thicket::procman {
namespace {

using test_support::ChildProcess;
using test_support::DescendantReaper;
using test_support::processAlive;

constexpr double kDeadline = 15.0;  // seconds any awaited condition may take

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> result;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) result.push_back(line);
  return result;
}

// ---------------------------------------------------------------------------------------------
// What the sheriff prints.

// One line of a status table: "COMMAND DEPUTY STATUS PID RUN CPU% RSS-MB EXIT".
struct Row {
  std::string path;
  std::string deputy;
  std::string status;
  int pid = 0;         // 0 for "-"
  std::string actual;  // the reported run id, "-" before any report
  int desired = 0;     // the wanted run id
  std::string exit;    // "-" while running
  bool runIds(int runid) const { return actual == std::to_string(runid) && desired == runid; }
};
using Table = std::map<std::string, Row>;  // by path

std::optional<Row> parseRow(const std::string& line) {
  static const std::regex row(
      R"(^(\S+) +(\S+(?: \(!\))?) +(Unknown|Starting \(Command Sent\)|Restarting \(Command Sent\)|)"
      R"(Running|Stopping \(Command Sent\)|Removing \(Command Sent\)|Stopped \(OK\)|)"
      R"(Stopped \(Error\)) +(\d+|-) +(\d+|-)/(\d+) +\S+ +\S+ +(.+)$)");
  std::smatch m;
  if (!std::regex_match(line, m, row)) return std::nullopt;
  Row r;
  r.path = m[1];
  r.deputy = m[2];
  r.status = m[3];
  r.pid = m[4] == "-" ? 0 : std::stoi(m[4]);
  r.actual = m[5];
  r.desired = std::stoi(m[6]);
  r.exit = m[7];
  return r;
}

// Every complete status table printed ("---- status HH:MM:SS ----" ... "----"), in order.
std::vector<Table> parseTables(const std::string& output) {
  std::vector<Table> tables;
  std::optional<Table> open;
  for (const std::string& line : lines(output)) {
    if (line.rfind("---- status ", 0) == 0) {
      open.emplace();
    } else if (open && line == "----") {
      tables.push_back(std::move(*open));
      open.reset();
    } else if (open) {
      if (auto r = parseRow(line)) (*open)[r->path] = *r;
    }
  }
  return tables;
}

// A thicket-sheriff with its stdin on a pipe and its stdout in a file. Status tables are
// reprinted on every change (at most every 0.1 s), so the last one shows the sheriff's view.
class SheriffProcess : public ChildProcess {
 public:
  SheriffProcess(const std::vector<std::string>& argv, const std::string& output_path)
      : ChildProcess(argv, output_path, /*stdin_pipe=*/true) {}

  void send(const std::string& line) { EXPECT_TRUE(write(line + "\n")) << line; }

  std::vector<Table> tables() const { return parseTables(output()); }
  std::optional<Row> row(const std::string& path) const {
    const std::vector<Table> all = tables();
    if (all.empty()) return std::nullopt;
    const auto it = all.back().find(path);
    if (it == all.back().end()) return std::nullopt;
    return it->second;
  }
  // Every state of `path` the sheriff printed, in order.
  std::vector<Row> history(const std::string& path) const {
    std::vector<Row> rows;
    for (const Table& table : tables()) {
      const auto it = table.find(path);
      if (it != table.end()) rows.push_back(it->second);
    }
    return rows;
  }
  bool says(const std::string& text) const { return output().find(text) != std::string::npos; }
  // The sheriff id from "[sheriff] ID commanding|observing ...".
  std::string id() const {
    static const std::regex first(R"(^\[sheriff\] (\S+) (commanding|observing))");
    for (const std::string& line : lines(output())) {
      std::smatch m;
      if (std::regex_search(line, m, first)) return m[1];
    }
    return {};
  }
};

// ---------------------------------------------------------------------------------------------
// What the deputies and sheriffs say on LCM.

class Observer {
 public:
  struct Truth {
    int pid = 0;
    int runid = 0;
    int exit_code = 0;
    std::vector<int> pids;  // every pid reported, in order
  };
  struct Orders {
    std::string sheriff;
    std::string deputy;
    std::string command;
    int32_t desired_runid;
    bool force_quit;
  };

  explicit Observer(const std::string& url) : lcm_(url) {
    lcm_.subscribe("PM_INFO", &Observer::onInfo, this);
    lcm_.subscribe("PM_ORDERS", &Observer::onOrders, this);
    lcm_.subscribe("PM_OUTPUT", &Observer::onOutput, this);
  }
  bool good() { return lcm_.good(); }

  // Handles what arrives within 10 ms.
  void pump() {
    if (lcm_.handleTimeout(10) > 0) {
      for (int i = 0; i < 1000 && lcm_.handleTimeout(0) > 0; ++i) {
      }
    }
  }

  const Truth* command(const std::string& deputy, const std::string& id) const {
    const auto it = commands_.find({deputy, id});
    return it == commands_.end() ? nullptr : &it->second;
  }
  int pid(const std::string& deputy, const std::string& id) const {
    const Truth* truth = command(deputy, id);
    return truth == nullptr ? -1 : truth->pid;
  }
  // The deputy's clock at its latest report, 0 before any.
  int64_t lastInfoUtime(const std::string& deputy) const {
    const auto it = last_info_utime_.find(deputy);
    return it == last_info_utime_.end() ? 0 : it->second;
  }
  // Sheriff ids that sent orders, in order of their first orders.
  const std::vector<std::string>& sheriffs() const { return sheriffs_; }
  int ordersCount(const std::string& sheriff) const {
    return static_cast<int>(std::count_if(orders_.begin(), orders_.end(),
                                          [&](const Orders& o) { return o.sheriff == sheriff; }));
  }
  const std::vector<Orders>& orders() const { return orders_; }
  std::string output(const std::string& deputy, const std::string& id) const {
    const auto it = output_.find({deputy, id});
    return it == output_.end() ? std::string() : it->second;
  }

 private:
  void onInfo(const lcm::ReceiveBuffer*, const std::string&, const procman_lcm::deputy_info_t* m) {
    last_info_utime_[m->deputy_id] = m->utime;
    for (const procman_lcm::cmd_status_t& s : m->cmds) {
      Truth& truth = commands_[{m->deputy_id, s.cmd.command_id}];
      truth.pid = s.pid;
      truth.runid = s.actual_runid;
      truth.exit_code = s.exit_code;
      if (s.pid != 0 && (truth.pids.empty() || truth.pids.back() != s.pid)) {
        truth.pids.push_back(s.pid);
      }
    }
  }
  void onOrders(const lcm::ReceiveBuffer*, const std::string&, const procman_lcm::orders_t* m) {
    if (std::find(sheriffs_.begin(), sheriffs_.end(), m->sheriff_id) == sheriffs_.end()) {
      sheriffs_.push_back(m->sheriff_id);
    }
    for (const procman_lcm::cmd_desired_t& d : m->cmds) {
      orders_.push_back(
          {m->sheriff_id, m->deputy_id, d.cmd.command_id, d.desired_runid, d.force_quit != 0});
    }
    if (m->cmds.empty()) orders_.push_back({m->sheriff_id, m->deputy_id, "", 0, false});
  }
  void onOutput(const lcm::ReceiveBuffer*, const std::string&, const procman_lcm::output_t* m) {
    for (int i = 0; i < m->num_commands; ++i)
      output_[{m->deputy_id, m->command_ids[i]}] += m->text[i];
  }

  lcm::LCM lcm_;
  std::map<std::pair<std::string, std::string>, Truth> commands_;
  std::map<std::string, int64_t> last_info_utime_;
  std::vector<std::string> sheriffs_;
  std::vector<Orders> orders_;
  std::map<std::pair<std::string, std::string>, std::string> output_;
};

// ---------------------------------------------------------------------------------------------

struct ProcmanSystem : ::testing::Test {
  DescendantReaper reaper;  // first member: the last to go, it kills whatever is left
  std::string url = test_support::isolatedUrl();
  std::string dir = makeDirectory();
  Observer observer{url};
  std::vector<std::unique_ptr<ChildProcess>> children;  // stopped in reverse order

  ~ProcmanSystem() override { stopChildren(); }

  void SetUp() override {
    ::signal(SIGPIPE, SIG_IGN);  // a sheriff that died must not take the test along
    ASSERT_TRUE(observer.good()) << url;
  }
  void TearDown() override {
    if (HasFailure()) {
      for (const auto& child : children) {
        std::fprintf(stderr, "---- output of pid %d (%s) ----\n%s\n", child->pid(),
                     child->outputPath().c_str(), child->output().c_str());
      }
    }
    stopChildren();
    if (!HasFailure()) std::filesystem::remove_all(dir);
  }
  void stopChildren() {
    while (!children.empty()) children.pop_back();
  }

  static std::string makeDirectory() {
    std::string pattern = ::testing::TempDir() + "/procman_system_XXXXXX";
    const char* made = ::mkdtemp(pattern.data());
    EXPECT_NE(made, nullptr) << pattern;
    return pattern;
  }

  std::string writeSheet(const std::string& name, const std::string& text) {
    const std::string path = dir + "/" + name;
    std::ofstream(path) << text;
    return path;
  }

  ChildProcess& startDeputy(const std::string& id) {
    children.push_back(std::make_unique<ChildProcess>(
        std::vector<std::string>{THICKET_DEPUTY, "-i", id, "-u", url},
        dir + "/deputy_" + id + "_" + std::to_string(children.size()) + ".txt"));
    return *children.back();
  }

  SheriffProcess& startSheriff(const std::vector<std::string>& args) {
    std::vector<std::string> argv = {THICKET_SHERIFF, "-u", url, "--status-period", "0.1"};
    argv.insert(argv.end(), args.begin(), args.end());
    auto sheriff = std::make_unique<SheriffProcess>(
        argv, dir + "/sheriff_" + std::to_string(children.size()) + ".txt");
    SheriffProcess& result = *sheriff;
    children.push_back(std::move(sheriff));
    return result;
  }

  // Handles LCM until `condition` holds (true) or the deadline passes (false).
  bool waitFor(const std::function<bool()>& condition, double seconds = kDeadline) {
    return test_support::waitUntil(condition, seconds, [&] { observer.pump(); });
  }

  // The sheriff shows `path` Running with run id `runid`, the deputy reports the same pid and run
  // id, and the process lives. Its pid goes to `pid`.
  bool running(const SheriffProcess& sheriff, const std::string& path, int runid,
               int* pid = nullptr, const std::string& deputy = "dep") {
    const auto r = sheriff.row(path);
    const std::string id = path.substr(path.rfind('/') + 1);
    const Observer::Truth* truth = observer.command(deputy, id);
    if (!r || r->status != "Running" || r->pid <= 0 || !r->runIds(runid) || truth == nullptr ||
        truth->pid != r->pid || truth->runid != runid || !processAlive(r->pid)) {
      return false;
    }
    if (pid != nullptr) *pid = r->pid;
    return true;
  }

  // The sheriff shows `path` as `status` (a "Stopped ..." one) with exit `exit` (any when
  // empty), and the deputy reports no process.
  bool stopped(const SheriffProcess& sheriff, const std::string& path,
               const std::string& status = "Stopped (OK)", const std::string& exit = "",
               int runid = -1, const std::string& deputy = "dep") {
    const auto r = sheriff.row(path);
    const std::string id = path.substr(path.rfind('/') + 1);
    const Observer::Truth* truth = observer.command(deputy, id);
    return r && r->status == status && r->pid == 0 && (exit.empty() || r->exit == exit) &&
           (runid < 0 || r->runIds(runid)) && truth != nullptr && truth->pid == 0 &&
           (runid < 0 || truth->runid == runid);
  }

  // Waits until `pid` has gone (exited and reaped, or a zombie).
  bool gone(int pid) {
    return waitFor([&] { return !processAlive(pid); });
  }
};

std::string showRow(const SheriffProcess& sheriff, const std::string& path) {
  const auto r = sheriff.row(path);
  if (!r) return "no row for '" + path + "' in the last status table";
  return r->path + " | " + r->deputy + " | " + r->status + " | pid " + std::to_string(r->pid) +
         " | run " + r->actual + "/" + std::to_string(r->desired) + " | exit " + r->exit;
}

// ---- 1. start, stop, restart -----------------------------------------------------------------

TEST_F(ProcmanSystem, StartsStopsAndRestartsCommandsGroupsAndEverything) {
  const std::string sheet = writeSheet("basic.pmd", R"PMD(
cmd "a" { exec = "sleep 1000"; deputy = "dep"; }
group "grp" {
  cmd "b" { exec = "sleep 1000"; deputy = "dep"; }
  group "inner" { cmd "c" { exec = "sleep 1000"; host = "dep"; } }
}
)PMD");
  startDeputy("dep");
  SheriffProcess& sheriff = startSheriff({sheet});
  // Once the deputy is heard from, the commands it has never run show as stopped.
  ASSERT_TRUE(waitFor([&] { return stopped(sheriff, "a") && stopped(sheriff, "grp/inner/c"); }))
      << showRow(sheriff, "a");

  sheriff.send("start cmd a");
  int a1 = 0;
  ASSERT_TRUE(waitFor([&] { return running(sheriff, "a", 1, &a1); })) << showRow(sheriff, "a");

  sheriff.send("stop cmd a");
  ASSERT_TRUE(waitFor([&] { return stopped(sheriff, "a", "Stopped (OK)", "SIGINT"); }))
      << showRow(sheriff, "a");
  EXPECT_TRUE(gone(a1));

  sheriff.send("start cmd a");
  int a2 = 0;
  ASSERT_TRUE(waitFor([&] { return running(sheriff, "a", 2, &a2); })) << showRow(sheriff, "a");
  EXPECT_NE(a2, a1);

  sheriff.send("restart cmd a");
  int a3 = 0;
  ASSERT_TRUE(waitFor([&] { return running(sheriff, "a", 3, &a3); })) << showRow(sheriff, "a");
  EXPECT_NE(a3, a2) << "a restart is a new process";
  EXPECT_TRUE(gone(a2));

  // A group covers its subgroups, and nothing else.
  sheriff.send("start group grp");
  int b1 = 0, c1 = 0;
  ASSERT_TRUE(waitFor([&] {
    return running(sheriff, "grp/b", 1, &b1) && running(sheriff, "grp/inner/c", 1, &c1);
  })) << showRow(sheriff, "grp/b")
      << "\n"
      << showRow(sheriff, "grp/inner/c");
  EXPECT_EQ(observer.pid("dep", "a"), a3);

  sheriff.send("stop group grp/inner");
  ASSERT_TRUE(waitFor([&] { return stopped(sheriff, "grp/inner/c"); }))
      << showRow(sheriff, "grp/inner/c");
  EXPECT_TRUE(gone(c1));
  EXPECT_TRUE(running(sheriff, "grp/b", 1)) << showRow(sheriff, "grp/b");
  EXPECT_EQ(observer.pid("dep", "b"), b1);

  sheriff.send("stop everything");
  ASSERT_TRUE(waitFor([&] {
    return stopped(sheriff, "a") && stopped(sheriff, "grp/b") && stopped(sheriff, "grp/inner/c");
  })) << showRow(sheriff, "a")
      << "\n"
      << showRow(sheriff, "grp/b");
  EXPECT_TRUE(gone(a3));
  EXPECT_TRUE(gone(b1));

  sheriff.send("start everything");
  int a4 = 0, b2 = 0, c2 = 0;
  ASSERT_TRUE(waitFor([&] {
    return running(sheriff, "a", 4, &a4) && running(sheriff, "grp/b", 2, &b2) &&
           running(sheriff, "grp/inner/c", 2, &c2);
  })) << showRow(sheriff, "a")
      << "\n"
      << showRow(sheriff, "grp/b") << "\n"
      << showRow(sheriff, "grp/inner/c");

  // Quitting stops everything, then exits 0.
  sheriff.send("quit");
  ASSERT_TRUE(sheriff.waitExit(kDeadline));
  EXPECT_EQ(sheriff.exitCode(), 0);
  EXPECT_TRUE(sheriff.says("every command is stopped")) << sheriff.output();
  for (int pid : {a4, b2, c2}) EXPECT_TRUE(gone(pid)) << pid;
}

// ---- 2. respawn ------------------------------------------------------------------------------

TEST_F(ProcmanSystem, RespawnsACrashingCommandUntilItIsStopped) {
  const std::string sheet = writeSheet("respawn.pmd", R"PMD(
cmd "crasher" { exec = "sh -c 'sleep 0.3; exit 1'"; deputy = "dep"; auto_respawn = "true"; }
)PMD");
  startDeputy("dep");
  SheriffProcess& sheriff = startSheriff({sheet});
  ASSERT_TRUE(waitFor([&] { return stopped(sheriff, "crasher"); })) << showRow(sheriff, "crasher");

  sheriff.send("start cmd crasher");
  ASSERT_TRUE(waitFor([&] {
    const Observer::Truth* truth = observer.command("dep", "crasher");
    return truth != nullptr && truth->pids.size() >= 3;
  }));
  // The sheriff saw it come back with other pids, all in the same run.
  ASSERT_TRUE(waitFor([&] {
    std::set<int> pids;
    for (const Row& r : sheriff.history("crasher")) {
      if (r.status == "Running") pids.insert(r.pid);
    }
    return pids.size() >= 2;
  })) << sheriff.output();
  for (const Row& r : sheriff.history("crasher")) {
    if (r.status == "Running") {
      EXPECT_TRUE(r.runIds(1)) << r.actual << "/" << r.desired;
    }
  }
  const std::vector<int> pids = observer.command("dep", "crasher")->pids;
  EXPECT_EQ(std::set<int>(pids.begin(), pids.end()).size(), pids.size()) << "a new pid each time";

  sheriff.send("stop cmd crasher");
  ASSERT_TRUE(waitFor([&] {
    const auto r = sheriff.row("crasher");
    return r && r->status.rfind("Stopped", 0) == 0 && observer.pid("dep", "crasher") == 0;
  })) << showRow(sheriff, "crasher");
  const size_t runs = observer.command("dep", "crasher")->pids.size();
  for (int pid : observer.command("dep", "crasher")->pids) EXPECT_TRUE(gone(pid)) << pid;
  // It would have come back within a second (its runs last 0.3 s, the backoff stays below 1 s):
  // watch the deputy's reports for more than that.
  const int64_t since = observer.lastInfoUtime("dep");
  ASSERT_TRUE(waitFor([&] { return observer.lastInfoUtime("dep") >= since + 1'500'000; }));
  EXPECT_EQ(observer.command("dep", "crasher")->pids.size(), runs) << "respawned after stop";
  EXPECT_EQ(observer.pid("dep", "crasher"), 0);
  const auto r = sheriff.row("crasher");
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->status.rfind("Stopped", 0), 0u) << showRow(sheriff, "crasher");
}

// ---- 3. SIGKILL after stop_time_allowed ------------------------------------------------------

TEST_F(ProcmanSystem, EscalatesToSigkillWhenTheStopSignalIsIgnored) {
  const std::string sheet = writeSheet("stubborn.pmd", R"PMD(
cmd "stubborn" {
  exec = "sh -c 'trap \"\" INT; echo ready; while :; do sleep 0.1; done'";
  deputy = "dep";
  stop_time_allowed = 1;
}
)PMD");
  startDeputy("dep");
  SheriffProcess& sheriff = startSheriff({sheet});
  ASSERT_TRUE(waitFor([&] { return stopped(sheriff, "stubborn"); }))
      << showRow(sheriff, "stubborn");
  sheriff.send("start cmd stubborn");
  int pid = 0;
  // "ready": the trap is set.
  ASSERT_TRUE(waitFor([&] {
    return running(sheriff, "stubborn", 1, &pid) && sheriff.says("[stubborn] ready");
  })) << sheriff.output();

  // A restart has to kill it too before it can start it again.
  sheriff.send("restart cmd stubborn");
  int second = 0;
  ASSERT_TRUE(waitFor([&] {
    const std::vector<std::string> all = lines(sheriff.output());
    return running(sheriff, "stubborn", 2, &second) &&
           std::count(all.begin(), all.end(), "[stubborn] ready") == 2;
  })) << sheriff.output();
  EXPECT_NE(second, pid);
  EXPECT_TRUE(gone(pid));
  const std::vector<Row> history = sheriff.history("stubborn");
  EXPECT_TRUE(std::any_of(history.begin(), history.end(), [](const Row& r) {
    return r.status == "Restarting (Command Sent)";
  })) << sheriff.output();
  pid = second;

  sheriff.send("stop cmd stubborn");
  ASSERT_TRUE(waitFor([&] { return stopped(sheriff, "stubborn", "Stopped (OK)", "SIGKILL", 2); }))
      << showRow(sheriff, "stubborn");
  const int status = observer.command("dep", "stubborn")->exit_code;
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << status;
  EXPECT_TRUE(gone(pid));
}

// ---- 4. process trees --------------------------------------------------------------------------

TEST_F(ProcmanSystem, StopKillsTheWholeProcessTree) {
  // Background children of a non-interactive shell ignore SIGINT; one is in a session of its
  // own. Both must go with the shell.
  const std::string sheet = writeSheet("tree.pmd", R"PMD(
cmd "tree" {
  exec = "sh -c 'sleep 1000 & echo child $!; setsid sleep 1000 & echo child $!; wait'";
  deputy = "dep";
  stop_time_allowed = 1;
}
)PMD");
  startDeputy("dep");
  SheriffProcess& sheriff = startSheriff({sheet});
  ASSERT_TRUE(waitFor([&] { return stopped(sheriff, "tree"); })) << showRow(sheriff, "tree");
  sheriff.send("start cmd tree");
  int shell = 0;
  std::vector<int> tree;
  ASSERT_TRUE(waitFor([&] {
    tree.clear();
    static const std::regex child(R"(^\[tree\] child (\d+)$)");
    for (const std::string& line : lines(sheriff.output())) {
      std::smatch m;
      if (std::regex_match(line, m, child)) tree.push_back(std::stoi(m[1]));
    }
    return running(sheriff, "tree", 1, &shell) && tree.size() == 2;
  })) << sheriff.output();
  tree.push_back(shell);
  for (int pid : tree) EXPECT_TRUE(processAlive(pid)) << pid;

  sheriff.send("stop cmd tree");
  ASSERT_TRUE(waitFor([&] { return stopped(sheriff, "tree"); })) << showRow(sheriff, "tree");
  for (int pid : tree) EXPECT_TRUE(gone(pid)) << "still alive: " << pid;
}

// ---- 5. output -----------------------------------------------------------------------------

TEST_F(ProcmanSystem, PrintsCommandOutputPrefixedByItsId) {
  const std::string sheet = writeSheet("talker.pmd", R"PMD(
group "chat" {
  cmd "talker" { exec = "sh -c 'echo hello from the talker; echo and from stderr >&2; printf \\\\033[2Jcleared\\\\n'"; deputy = "dep"; }
}
)PMD");
  startDeputy("dep");
  SheriffProcess& sheriff = startSheriff({sheet});
  ASSERT_TRUE(waitFor([&] { return stopped(sheriff, "chat/talker"); }))
      << showRow(sheriff, "chat/talker");
  sheriff.send("start talker");
  ASSERT_TRUE(waitFor([&] {
    const std::vector<std::string> all = lines(sheriff.output());
    const auto has = [&](const std::string& line) {
      return std::find(all.begin(), all.end(), line) != all.end();
    };
    // The escape sequence is shown, not obeyed: it would clear the operator's screen.
    return has("[talker] hello from the talker") && has("[talker] and from stderr") &&
           has("[talker] \\x1b[2Jcleared");
  })) << sheriff.output();
  // It ran to completion, once.
  ASSERT_TRUE(waitFor([&] { return stopped(sheriff, "chat/talker", "Stopped (OK)", "0", 1); }))
      << showRow(sheriff, "chat/talker");
  EXPECT_EQ(observer.command("dep", "talker")->pids.size(), 1u);
}

// ---- 6. scripts ------------------------------------------------------------------------------

const char* kScriptSheet = R"PMD(
cmd "a" { exec = "sleep 1000"; deputy = "dep"; }
script "cycle" {
  start cmd "a" wait "running";
  wait ms 200;
  stop cmd "a" wait "stopped";
}
script "stuck" {
  wait cmd "a" status "running";
}
)PMD";

TEST_F(ProcmanSystem, AScriptWithWaitsRunsToTheEndAndTheSheriffExitsZero) {
  const std::string sheet = writeSheet("script.pmd", kScriptSheet);
  startDeputy("dep");
  SheriffProcess& sheriff = startSheriff({"--exit-after-script", sheet, "cycle"});
  ASSERT_TRUE(waitFor([&] { return sheriff.waitExit(0); })) << sheriff.output();
  EXPECT_EQ(sheriff.exitCode(), 0) << sheriff.output();
  EXPECT_TRUE(sheriff.says("script 'cycle' completed")) << sheriff.output();
  EXPECT_TRUE(sheriff.says("stop cmd 'a' wait \"stopped\"")) << sheriff.output();
  // The command ran once, and the script stopped it.
  ASSERT_TRUE(waitFor([&] {
    const Observer::Truth* truth = observer.command("dep", "a");
    return truth != nullptr && truth->pids.size() == 1 && truth->pid == 0 && truth->runid == 1;
  }));
  const int status = observer.command("dep", "a")->exit_code;
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT) << status;
  EXPECT_TRUE(gone(observer.command("dep", "a")->pids[0]));
}

TEST_F(ProcmanSystem, AScriptWhoseWaitTimesOutMakesTheSheriffExitOne) {
  const std::string sheet = writeSheet("script.pmd", kScriptSheet);
  startDeputy("dep");
  // "a" is never started, so it is never running.
  SheriffProcess& sheriff =
      startSheriff({"--exit-after-script", "--wait-timeout", "1", sheet, "stuck"});
  ASSERT_TRUE(waitFor([&] { return sheriff.waitExit(0); })) << sheriff.output();
  EXPECT_EQ(sheriff.exitCode(), 1) << sheriff.output();
  EXPECT_TRUE(std::regex_search(
      sheriff.output(),
      std::regex(R"(timed out after 1(\.0)? s waiting for cmd 'a' to be running)")))
      << sheriff.output();
  EXPECT_TRUE(sheriff.says("the script failed")) << sheriff.output();
}

// ---- 7. a new sheriff adopts what runs ---------------------------------------------------------

TEST_F(ProcmanSystem, ARestartedSheriffAdoptsRunningCommands) {
  const std::string sheet = writeSheet("adopt.pmd", R"PMD(
cmd "a" { exec = "sleep 1000"; deputy = "dep"; }
)PMD");
  startDeputy("dep");
  SheriffProcess& first = startSheriff({sheet});
  ASSERT_TRUE(waitFor([&] { return stopped(first, "a"); })) << showRow(first, "a");
  first.send("start cmd a");
  int pid = 0;
  ASSERT_TRUE(waitFor([&] { return running(first, "a", 1, &pid); })) << showRow(first, "a");
  const std::string first_id = first.id();

  // Killed outright: it cannot stop anything.
  ASSERT_TRUE(first.signal(SIGKILL));
  ASSERT_TRUE(first.waitExit(kDeadline));

  SheriffProcess& second = startSheriff({sheet});
  ASSERT_TRUE(waitFor([&] { return running(second, "a", 1) && second.row("a")->pid == pid; }))
      << showRow(second, "a");
  const std::string second_id = second.id();
  ASSERT_FALSE(second_id.empty());
  EXPECT_NE(second_id, first_id);
  // The deputy kept the process: one pid ever, and the new sheriff ordered that very run.
  EXPECT_EQ(observer.command("dep", "a")->pids, std::vector<int>{pid});
  EXPECT_TRUE(processAlive(pid));
  ASSERT_TRUE(waitFor([&] { return observer.ordersCount(second_id) > 0; }));
  for (const Observer::Orders& o : observer.orders()) {
    if (o.sheriff != second_id) continue;
    EXPECT_EQ(o.command, "a");
    EXPECT_EQ(o.desired_runid, 1) << "the adopted run id";
    EXPECT_FALSE(o.force_quit);
  }
  for (const Row& r : second.history("a")) {
    EXPECT_TRUE(r.status == "Unknown" || r.status == "Running") << r.status;
  }

  second.send("stop cmd a");
  ASSERT_TRUE(waitFor([&] { return stopped(second, "a", "Stopped (OK)", "SIGINT"); }))
      << showRow(second, "a");
  EXPECT_TRUE(gone(pid));
}

// ---- 8. lone ranger ----------------------------------------------------------------------------

TEST_F(ProcmanSystem, ALoneRangerTakesItsDeputyAndCommandsAlongWhenItExits) {
  const std::string sheet = writeSheet("lone.pmd", R"PMD(
cmd "sleeper" { exec = "sleep 1000"; deputy = "lone"; }
cmd "stubborn" {
  exec = "sh -c 'trap \"\" INT; while :; do sleep 0.1; done'";
  deputy = "lone";
  stop_time_allowed = 1;
}
script "up" { start everything wait "running"; }
)PMD");
  SheriffProcess& sheriff = startSheriff({"-l", "--exit-after-script", sheet, "up"});
  ASSERT_TRUE(waitFor([&] { return sheriff.waitExit(0); })) << sheriff.output();
  EXPECT_EQ(sheriff.exitCode(), 0) << sheriff.output();
  EXPECT_TRUE(sheriff.says("script 'up' completed")) << sheriff.output();

  std::smatch m;
  const std::string output = sheriff.output();
  ASSERT_TRUE(
      std::regex_search(output, m, std::regex(R"(started local deputy 'lone' \(pid (\d+)\))")))
      << output;
  const int deputy = std::stoi(m[1]);
  // Both ran, under the local deputy.
  std::vector<int> pids = {deputy};
  for (const std::string id : {"sleeper", "stubborn"}) {
    observer.pump();
    const Observer::Truth* truth = observer.command("lone", id);
    ASSERT_NE(truth, nullptr) << id;
    ASSERT_FALSE(truth->pids.empty()) << id;
    EXPECT_EQ(truth->runid, 1) << id;
    pids.insert(pids.end(), truth->pids.begin(), truth->pids.end());
  }
  // The sheriff has exited: nothing it started is left.
  for (int pid : pids) EXPECT_FALSE(processAlive(pid)) << pid;
  EXPECT_TRUE(DescendantReaper::descendants().empty());
}

// ---- observer mode -----------------------------------------------------------------------------

TEST_F(ProcmanSystem, AnObserverShowsWhatAnotherSheriffRunsAndSendsNoOrders) {
  const std::string sheet = writeSheet("observed.pmd", R"PMD(
group "g" { cmd "a" { exec = "sleep 1000"; deputy = "dep"; } }
)PMD");
  startDeputy("dep");
  SheriffProcess& commander = startSheriff({sheet});
  ASSERT_TRUE(waitFor([&] { return stopped(commander, "g/a"); })) << showRow(commander, "g/a");
  commander.send("start cmd a");
  int pid = 0;
  ASSERT_TRUE(waitFor([&] { return running(commander, "g/a", 1, &pid); }))
      << showRow(commander, "g/a");

  SheriffProcess& watcher = startSheriff({"-o"});  // no sheet: it learns everything on LCM
  ASSERT_TRUE(waitFor([&] { return running(watcher, "g/a", 1) && watcher.row("g/a")->pid == pid; }))
      << watcher.output();
  const std::string commander_id = commander.id();
  const std::string watcher_id = watcher.id();
  ASSERT_FALSE(commander_id.empty());
  ASSERT_FALSE(watcher_id.empty());
  EXPECT_TRUE(watcher.says(watcher_id + " observing")) << watcher.output();

  // An observer that gave orders would do so at least once a second: watch a few of the
  // commander's (1 Hz) orders go by.
  const int seen = observer.ordersCount(commander_id);
  ASSERT_TRUE(waitFor([&] { return observer.ordersCount(commander_id) >= seen + 2; }));
  EXPECT_EQ(observer.sheriffs(), std::vector<std::string>{commander_id});
  EXPECT_FALSE(watcher.says("CONFLICT")) << watcher.output();
  EXPECT_FALSE(commander.says("CONFLICT")) << commander.output();
  watcher.send("stop everything");
  ASSERT_TRUE(waitFor([&] { return watcher.says("observer mode sends no orders"); }))
      << watcher.output();

  // The observer follows what the commander does.
  commander.send("stop cmd a");
  ASSERT_TRUE(waitFor([&] { return stopped(watcher, "g/a", "Stopped (OK)", "SIGINT"); }))
      << showRow(watcher, "g/a");
  EXPECT_TRUE(gone(pid));
  watcher.send("quit");
  ASSERT_TRUE(watcher.waitExit(kDeadline));
  EXPECT_EQ(watcher.exitCode(), 0);
  EXPECT_EQ(observer.sheriffs(), std::vector<std::string>{commander_id});
}

}  // namespace
}  // namespace thicket::procman
