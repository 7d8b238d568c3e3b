// A thicket-bench campaign on a Slurm cluster: the test starts a single-node cluster of its own
// (Debian's slurmctld and slurmd, auth/none, state, spool and logs in a temporary folder, inside a
// private network namespace so that its ports and traffic stay there), submits a small campaign
// with tools/bench/slurm/submit (a job array of two shards, then the merge after both), and checks
// that the merged trials are those of one local run of the same selection, timings aside. Skipped,
// with the reason, where Slurm is not installed or cannot start (no root for the namespace).
#include <pwd.h>
#include <sched.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "bench_tables.h"
#include "cli.h"
#include "procman_test_support.h"

namespace {

namespace fs = std::filesystem;
using thicket::bench::testing::readTable;
using thicket::bench::testing::Table;
using thicket::bench::testing::withoutTimes;
using thicket::procman::test_support::ChildProcess;
using thicket::procman::test_support::DescendantReaper;
using thicket::procman::test_support::readFile;
using thicket::procman::test_support::waitUntil;
using thicket::testing::CliResult;
using thicket::testing::runCommand;

// The campaign: 4 trials, 2 per shard.
const std::string kSelection =
    "--experiment E2 --scenario paper --density 0.3 --method none,local_exploration --trials 2 "
    "--replans 20";

// Why this machine cannot run a local Slurm, empty when it can.
std::string slurmMissing() {
  for (const char* program : {"slurmctld", "slurmd", "sbatch", "scontrol", "sinfo"}) {
    if (runCommand(std::string("command -v ") + program).status != 0) {
      return std::string(program) +
             " is not installed (scripts/setup installs slurmctld, slurmd and slurm-client)";
    }
  }
  if (runCommand("ls /usr/lib/*/slurm-wlm/auth_none.so").status != 0) {
    return "this Slurm has no auth/none plugin (auth_none.so)";
  }
  return "";
}

// slurmd's view of this machine's processors ("CPUs=2 Boards=1 ..."): a node configured with
// more than that is drained.
std::string nodeHardware() {
  const CliResult probe = runCommand("slurmd -C");
  std::string hardware;
  for (const char* field :
       {"CPUs", "Boards", "SocketsPerBoard", "CoresPerSocket", "ThreadsPerCore"}) {
    std::smatch match;
    std::regex_search(probe.output, match, std::regex(std::string(" ") + field + "=([0-9]+)"));
    if (!match.empty()) hardware += std::string(" ") + field + "=" + match[1].str();
  }
  return hardware.empty() ? " CPUs=1" : hardware;
}

// A single-node cluster in `dir`, with the test's user as Slurm's user; SLURM_CONF points the
// client commands (and the test's children) at it.
class LocalSlurm {
 public:
  explicit LocalSlurm(const std::string& dir) : dir_(dir) {
    for (const char* sub : {"state", "spool", "log"}) fs::create_directories(dir_ + "/" + sub);
    std::ofstream(dir_ + "/plugstack.conf");
    const std::string user = ::getpwuid(::geteuid())->pw_name;
    std::ofstream conf(dir_ + "/slurm.conf");
    // EnableIPv6: Slurm 22.05 resolves "localhost" with AI_ADDRCONFIG otherwise, which fails in a
    // namespace whose only address is loopback. The scheduler runs every second so that the
    // test does not wait on it.
    conf << "ClusterName=thicket-test\nSlurmctldHost=localhost(127.0.0.1)\n"
         << "SlurmctldPort=6817\nSlurmdPort=6818\nCommunicationParameters=EnableIPv6\n"
         << "SlurmUser=" << user << "\nSlurmdUser=" << user << "\n"
         << "AuthType=auth/none\nCredType=cred/none\nMailProg=/bin/true\n"
         << "StateSaveLocation=" << dir_ << "/state\nSlurmdSpoolDir=" << dir_ << "/spool\n"
         << "SlurmctldPidFile=" << dir_ << "/slurmctld.pid\nSlurmdPidFile=" << dir_
         << "/slurmd.pid\nSlurmctldLogFile=" << dir_ << "/log/slurmctld.log\nSlurmdLogFile=" << dir_
         << "/log/slurmd.log\nPlugStackConfig=" << dir_ << "/plugstack.conf\n"
         << "ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n"
         << "SelectType=select/cons_tres\nSelectTypeParameters=CR_Core\n"
         << "SchedulerType=sched/builtin\n"
         << "SchedulerParameters=sched_interval=1,sched_min_interval=0,batch_sched_delay=0\n"
         << "AccountingStorageType=accounting_storage/none\n"
         << "JobAcctGatherType=jobacct_gather/none\nJobCompType=jobcomp/none\n"
         << "MpiDefault=none\nReturnToService=2\nInactiveLimit=0\nMinJobAge=300\nKillWait=5\n"
         << "NodeName=n1 NodeAddr=127.0.0.1 NodeHostname=localhost" << nodeHardware()
         << " State=UNKNOWN\nPartitionName=test Nodes=n1 Default=YES MaxTime=INFINITE State=UP\n";
    conf.close();
    ::setenv("SLURM_CONF", (dir_ + "/slurm.conf").c_str(), 1);
    controller_ = std::make_unique<ChildProcess>(
        std::vector<std::string>{"/usr/sbin/slurmctld", "-D", "-i", "-f", dir_ + "/slurm.conf"});
    node_ = std::make_unique<ChildProcess>(
        std::vector<std::string>{"/usr/sbin/slurmd", "-D", "-N", "n1", "-f", dir_ + "/slurm.conf"});
  }
  LocalSlurm(const LocalSlurm&) = delete;
  LocalSlurm& operator=(const LocalSlurm&) = delete;
  ~LocalSlurm() {
    runCommand("timeout 10 scontrol shutdown");
    controller_->waitExit(10.0);
    node_->waitExit(10.0);
  }

  // Waits until the node takes jobs; false (the reason in `why`) when it does not in 30 s.
  bool ready(std::string& why) const {
    const bool up = waitUntil(
        [&] {
          return controller_->exited() || node_->exited() ||
                 runCommand("timeout 5 sinfo -h -n n1 -o %T").output.rfind("idle", 0) == 0;
        },
        30.0);
    if (up && !controller_->exited() && !node_->exited()) return true;
    why = "the local Slurm did not start: slurmctld: " + controller_->output() +
          readFile(dir_ + "/log/slurmctld.log") + "\nslurmd: " + node_->output() +
          readFile(dir_ + "/log/slurmd.log");
    return false;
  }

  // The job's state (scontrol's JobState), empty when Slurm does not know the job.
  static std::string jobState(const std::string& id) {
    const CliResult job = runCommand("timeout 5 scontrol show job -o " + id);
    std::smatch m;
    return std::regex_search(job.output, m, std::regex("JobState=([A-Z_]+)")) ? m[1].str() : "";
  }

 private:
  std::string dir_;
  std::unique_ptr<ChildProcess> controller_, node_;
};

TEST(SlurmCampaign, AnArrayOfShardsAndItsMergeGiveTheRowsOfOneLocalRun) {
  if (const std::string missing = slurmMissing(); !missing.empty()) GTEST_SKIP() << missing;
  if (::unshare(CLONE_NEWNET) != 0 || runCommand("ip link set lo up").status != 0) {
    GTEST_SKIP() << "needs a private network namespace for its cluster (run as root)";
  }
  const std::string dir = ::testing::TempDir() + "/slurm_campaign_" + std::to_string(::getpid());
  fs::remove_all(dir);
  DescendantReaper reaper;
  LocalSlurm slurm(dir + "/slurm");
  std::string why;
  if (!slurm.ready(why)) GTEST_SKIP() << why;

  const std::string bench = THICKET_BENCH;
  const std::string out = dir + "/campaign";
  const CliResult submit =
      runCommand("THICKET_BENCH=" + bench + " THICKET_SHARD_CPUS=1 " + THICKET_SOURCE_DIR +
                 "/tools/bench/slurm/submit 2 " + out + " " + kSelection);
  ASSERT_EQ(submit.status, 0) << submit.output;
  std::smatch ids;
  ASSERT_TRUE(std::regex_search(
      submit.output, ids, std::regex("array job ([0-9]+) \\(2 shards\\), merge job ([0-9]+)")))
      << submit.output;
  const std::string array = ids[1].str(), merge = ids[2].str();

  // The merge waits for the array, then ends; a failed shard would cancel it.
  std::string state;
  EXPECT_TRUE(waitUntil(
      [&] {
        state = LocalSlurm::jobState(merge);
        return state == "COMPLETED" || state == "FAILED" || state == "CANCELLED";
      },
      300.0))
      << state;
  ASSERT_EQ(state, "COMPLETED") << readFile(out + "/slurm-" + merge + ".out");
  for (int i = 0; i < 2; ++i) {
    const std::string shard_log =
        readFile(out + "/slurm-" + array + "_" + std::to_string(i) + ".out");
    EXPECT_NE(shard_log.find("shard " + std::to_string(i) + "/2: 2 trials, 2 run"),
              std::string::npos)
        << shard_log;
  }
  EXPECT_TRUE(fs::exists(out + "/merged/summary.md"));

  const CliResult local =
      runCommand(bench + " experiment " + kSelection + " --jobs 2 --out " + dir + "/local");
  ASSERT_EQ(local.status, 0) << local.output;
  const Table merged = withoutTimes(readTable(out + "/merged/trials.csv"));
  EXPECT_EQ(merged.size(), 5u);  // the header and 4 trials
  EXPECT_EQ(merged, withoutTimes(readTable(dir + "/local/trials.csv")));

  // A shard whose indices leave a gap is refused: it would not fly the trials of its shard.
  const CliResult gap = runCommand(
      "sbatch --wait --array=1 --chdir=" + dir + " --export=ALL,THICKET_BENCH=" + bench + " " +
      THICKET_SOURCE_DIR + "/tools/bench/slurm/shard.sbatch " + dir + "/gap " + kSelection);
  EXPECT_NE(gap.status, 0) << gap.output;
  EXPECT_FALSE(fs::exists(dir + "/gap"));
}

}  // namespace
