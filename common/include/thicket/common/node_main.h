// What every thicket-<module> executable shares: the LCM URL default and the common flags.
#pragma once

#include <cstdio>
#include <functional>
#include <optional>
#include <string>

#include <lcm/lcm-cpp.hpp>

#include "thicket/common/expected.h"
#include "thicket/common/loop.h"
#include "thicket/common/params.h"

namespace CLI {
class App;
}

namespace thicket {

/// Loopback-only multicast: with ttl=0 nothing leaves the host (docs/design.md §5).
inline constexpr const char* kLoopbackLcmUrl = "udpm://239.255.76.67:7667?ttl=0";

/// $LCM_DEFAULT_URL when set and non-empty, else kLoopbackLcmUrl.
std::string defaultLcmUrl();

struct NodeArgs {
  std::string lcm_url;      // --lcm-url URL, default defaultLcmUrl()
  std::string config_path;  // --config FILE, empty when not given
  bool params = false;      // the `params` command: print every option with its default
};

/// Parses a node's command line, `[--lcm-url URL] [--config FILE]` or `params` (cli.h; `usage` is
/// the program's description in its --help). Returns the exit status when main should return now
/// (0 after --help, 2 after a message on a bad command line), else nothing and fills `args`.
/// `extend` may add the program's own subcommands (thicket-stereo-depth's `file`).
std::optional<int> parseNodeArgs(int argc, const char* const* argv, const std::string& program,
                                 const std::string& usage, NodeArgs& args,
                                 const std::function<void(CLI::App&)>& extend = nullptr);

/// Prints "<program>: <message>" to stderr and returns 2, the exit code of a refused start.
int failNode(const std::string& program, const std::string& message);

/// The rest of a node's main: opens LCM at `lcm_url`, installs the signal handlers and runs
/// `body` with the LCM and a Loop on it (body builds the node, runs the loop, prints its summary).
/// Returns body's exit code, or failNode's when LCM does not open or body throws.
int runNode(const std::string& program, const std::string& lcm_url,
            const std::function<int(lcm::LCM&, Loop&)>& body);

/// The start of a node's main that takes no arguments of its own: `<program> params` prints every
/// option with its default; -h/--help prints `usage` and the flags; any other argument is
/// refused; --config loads `options`. Returns the exit code when main should return now (0 after
/// params or help, 2 with a message on an error), else nothing and fills `args`.
template <class Options>
std::optional<int> startNode(int argc, char** argv, const std::string& program,
                             const std::string& usage, NodeArgs& args, Options& options,
                             const std::function<void(CLI::App&)>& extend = nullptr) {
  if (auto exit_code = parseNodeArgs(argc, argv, program, usage, args, extend)) return exit_code;
  if (args.params) {
    std::printf("%s", describeParams<Options>().c_str());
    return 0;
  }
  if (!args.config_path.empty()) {
    try {
      options = loadParams<Options>(args.config_path);
    } catch (const ParamError& e) {
      return failNode(program, e.what());
    }
  }
  return std::nullopt;
}

}  // namespace thicket
