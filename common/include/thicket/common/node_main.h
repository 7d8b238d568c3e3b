// What every thicket-<module> executable shares: the LCM URL default and the common flags.
#pragma once

#include <cstdio>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "thicket/common/expected.h"
#include "thicket/common/loop.h"
#include "thicket/common/params.h"

namespace thicket {

/// Loopback-only multicast: with ttl=0 nothing leaves the host (docs/design.md §5).
inline constexpr const char* kLoopbackLcmUrl = "udpm://239.255.76.67:7667?ttl=0";

/// $LCM_DEFAULT_URL when set and non-empty, else kLoopbackLcmUrl.
std::string defaultLcmUrl();

struct NodeArgs {
  std::string lcm_url;               // --lcm-url URL, default defaultLcmUrl()
  std::string config_path;           // --config FILE, empty when not given
  bool help = false;                 // -h or --help
  std::vector<std::string> options;  // everything else, in order, for the node to parse
};

/// Parses the flags every node takes (both "--flag value" and "--flag=value"). A flag without
/// its value or an empty value is an error.
Expected<NodeArgs> parseNodeArgs(int argc, const char* const* argv);

/// The help text of the common flags, for a node's usage message.
std::string commonNodeFlagsHelp();

/// Prints "<program>: <message>" to stderr and returns 2, the exit code of a refused start.
int failNode(const std::string& program, const std::string& message);

/// The rest of a node's main: opens LCM at `lcm_url`, installs the signal handlers and runs
/// `body` with the LCM and a Loop on it (body builds the node, runs the loop, prints its summary).
/// Returns body's exit code, or failNode's when LCM does not open or body throws.
int runNode(const std::string& program, const std::string& lcm_url,
            const std::function<int(lcm::LCM&, Loop&)>& body);

/// The start of a node's main that takes no arguments of its own: `<program> params` prints every
/// option with its default; -h/--help prints `usage` and the common flags; any other argument is
/// refused; --config loads `options`. Returns the exit code when main should return now (0 after
/// params or help, 2 with a message on an error), else nothing and fills `args`.
template <class Options>
std::optional<int> startNode(int argc, char** argv, const std::string& program,
                             const std::string& usage, NodeArgs& args, Options& options) {
  if (argc >= 2 && std::string(argv[1]) == "params") {
    std::printf("%s", describeParams<Options>().c_str());
    return 0;
  }
  auto parsed = parseNodeArgs(argc, argv);
  if (!parsed) return failNode(program, parsed.error());
  if (parsed->help) {
    std::printf("%s%s", usage.c_str(), commonNodeFlagsHelp().c_str());
    return 0;
  }
  if (!parsed->options.empty()) {
    return failNode(program, "unexpected argument '" + parsed->options.front() + "'");
  }
  if (!parsed->config_path.empty()) {
    try {
      options = loadParams<Options>(parsed->config_path);
    } catch (const ParamError& e) {
      return failNode(program, e.what());
    }
  }
  args = *parsed;
  return std::nullopt;
}

}  // namespace thicket
