// A command's exec string split into the argv and environment of its process, without a shell,
// as procman deputies do it (docs/procman.md).
//
// Rules:
//  - Unquoted whitespace separates words.
//  - '...' groups literally: no escapes, no expansion inside.
//  - "..." groups; inside, a backslash escapes the next character and $ expands.
//  - Outside single quotes a backslash makes the next character literal (a trailing backslash
//    stays a backslash).
//  - $NAME and ${NAME} (NAME = [A-Za-z_][A-Za-z0-9_]*) expand from the given environment; an
//    undefined one, or a '$' not followed by a name, stays literal. Expanded values are never
//    split into words.
//  - Leading words of the form NAME=value (NAME unquoted) are environment assignments for the
//    child. Every expansion, in assignments and in argv alike, reads the given environment, not
//    earlier assignments.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "thicket/common/expected.h"

namespace thicket::procman {

/// Variable name → value.
using Environment = std::map<std::string, std::string>;

struct CommandLine {
  std::vector<std::string> argv;  ///< never empty: argv[0] is the program
  /// Leading NAME=value assignments, in order (a later one for the same name wins).
  std::vector<std::pair<std::string, std::string>> assignments;
};

/// Splits `exec`. Errors: an unterminated quote (with its column, 1-based), or no program word
/// (empty, only whitespace, or only assignments).
Expected<CommandLine> splitCommandLine(const std::string& exec, const Environment& environment);

/// The calling process's environment (environ).
Environment currentEnvironment();

/// `base` with the command's assignments applied, as "NAME=value" strings for execve.
std::vector<std::string> childEnvironment(const Environment& base, const CommandLine& command);

}  // namespace thicket::procman
