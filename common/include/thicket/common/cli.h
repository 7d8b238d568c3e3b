// The command line of every thicket executable, parsed by CLI11 (`--flag value` and
// `--flag=value`, `-h`/`--help` everywhere). What thicket adds to CLI11 lives here: the flags
// several executables share, spelled once, number checks stricter than CLI11 2.1's own
// conversions, and one way to end on --help or a bad command line.
//
// CLI11 2.1 converts integers with strtoll/strtoull in base 0 ("010" is 8, "0x10" is 16), wraps
// "-3" into an unsigned and clamps an overflowing value, and its floating-point conversion takes
// "nan" and "inf". The validators below run on the text before that conversion and refuse all of
// these (integers only in their canonical decimal spelling).
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "thicket/common/expected.h"
#include "thicket/common/node_main.h"

namespace thicket::cli {

/// A decimal integer in [min, max], spelled canonically ("10", not "010", "+10" or "0xa").
CLI::Validator integer(int64_t min, int64_t max = std::numeric_limits<int64_t>::max());

/// A finite number in [min, max] (each item of a list option split with ->delimiter(',')).
CLI::Validator number(double min = -std::numeric_limits<double>::infinity(),
                      double max = std::numeric_limits<double>::infinity());

/// A non-empty text (a path, a URL, a name).
CLI::Validator nonEmpty();

/// `--lcm-url URL` (with `-u` when `with_short`), default $LCM_DEFAULT_URL, else the loopback URL.
/// Sets `url` to that default.
CLI::Option* addLcmUrl(CLI::App& app, std::string& url, bool with_short = false);

/// An option `name` that takes on or off into `value` (its default shown in the help).
CLI::Option* addSwitch(CLI::App& app, const std::string& name, bool& value,
                       const std::string& help);

/// `--lcm-url URL` and `--config FILE`, the flags every module node takes.
void addNodeFlags(CLI::App& app, NodeArgs& args);

/// `--seed N`: a world's seed, a decimal integer >= 0 (into an integer or an optional one).
template <class Seed>
CLI::Option* addSeed(CLI::App& app, Seed& seed,
                     const std::string& help = "the world's seed (an integer >= 0)") {
  return app.add_option("--seed", seed, help)->check(integer(0));
}

/// Prints "<program>: <message>" and a hint to --help on stderr and returns 2, the exit status of
/// a bad command line (also for what only the program can check after parsing).
int usageError(const std::string& program, const std::string& message);

/// Parses `argc`/`argv` into `app`. Returns the exit status when main should return now: 0 after
/// printing the help (-h/--help, of the program or of the subcommand asked), 2 after printing
/// "<program>: <what is wrong>" and a hint to --help on stderr. Nothing when the program goes on.
std::optional<int> parse(CLI::App& app, int argc, const char* const* argv);

/// Parses `args` (without the program name) into `app` and returns whether the help was asked
/// (its text is app.help()), or the message for the user: for parsers that tests call directly.
Expected<bool> parseArgs(CLI::App& app, std::vector<std::string> args);

}  // namespace thicket::cli
