// Two processes built on the node runtime exchange typed messages over udpm, inside a private
// network namespace with a loopback multicast route (docs/design.md §5). Where namespaces are not
// permitted, a multicast port unique to this test run keeps it apart from other traffic.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <thicket/depth_image_t.hpp>
#include <thicket/odometry_t.hpp>

#include "thicket/common/loop.h"
#include "thicket/common/node.h"

extern char** environ;

namespace thicket {
namespace {

// The URL to use: the default one inside a fresh namespace, else a unique port.
std::string isolatedUrl() {
  if (::unshare(CLONE_NEWNET) == 0 &&
      std::system("ip link set lo up multicast on && ip route add 224.0.0.0/4 dev lo") == 0) {
    return "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
  }
  std::fprintf(stderr, "no private network namespace here; using a unique port\n");
  return "udpm://239.255.76.67:" + std::to_string(20000 + ::getpid() % 20000) +
         "?ttl=0&recv_buf_size=8388608";
}

struct Child {
  pid_t pid = -1;
  std::string output_path;

  std::string output() const {
    std::ifstream in(output_path);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }
};

Child spawnEcho(const std::string& url) {
  Child child;
  child.output_path = ::testing::TempDir() + "/echo_" + std::to_string(::getpid()) + ".txt";
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, child.output_path.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  const std::string flag = "--lcm-url=" + url;
  const char* argv[] = {THICKET_ECHO_NODE, flag.c_str(), nullptr};
  EXPECT_EQ(posix_spawn(&child.pid, THICKET_ECHO_NODE, &actions, nullptr,
                        const_cast<char* const*>(argv), environ),
            0);
  posix_spawn_file_actions_destroy(&actions);
  return child;
}

// Sends message k until its echo comes back (UDP may drop; the echo process may not be
// subscribed yet), then k + 1; a deadline fails the test instead of hanging.
TEST(UdpmProcesses, PingPongAndALargeImageAcrossProcesses) {
  const std::string url = isolatedUrl();
  lcm::LCM lcm(url);
  ASSERT_TRUE(lcm.good()) << url;
  Child echo = spawnEcho(url);
  ASSERT_GT(echo.pid, 0);

  Loop loop(lcm);
  Node pinger("pinger", lcm);
  constexpr int kPings = 20;
  int next = 0;  // pings 0..kPings-1, then one large image
  bool image_back = false;
  int64_t replies = 0;

  depth_image_t image{};
  image.utime = 77;
  image.width = 640;
  image.height = 480;
  image.depth_encoding = depth_image_t::DEPTH_UINT16_MM;
  image.size = image.width * image.height * 2;  // 600 KB: dropped without recv_buf_size
  image.data.resize(static_cast<size_t>(image.size));
  for (size_t i = 0; i < image.data.size(); ++i) image.data[i] = static_cast<uint8_t>(i * 31);

  auto send = [&] {
    if (next < kPings) {
      odometry_t ping{};
      ping.utime = 1000 + next;
      ping.sequence = next;
      ping.orientation[0] = 1.0;
      pinger.publish("PING", ping);
    } else if (!image_back) {
      pinger.publish("CAMERA_DEPTH", image);
    }
  };
  pinger.subscribe<odometry_t>("PONG", [&](const odometry_t& msg, const MessageInfo&) {
    ++replies;
    EXPECT_EQ(msg.utime - 1000, msg.sequence - 1000);
    if (msg.sequence == next + 1000) {
      ++next;
      send();
    }
  });
  pinger.subscribe<depth_image_t>("DEPTH_ECHO", [&](const depth_image_t& msg, const MessageInfo&) {
    EXPECT_EQ(msg.data, image.data);
    image_back = true;
    loop.stop();
  });
  loop.addTimer(20'000, send);
  bool timed_out = false;
  loop.addTimer(20'000'000, [&] {
    timed_out = true;
    loop.stop();
  });
  send();
  loop.run();

  EXPECT_FALSE(timed_out) << "echoes received: " << next << " of " << kPings;
  EXPECT_EQ(next, kPings);
  EXPECT_TRUE(image_back);
  EXPECT_GE(replies, kPings);

  // The echo process stops cleanly on SIGTERM and reports what it handled.
  ASSERT_EQ(::kill(echo.pid, SIGTERM), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(echo.pid, &status, 0), echo.pid);
  ASSERT_TRUE(WIFEXITED(status)) << "echo died by signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 0);
  const std::string output = echo.output();
  EXPECT_NE(output.find("stopped by signal 15"), std::string::npos) << output;
  EXPECT_NE(output.find("0 refused"), std::string::npos) << output;
}

}  // namespace
}  // namespace thicket
