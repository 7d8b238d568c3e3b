// What every thicket-<module> executable shares: the LCM URL default and the common flags.
#pragma once

#include <string>
#include <vector>

#include "thicket/common/expected.h"

namespace thicket {

/// Loopback-only multicast: with ttl=0 nothing leaves the host (DESIGN §5).
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

}  // namespace thicket
