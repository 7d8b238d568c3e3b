// thicket-sheriff's command line: the options (Args) and their parsing with CLI11 (parseArgs).
#pragma once

#include <optional>
#include <string>

namespace thicket::sheriff {

inline constexpr const char* kProgram = "thicket-sheriff";

struct Args {
  bool lone_ranger = false;
  bool observer = false;
  bool exit_after_script = false;
  std::string lcm_url;
  double wait_timeout_s = 0;
  double status_period_s = 1;
  std::string sheet_path;
  std::string script;
};

// Parses the command line into `args`; the exit status when main should return now.
std::optional<int> parseArgs(int argc, char** argv, Args& args);

}  // namespace thicket::sheriff
