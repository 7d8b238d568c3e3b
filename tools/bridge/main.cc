// thicket-lcm-bridge: the vehicle's own bus and the radio link's bus, kept apart so that a radio
// dropout cannot silence the on-board graph (see bridge.h and the README, "Two hosts").
#include <poll.h>
#include <signal.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <regex>
#include <string>
#include <thread>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "bridge.h"
#include "thicket/common/node_main.h"

namespace {

volatile sig_atomic_t g_stop = 0;

void onSignal(int) {
  g_stop = 1;
}

std::string counters(const char* name, const thicket::bridge::DirectionCounters& c) {
  char text[200];
  std::snprintf(text, sizeof text, "%s %lld copied (%lld B), %lld failed, %lld not for it", name,
                static_cast<long long>(c.copied), static_cast<long long>(c.bytes),
                static_cast<long long>(c.failed), static_cast<long long>(c.filtered));
  return text;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "thicket-lcm-bridge: copies LCM traffic between the vehicle's own bus (--vehicle) and the "
      "bus it shares with the ground over the radio link (--link). The on-board graph talks on "
      "the vehicle bus, which needs no link (ttl=0, the vehicle's loopback); a radio dropout "
      "drops only what crosses. Channels matching --up (and not --up-exclude) go to the link, "
      "channels matching --down come from it; the bridge's own copies are never copied back. "
      "Prints what crossed every --report seconds and when the link fails or comes back."};
  std::string vehicle_url = thicket::defaultLcmUrl();
  std::string link_url;
  std::string up = ".*";
  std::string up_exclude = "STEREO.*|CAMERA_.*|MAP_.*";
  std::string down = "PM_ORDERS|PM_DISCOVER|MISSION_GOAL";
  double report = 5.0;
  app.add_option("--vehicle", vehicle_url, "the vehicle's bus")->capture_default_str();
  app.add_option("--link", link_url,
                 "the bus shared with the ground: a udpm URL on a group of its own routed over "
                 "the radio, with the ttl the radio needs (README, Two hosts)")
      ->required();
  app.add_option("--up", up, "channels copied to the link (regex)")->capture_default_str();
  app.add_option("--up-exclude", up_exclude,
                 "... except these (regex; by default the images and map snapshots)")
      ->capture_default_str();
  app.add_option("--down", down, "channels copied from the link (regex)")->capture_default_str();
  app.add_option("--report", report, "seconds between counter lines")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  thicket::bridge::BridgeOptions options;
  try {
    options.up = std::regex(up);
    options.up_exclude = std::regex(up_exclude);
    options.down = std::regex(down);
  } catch (const std::regex_error& e) {
    std::fprintf(stderr, "thicket-lcm-bridge: bad regex: %s\n", e.what());
    return 2;
  }
  if (vehicle_url == link_url) {
    std::fprintf(stderr, "thicket-lcm-bridge: --vehicle and --link are the same bus\n");
    return 2;
  }
  struct sigaction action {};
  action.sa_handler = onSignal;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);

  lcm::LCM vehicle(vehicle_url);
  if (!vehicle.good()) {
    std::fprintf(stderr, "thicket-lcm-bridge: cannot open the vehicle bus %s\n",
                 vehicle_url.c_str());
    return 1;
  }
  // The link may be down at start (no route for its group yet): wait for it.
  std::unique_ptr<lcm::LCM> link;
  for (bool said = false; !g_stop;) {
    link = std::make_unique<lcm::LCM>(link_url);
    if (link->good()) break;
    if (!said) {
      std::printf("cannot open the link bus %s: retrying every second\n", link_url.c_str());
      std::fflush(stdout);
      said = true;
    }
    std::this_thread::sleep_for(std::chrono::seconds(1));
  }
  if (g_stop) return 0;

  thicket::bridge::Bridge bridge(vehicle, *link, options);
  std::printf("bridging %s (vehicle) and %s (link): up '%s' except '%s', down '%s'\n",
              vehicle_url.c_str(), link_url.c_str(), up.c_str(), up_exclude.c_str(), down.c_str());
  std::fflush(stdout);
  const auto period = std::chrono::duration<double>(report);
  auto next_report = std::chrono::steady_clock::now() + period;
  bool link_up = true;
  int64_t failed_before = 0;
  while (!g_stop) {
    pollfd fds[2] = {{vehicle.getFileno(), POLLIN, 0}, {link->getFileno(), POLLIN, 0}};
    if (::poll(fds, 2, 200) > 0) {
      if (fds[0].revents & POLLIN) vehicle.handleTimeout(0);
      if (fds[1].revents & POLLIN) link->handleTimeout(0);
    }
    if (bridge.linkUp() != link_up) {
      link_up = bridge.linkUp();
      if (link_up) {
        std::printf("link back: %lld copies toward it dropped while it was down\n",
                    static_cast<long long>(bridge.up().failed - failed_before));
      } else {
        failed_before = bridge.up().failed - 1;
        std::printf("link down: publishing to %s fails; the vehicle bus goes on\n",
                    link_url.c_str());
      }
      std::fflush(stdout);
    }
    if (std::chrono::steady_clock::now() >= next_report) {
      next_report += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
      std::printf("%s; %s\n", counters("up", bridge.up()).c_str(),
                  counters("down", bridge.down()).c_str());
      std::fflush(stdout);
    }
  }
  std::printf("stopping: %s; %s\n", counters("up", bridge.up()).c_str(),
              counters("down", bridge.down()).c_str());
  return 0;
}
