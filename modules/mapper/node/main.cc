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

namespace {

using thicket::mapper::MapperNodeOptions;

int fail(const std::string& message) {
  std::fprintf(stderr, "thicket-mapper: %s\n", message.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 2 && std::string(argv[1]) == "params") {
    std::printf("%s", thicket::describeParams<MapperNodeOptions>().c_str());
    return 0;
  }
  auto args = thicket::parseNodeArgs(argc, argv);
  if (!args) return fail(args.error());
  if (args->help) {
    std::printf("usage: thicket-mapper [--config mapper.yaml]\n       thicket-mapper params\n%s",
                thicket::commonNodeFlagsHelp().c_str());
    return 0;
  }
  if (!args->options.empty()) return fail("unexpected argument '" + args->options.front() + "'");
  MapperNodeOptions options;
  if (!args->config_path.empty()) {
    try {
      options = thicket::loadParams<MapperNodeOptions>(args->config_path);
    } catch (const thicket::ParamError& e) {
      return fail(e.what());
    }
  }
  // Only measured durations and the map id read the wall clock; no decision does.
  const auto now_ms = [] {
    return std::chrono::duration<double, std::milli>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
  const int64_t map_id = options.map_id != 0
                             ? options.map_id
                             : std::chrono::duration_cast<std::chrono::microseconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count();
  lcm::LCM lcm(args->lcm_url);
  if (!lcm.good()) return fail("cannot open LCM at " + args->lcm_url);
  thicket::Loop::installSignalHandlers();
  try {
    thicket::Loop loop(lcm);
    thicket::mapper::MapperNode node(lcm, options, map_id, now_ms);
    loop.run();
    std::printf("thicket-mapper: %s\n", node.summary().c_str());
    if (const std::string saved = node.saveIfConfigured(); !saved.empty()) {
      std::printf("thicket-mapper: map saved to %s\n", saved.c_str());
    }
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  return 0;
}
