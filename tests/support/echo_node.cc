// A minimal thicket node for the multi-process transport test: answers every odometry_t on
// PING with the same message on PONG (sequence + 1000), and republishes every depth image on
// CAMERA_DEPTH unchanged on DEPTH_ECHO. Stops cleanly on SIGINT/SIGTERM and says how much it
// handled.
#include <cstdio>

#include <thicket/depth_image_t.hpp>
#include <thicket/odometry_t.hpp>

#include "thicket/common/loop.h"
#include "thicket/common/node.h"
#include "thicket/common/node_main.h"

namespace {

class EchoNode : public thicket::Node {
 public:
  explicit EchoNode(lcm::LCM& lcm) : Node("echo", lcm) {
    subscribe<thicket::odometry_t>(
        "PING", [this](const thicket::odometry_t& msg, const thicket::MessageInfo&) {
          thicket::odometry_t reply = msg;
          reply.sequence = msg.sequence + 1000;
          publish("PONG", reply);
          ++pings;
        });
    subscribe<thicket::depth_image_t>(
        "CAMERA_DEPTH", [this](const thicket::depth_image_t& msg, const thicket::MessageInfo&) {
          publish("DEPTH_ECHO", msg);
          ++images;
        });
  }
  int pings = 0;
  int images = 0;
};

}  // namespace

int main(int argc, char** argv) {
  thicket::NodeArgs args;
  if (auto exit_code = thicket::parseNodeArgs(argc, argv, "echo", "a test node", args)) {
    return *exit_code;
  }
  lcm::LCM lcm(args.lcm_url);
  thicket::Loop::installSignalHandlers();
  try {
    thicket::Loop loop(lcm);
    EchoNode node(lcm);
    std::printf("echo: ready on %s\n", args.lcm_url.c_str());
    std::fflush(stdout);
    const int signal = loop.run();
    std::printf("echo: stopped by signal %d after %d pings and %d images, %lld refused\n", signal,
                node.pings, node.images, static_cast<long long>(node.badMessageCount()));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "echo: %s\n", e.what());
    return 1;
  }
  return 0;
}
