// Every module as a process, fed hostile messages on every channel it subscribes to, over udpm
// inside a private network namespace: a valid sample of the channel's type with each 4-byte
// window overwritten by huge, negative and zero counts, truncations, trailing bytes, NaN,
// infinite and huge numbers, integers (times, ids) at their extremes, random bytes with and
// without a valid fingerprint, and then a flood. Each module must stay alive, keep its peak
// memory under a bound, count what it refuses, and exit promptly and cleanly on SIGINT.
#include <gtest/gtest.h>

#include <signal.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "lcm_fuzz.h"
#include "procman_test_support.h"

namespace thicket {
namespace {

using procman::test_support::ChildProcess;
using procman::test_support::isolatedUrl;
using procman::test_support::processAlive;
using procman::test_support::readFile;
using procman::test_support::waitUntil;

struct Subscription {
  std::string channel;
  std::string type;  // "package.type"
};

struct Module {
  std::string name;
  std::vector<std::string> argv;  // without the LCM URL
  std::vector<Subscription> inputs;
  std::vector<int> exit_codes = {0};  // what a clean exit on SIGINT may return
};

// A process's peak resident memory [MB], from /proc; -1 when it cannot be read.
double peakMegabytes(int pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  return -1;
}

int64_t nextPowerOfTen(int64_t n) {
  int64_t power = 10;
  while (power <= n) power *= 10;
  return power;
}

void fuzzModule(const Module& module) {
  SCOPED_TRACE(module.name);
  const std::string url = isolatedUrl();
  lcm::LCM lcm(url);
  ASSERT_TRUE(lcm.good());
  std::vector<std::string> argv = module.argv;
  argv.push_back("--lcm-url=" + url);
  ChildProcess child(argv);
  ASSERT_GT(child.pid(), 0);
  const auto refusedLine = [&](int64_t count, const std::string& channel) {
    return "refused message " + std::to_string(count) + " on " + channel + ":";
  };
  const fuzz::Bytes junk = {1, 2, 3};  // no type's fingerprint: always refused
  const auto publish = [&](const std::string& channel, const fuzz::Bytes& bytes) {
    lcm.publish(channel, bytes.data(), static_cast<unsigned>(bytes.size()));
  };
  // Subscribed: the first refusal is printed.
  const std::string first = module.inputs.front().channel;
  ASSERT_TRUE(waitUntil(
      [&] { return child.output().find(refusedLine(1, first)) != std::string::npos; }, 20.0,
      [&] {
        publish(first, junk);
        ::usleep(20'000);
      }))
      << child.output();

  uint32_t seed = 1;
  for (const Subscription& input : module.inputs) {
    const std::vector<fuzz::Bytes> hostile = fuzz::hostileMessages(input.type, 300, seed++);
    for (const fuzz::Bytes& bytes : hostile) publish(input.channel, bytes);
    // A flood of one valid message.
    const fuzz::Bytes sample = fuzz::sampleBytes(input.type);
    for (int i = 0; i < 2000; ++i) publish(input.channel, sample);
    // Junk until a refusal count that only junk sent after all of the above can reach: by then
    // the module has dealt with everything before it (loopback keeps the order; LCM may drop).
    const int64_t target = nextPowerOfTen(static_cast<int64_t>(hostile.size()) + 2000 + 1);
    EXPECT_TRUE(waitUntil(
        [&] {
          return !processAlive(child.pid()) ||
                 child.output().find(refusedLine(target, input.channel)) != std::string::npos;
        },
        120.0,
        [&] {
          for (int i = 0; i < 50; ++i) publish(input.channel, junk);
          ::usleep(2'000);
        }))
        << input.channel << ": " << child.output().substr(0, 4000);
    ASSERT_TRUE(processAlive(child.pid())) << input.channel << ": " << child.output();
  }
  const double peak = peakMegabytes(child.pid());
  EXPECT_GT(peak, 0.0);
  EXPECT_LT(peak, 600.0) << "peak resident memory [MB]";
  ASSERT_TRUE(child.signal(SIGINT));
  ASSERT_TRUE(child.waitExit(5.0)) << "no exit within 5 s of SIGINT: " << child.output();
  EXPECT_TRUE(WIFEXITED(child.status())) << child.output();
  EXPECT_NE(std::find(module.exit_codes.begin(), module.exit_codes.end(), child.exitCode()),
            module.exit_codes.end())
      << "exit code " << child.exitCode() << ": " << child.output();
}

TEST(ModuleFuzz, Mapper) {
  fuzzModule({"mapper",
              {THICKET_MAPPER},
              {{"CAMERA_DEPTH", "thicket.depth_image_t"},
               {"STATE_ESTIMATE", "thicket.odometry_t"},
               {"MAP_REQUEST", "thicket.map_request_t"}}});
}

TEST(ModuleFuzz, LocalPlanner) {
  fuzzModule({"local planner",
              {THICKET_LOCAL_PLANNER},
              {{"MAP_ESDF", "thicket.map_update_t"},
               {"STATE_ESTIMATE", "thicket.odometry_t"},
               {"MISSION_GOAL", "thicket.goal_t"},
               {"EXPLORER_GOAL", "thicket.goal_t"}}});
}

TEST(ModuleFuzz, Explorer) {
  fuzzModule({"explorer",
              {THICKET_EXPLORER},
              {{"MAP_TSDF", "thicket.map_update_t"},
               {"MAP_ESDF", "thicket.map_update_t"},
               {"PLANNER_STATUS", "thicket.planner_status_t"}}});
}

TEST(ModuleFuzz, VioBridge) {
  fuzzModule({"vio bridge", {THICKET_VIO_BRIDGE}, {{"VIO_ODOMETRY", "thicket.odometry_t"}}});
}

TEST(ModuleFuzz, StereoDepth) {
  fuzzModule({"stereo depth", {THICKET_STEREO_DEPTH}, {{"STEREO", "thicket.stereo_image_t"}}});
}

// The simulator in real time (the lockstep one waits for planner statuses): one
// PLANNER_TRAJECTORY of 49 bytes claiming 2^28 + 1 segments killed it.
TEST(ModuleFuzz, Simulator) {
  fuzzModule({"simulator",
              {THICKET_SIM, "run", "--scenario", "paper", "--density", "0.1", "--seed", "1",
               "--worlds-dir", THICKET_SOURCE_DIR "/config/worlds"},
              {{"PLANNER_TRAJECTORY", "thicket.polynomial_trajectory_t"},
               {"PLANNER_STATUS", "thicket.planner_status_t"}},
              {0, 1}});  // 1: the mission did not reach its goal, as it cannot without a planner
}

TEST(ModuleFuzz, Deputy) {
  fuzzModule({"deputy",
              {THICKET_DEPUTY, "-i", "fuzzed"},
              {{"PM_ORDERS", "procman_lcm.orders_t"},
               {"PM_INFO", "procman_lcm.deputy_info_t"},
               {"PM_DISCOVER", "procman_lcm.discovery_t"}}});
}

}  // namespace
}  // namespace thicket
