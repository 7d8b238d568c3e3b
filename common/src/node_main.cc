#include "thicket/common/node_main.h"

#include <cstdio>
#include <cstdlib>
#include <exception>

namespace thicket {

std::string defaultLcmUrl() {
  const char* env = std::getenv("LCM_DEFAULT_URL");
  return (env != nullptr && env[0] != '\0') ? std::string(env) : std::string(kLoopbackLcmUrl);
}

Expected<NodeArgs> parseNodeArgs(int argc, const char* const* argv) {
  NodeArgs args;
  args.lcm_url = defaultLcmUrl();
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    std::string* target = nullptr;
    std::string flag = arg;
    std::string value;
    bool has_value = false;
    if (const size_t eq = arg.find('='); arg.rfind("--", 0) == 0 && eq != std::string::npos) {
      flag = arg.substr(0, eq);
      value = arg.substr(eq + 1);
      has_value = true;
    }
    if (flag == "--lcm-url") {
      target = &args.lcm_url;
    } else if (flag == "--config") {
      target = &args.config_path;
    } else if (arg == "-h" || arg == "--help") {
      args.help = true;
      continue;
    } else {
      args.options.push_back(arg);
      continue;
    }
    if (!has_value) {
      if (i + 1 >= argc) return unexpected(flag + " needs a value");
      value = argv[++i];
    }
    if (value.empty()) return unexpected(flag + " needs a non-empty value");
    *target = value;
  }
  return args;
}

int runNode(const std::string& program, const std::string& lcm_url,
            const std::function<int(lcm::LCM&, Loop&)>& body) {
  lcm::LCM lcm(lcm_url);
  if (!lcm.good()) return failNode(program, "cannot open LCM at " + lcm_url);
  Loop::installSignalHandlers();
  try {
    Loop loop(lcm);
    return body(lcm, loop);
  } catch (const std::exception& e) {
    return failNode(program, e.what());
  }
}

int failNode(const std::string& program, const std::string& message) {
  std::fprintf(stderr, "%s: %s\n", program.c_str(), message.c_str());
  return 2;
}

std::string commonNodeFlagsHelp() {
  return "  --lcm-url URL   LCM URL (default: $LCM_DEFAULT_URL, else " +
         std::string(kLoopbackLcmUrl) +
         ")\n"
         "  --config FILE   parameter file (YAML)\n"
         "  -h, --help      this help\n";
}

}  // namespace thicket
