// Running a thicket executable as a user would, for command-line tests.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace thicket::testing {

struct CliResult {
  int status;          // the exit status, -1 if the process did not exit normally
  std::string output;  // stdout and stderr together
};

inline CliResult runCommand(const std::string& command_line) {
  const std::string command = command_line + " 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return {-1, "popen failed"};
  std::string output;
  char buffer[4096];
  while (size_t n = std::fread(buffer, 1, sizeof(buffer), pipe)) output.append(buffer, n);
  const int status = ::pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

}  // namespace thicket::testing
