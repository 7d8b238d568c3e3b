// The command lines of thicket-bench's subcommands, parsed by CLI11 through common/cli.h: each
// command puts its flags on an app bound to its options struct, whose `help` receives the help
// text when -h/--help is given; and the messages of a command.
#pragma once

#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "thicket/common/cli.h"
#include "thicket/common/expected.h"

namespace thicket::bench {

/// Parses the arguments after `thicket-bench <command>` into `options` with the flags `add` puts
/// on the app. Returns the options (with the help text in `help` after -h/--help), or the message
/// for the user.
template <class Options>
Expected<Options> parseCommand(const std::string& command, const std::string& description,
                               const std::vector<std::string>& args,
                               const std::function<void(CLI::App&, Options&)>& add,
                               Options options = {}) {
  CLI::App app(description, "thicket-bench " + command);
  add(app, options);
  const Expected<bool> help = cli::parseArgs(app, args);
  if (!help) return unexpected(help.error());
  if (*help) options.help = app.help();
  return options;
}

/// The exit status and message of a refused `thicket-bench <command>` command line.
inline int usageError(const std::string& command, const std::string& message) {
  return cli::usageError("thicket-bench " + command, message);
}

/// A warning of `thicket-bench <command>` on stderr.
inline void warn(const std::string& command, const std::string& message) {
  std::fprintf(stderr, "thicket-bench %s: %s\n", command.c_str(), message.c_str());
}

/// `items` with `separator` between them, for help texts and messages.
inline std::string joined(const std::vector<std::string>& items, const char* separator = ", ") {
  std::string text;
  for (const std::string& item : items) text += (text.empty() ? "" : separator) + item;
  return text;
}

}  // namespace thicket::bench
