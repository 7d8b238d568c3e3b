// thicket-vio-bridge: VIO odometry (in the VIO's frames) to thicket's gated state estimate.
//
//   thicket-vio-bridge [--lcm-url URL] [--config vio_bridge.yaml]
//   thicket-vio-bridge params        (every option of --config, with its default)
#include <cstdio>
#include <string>

#include "thicket/common/loop.h"
#include "thicket/common/node_main.h"
#include "vio_bridge_node.h"

int main(int argc, char** argv) {
  const std::string program = "thicket-vio-bridge";
  thicket::NodeArgs args;
  thicket::vio_bridge::VioBridgeNodeOptions options;
  if (auto exit_code = thicket::startNode(argc, argv, program,
                                          "usage: thicket-vio-bridge [--config vio_bridge.yaml]\n  "
                                          "     thicket-vio-bridge params\n",
                                          args, options)) {
    return *exit_code;
  }
  // Wall-clock time only measures durations; no decision reads it.
  return thicket::runNode(program, args.lcm_url, [&](lcm::LCM& lcm, thicket::Loop& loop) {
    thicket::vio_bridge::VioBridgeNode node(lcm, options, thicket::steadyClockMillis);
    loop.run();
    std::printf("%s: %s\n", program.c_str(), node.summary().c_str());
    return 0;
  });
}
