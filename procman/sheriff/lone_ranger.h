// Lone-ranger mode (-l): local thicket-deputy processes that die with the sheriff.
#pragma once

#include <sys/types.h>

#include <string>
#include <vector>

#include "thicket/procman/sheet.h"

namespace thicket::sheriff {

struct LocalDeputy {
  std::string id;  // empty: the deputy's default (host name)
  pid_t pid = -1;
};

// Starts a thicket-deputy (the one next to this executable) on `lcm_url` for each deputy id the
// sheet names, appending them to `deputies`; false (the started ones stopped) when one cannot be.
bool spawnLocalDeputies(const procman::Sheet& sheet, const std::string& lcm_url,
                        std::vector<LocalDeputy>& deputies);

// Says which local deputies have exited, and forgets their process.
void checkLocalDeputies(std::vector<LocalDeputy>& deputies);

// Stops the local deputies (SIGTERM, then SIGKILL after a few seconds) and reaps them.
void stopDeputies(std::vector<LocalDeputy>& deputies);

}  // namespace thicket::sheriff
