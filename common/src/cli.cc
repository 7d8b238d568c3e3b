#include "thicket/common/cli.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "thicket/common/node_main.h"
#include "thicket/common/number_text.h"

namespace thicket::cli {
namespace {

std::string numberText(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
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
  const std::optional<double> value = finiteNumber(text);
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
  // An int's or an int64_t's whole upper range reads as none.
  const bool unbounded =
      max == std::numeric_limits<int64_t>::max() || max == std::numeric_limits<int>::max();
  const std::string range = unbounded
                                ? " >= " + std::to_string(min)
                                : " in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
  return CLI::Validator(
      [min, max, range](const std::string& text) -> std::string {
        const std::optional<int64_t> value = integerNumber<int64_t>(text);
        // Only the canonical spelling: "010" would reach CLI11's base-0 conversion as octal.
        if (!value || std::to_string(*value) != text || *value < min || *value > max) {
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

CLI::Option* addSwitch(CLI::App& app, const std::string& name, bool& value,
                       const std::string& help) {
  return app.add_option(name, value, help)
      ->transform(CLI::Validator(
          [](std::string& text) -> std::string {
            if (text != "on" && text != "off") return "must be on or off, not '" + text + "'";
            text = text == "on" ? "true" : "false";
            return {};
          },
          "on|off"))
      ->default_str(value ? "on" : "off");
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
