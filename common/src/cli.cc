#include "thicket/common/cli.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "thicket/common/node_main.h"

namespace thicket::cli {
namespace {

std::string numberText(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

// `text`, all of it, as a finite number, or nothing.
std::optional<double> finite(const std::string& text) {
  double value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size() ||
      !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

std::string trimmed(const std::string& text) {
  return text.empty() ? text : text.substr(1);
}

// " in [min, max]", " >= min", " <= max" or "".
std::string rangeText(double min, double max) {
  if (std::isfinite(min) && std::isfinite(max)) {
    return " in [" + numberText(min) + ", " + numberText(max) + "]";
  }
  if (std::isfinite(min)) return " >= " + numberText(min);
  if (std::isfinite(max)) return " <= " + numberText(max);
  return "";
}

std::string checkNumber(const std::string& text, double min, double max) {
  const std::optional<double> value = finite(text);
  if (value && *value >= min && *value <= max) return {};
  return "must be a number" + rangeText(min, max) + ", not '" + text + "'";
}

// What is wrong, for the user. CLI11 checks required flags and subcommands before it refuses
// unknown arguments: "thicket-sim fly" would only say that a subcommand is required.
std::string errorText(const CLI::App& app, const CLI::ParseError& error) {
  const std::vector<std::string> extra = app.remaining(true);
  if (dynamic_cast<const CLI::RequiredError*>(&error) != nullptr && !extra.empty()) {
    return "unexpected argument '" + extra.front() + "' (" + error.what() + ")";
  }
  return error.what();
}

}  // namespace

CLI::Validator integer(int64_t min, int64_t max) {
  const std::string range = max == std::numeric_limits<int64_t>::max()
                                ? " >= " + std::to_string(min)
                                : " in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
  return CLI::Validator(
      [min, max, range](const std::string& text) -> std::string {
        int64_t value = 0;
        const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
        // Only the canonical spelling: "010" would reach CLI11's base-0 conversion as octal.
        if (text.empty() || error != std::errc() || end != text.data() + text.size() ||
            std::to_string(value) != text || value < min || value > max) {
          return "must be an integer" + range + ", not '" + text + "'";
        }
        return {};
      },
      trimmed(range));
}

CLI::Validator number(double min, double max) {
  return CLI::Validator([min, max](std::string& text) { return checkNumber(text, min, max); },
                        trimmed(rangeText(min, max)));
}

CLI::Validator nonEmpty() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        return text.empty() ? "needs a non-empty value" : "";
      },
      "");
}

CLI::Option* addLcmUrl(CLI::App& app, std::string& url, bool with_short) {
  url = defaultLcmUrl();
  return app
      .add_option(with_short ? "-u,--lcm-url" : "--lcm-url", url,
                  "LCM URL (default: $LCM_DEFAULT_URL, else " + std::string(kLoopbackLcmUrl) + ")")
      ->check(nonEmpty());
}

void addNodeFlags(CLI::App& app, NodeArgs& args) {
  addLcmUrl(app, args.lcm_url);
  app.add_option("--config", args.config_path, "parameter file (YAML)")->check(nonEmpty());
}

int usageError(const std::string& program, const std::string& message) {
  std::fprintf(stderr, "%s: %s\nRun with --help for more information.\n", program.c_str(),
               message.c_str());
  return 2;
}

std::optional<int> parse(CLI::App& app, int argc, const char* const* argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    return usageError(app.get_name(), errorText(app, e));
  }
  return std::nullopt;
}

Expected<bool> parseArgs(CLI::App& app, std::vector<std::string> args) {
  std::reverse(args.begin(), args.end());  // CLI11 takes the arguments last first
  try {
    app.parse(args);
  } catch (const CLI::Success&) {
    return true;
  } catch (const CLI::ParseError& e) {
    return unexpected(errorText(app, e));
  }
  return false;
}

}  // namespace thicket::cli
