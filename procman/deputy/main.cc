// thicket-deputy: runs the commands procman sheriffs order on this host (procman_lcm protocol).
//
//   thicket-deputy [-i ID] [-u URL | --lcm-url URL] [-l LOGFILE]
#include <unistd.h>

#include <string>

#include "thicket/common/cli.h"
#include "thicket/procman/deputy.h"

namespace {

std::string hostName() {
  char name[256] = {};
  if (::gethostname(name, sizeof name - 1) != 0 || name[0] == '\0') return "localhost";
  return name;
}

}  // namespace

int main(int argc, char** argv) {
  thicket::procman::DeputyOptions options;
  options.id = hostName();
  CLI::App app(
      "thicket-deputy: runs the commands procman sheriffs order on this host (procman_lcm).",
      "thicket-deputy");
  app.footer(
      "Exit status: 0 after SIGINT/SIGTERM (every command stopped), 1 when LCM or the system\n"
      "fails, 2 when the arguments are wrong or another deputy with the same id is running.");
  app.add_option("-i,--id", options.id, "deputy id the sheriff addresses (default: the host name)")
      ->check(thicket::cli::nonEmpty());
  thicket::cli::addLcmUrl(app, options.lcm_url, true);
  app.add_option("-l,--log", options.log_path, "also append the deputy's own log lines to FILE")
      ->check(thicket::cli::nonEmpty());
  if (auto exit_code = thicket::cli::parse(app, argc, argv)) return *exit_code;
  return thicket::procman::runDeputy(options);
}
