// Where LCM traffic goes by default. Loopback-only multicast: with ttl=0 nothing leaves the host.
#pragma once

#include <string>

namespace thicket {

inline constexpr const char* kLoopbackLcmUrl = "udpm://239.255.76.67:7667?ttl=0";

/// $LCM_DEFAULT_URL when set and non-empty, else kLoopbackLcmUrl.
std::string defaultLcmUrl();

}  // namespace thicket
