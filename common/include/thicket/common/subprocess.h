// Running a helper program (the matplotlib scripts that draw figures) without a shell.
#pragma once

#include <string>
#include <vector>

namespace thicket {

/// Runs `args` (args[0] is the program's path; no shell, no PATH search) with stdin from
/// /dev/null and stdout and stderr into the file `log`, and waits for it. Returns empty when it
/// exited with status 0 (`log` is then removed), else what happened: the command, how it ended
/// and the end of its output.
std::string runProgram(std::vector<std::string> args, const std::string& log);

}  // namespace thicket
