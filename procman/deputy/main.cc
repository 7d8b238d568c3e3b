// thicket-deputy: runs the commands procman sheriffs order on this host (procman_lcm protocol).
//
//   thicket-deputy [-i ID] [-u URL | --lcm-url URL] [-l LOGFILE]
#include <unistd.h>

#include <cstdio>
#include <string>

#include "thicket/common/node_main.h"
#include "thicket/procman/deputy.h"

namespace {

const char* const kUsage =
    "usage: thicket-deputy [-i ID] [-u URL | --lcm-url URL] [-l LOGFILE]\n"
    "\n"
    "  -i, --id ID        deputy id the sheriff addresses (default: the host name)\n"
    "  -u, --lcm-url URL  LCM URL (default: $LCM_DEFAULT_URL, else "
    "udpm://239.255.76.67:7667?ttl=0)\n"
    "  -l, --log FILE     also append the deputy's own log lines to FILE\n"
    "  -h, --help         this help\n"
    "\n"
    "Exit status: 0 after SIGINT/SIGTERM (every command stopped), 1 when LCM or the system\n"
    "fails, 2 when the arguments are wrong or another deputy with the same id is running.\n";

std::string hostName() {
  char name[256] = {};
  if (::gethostname(name, sizeof name - 1) != 0 || name[0] == '\0') return "localhost";
  return name;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string program = "thicket-deputy";
  thicket::procman::DeputyOptions options;
  options.id = hostName();
  options.lcm_url = thicket::defaultLcmUrl();
  for (int i = 1; i < argc; ++i) {
    std::string flag = argv[i];
    std::string value;
    bool has_value = false;
    if (const size_t eq = flag.find('='); flag.rfind("--", 0) == 0 && eq != std::string::npos) {
      value = flag.substr(eq + 1);
      flag = flag.substr(0, eq);
      has_value = true;
    }
    if (flag == "-h" || flag == "--help") {
      std::printf("%s", kUsage);
      return 0;
    }
    std::string* target = nullptr;
    if (flag == "-i" || flag == "--id") {
      target = &options.id;
    } else if (flag == "-u" || flag == "--lcm-url") {
      target = &options.lcm_url;
    } else if (flag == "-l" || flag == "--log") {
      target = &options.log_path;
    } else {
      std::fprintf(stderr, "%s", kUsage);
      return thicket::failNode(program, "unexpected argument '" + flag + "'");
    }
    if (!has_value) {
      if (i + 1 >= argc) return thicket::failNode(program, flag + " needs a value");
      value = argv[++i];
    }
    if (value.empty()) return thicket::failNode(program, flag + " needs a non-empty value");
    *target = value;
  }
  return thicket::procman::runDeputy(options);
}
