// thicket-mapper: the mapping process.
//
//   thicket-mapper [--lcm-url URL] [--config mapper.yaml]
//   thicket-mapper params        (every option of --config, with its default)
#include <chrono>
#include <cstdio>
#include <string>

#include "mapper_node.h"
#include "thicket/common/loop.h"
#include "thicket/common/node_main.h"

int main(int argc, char** argv) {
  const std::string program = "thicket-mapper";
  thicket::NodeArgs args;
  thicket::mapper::MapperNodeOptions options;
  if (auto exit_code = thicket::startNode(
          argc, argv, program,
          "usage: thicket-mapper [--config mapper.yaml]\n       thicket-mapper params\n", args,
          options)) {
    return *exit_code;
  }
  // Only measured durations and the map id read the wall clock; no decision does.
  const auto now_ms = thicket::steadyClockMillis;
  const int64_t map_id = options.map_id != 0
                             ? options.map_id
                             : std::chrono::duration_cast<std::chrono::microseconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count();
  return thicket::runNode(program, args.lcm_url, [&](lcm::LCM& lcm, thicket::Loop& loop) {
    thicket::mapper::MapperNode node(lcm, options, map_id, now_ms);
    loop.run();
    std::printf("%s: %s\n", program.c_str(), node.summary().c_str());
    if (const std::string saved = node.saveIfConfigured(); !saved.empty()) {
      std::printf("%s: map saved to %s\n", program.c_str(), saved.c_str());
    }
    node.removeCheckpoint();  // a clean stop: only a crash leaves the checkpoint behind
    return 0;
  });
}
