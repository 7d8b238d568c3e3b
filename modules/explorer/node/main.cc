// thicket-explorer: the intermediate goal selection process.
//
//   thicket-explorer [--lcm-url URL] [--config explorer.yaml]
//   thicket-explorer params        (every option of --config, with its default)
#include <cstdio>
#include <string>

#include "explorer_node.h"
#include "thicket/common/loop.h"
#include "thicket/common/node_main.h"

int main(int argc, char** argv) {
  const std::string program = "thicket-explorer";
  thicket::NodeArgs args;
  thicket::explorer::ExplorerNodeOptions options;
  if (auto exit_code = thicket::startNode(
          argc, argv, program,
          "usage: thicket-explorer [--config explorer.yaml]\n       thicket-explorer params\n",
          args, options)) {
    return *exit_code;
  }
  // Wall-clock time only measures durations; no decision reads it.
  return thicket::runNode(program, args.lcm_url, [&](lcm::LCM& lcm, thicket::Loop& loop) {
    thicket::explorer::ExplorerNode node(lcm, options, thicket::steadyClockMillis);
    loop.run();
    std::printf("%s: %s\n", program.c_str(), node.summary().c_str());
    return 0;
  });
}
