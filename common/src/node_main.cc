#include "thicket/common/node_main.h"

#include <cstdio>
#include <cstdlib>
#include <exception>

#include "thicket/common/cli.h"

namespace thicket {

std::string defaultLcmUrl() {
  const char* env = std::getenv("LCM_DEFAULT_URL");
  return (env != nullptr && env[0] != '\0') ? std::string(env) : std::string(kLoopbackLcmUrl);
}

std::optional<int> parseNodeArgs(int argc, const char* const* argv, const std::string& program,
                                 const std::string& usage, NodeArgs& args,
                                 const std::function<void(CLI::App&)>& extend) {
  CLI::App app(usage, program);
  cli::addNodeFlags(app, args);
  const CLI::App* params =
      app.add_subcommand("params", "print every option of --config with its default and meaning");
  if (extend) extend(app);
  app.require_subcommand(0, 1);
  if (auto exit_code = cli::parse(app, argc, argv)) return exit_code;
  args.params = params->parsed();
  return std::nullopt;
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

}  // namespace thicket
