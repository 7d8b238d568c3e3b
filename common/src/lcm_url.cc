#include "thicket/common/lcm_url.h"

#include <cstdlib>

namespace thicket {

std::string defaultLcmUrl() {
  const char* env = std::getenv("LCM_DEFAULT_URL");
  return (env != nullptr && env[0] != '\0') ? std::string(env) : std::string(kLoopbackLcmUrl);
}

}  // namespace thicket
