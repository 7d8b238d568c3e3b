// thicket-local-planner: the local planning process.
//
//   thicket-local-planner [--lcm-url URL] [--config local_planner.yaml]
//   thicket-local-planner params        (every option of --config, with its default)
#include <cstdio>
#include <string>

#include "local_planner_node.h"
#include "thicket/common/loop.h"
#include "thicket/common/node_main.h"

int main(int argc, char** argv) {
  const std::string program = "thicket-local-planner";
  thicket::NodeArgs args;
  thicket::local_planner::LocalPlannerNodeOptions options;
  if (auto exit_code = thicket::startNode(argc, argv, program,
                                          "usage: thicket-local-planner [--config "
                                          "local_planner.yaml]\n       thicket-local-planner "
                                          "params\n",
                                          args, options)) {
    return *exit_code;
  }
  // Wall-clock time measures durations and paces the vehicle's timers; no decision reads it.
  const auto now_ms = thicket::steadyClockMillis;
  return thicket::runNode(program, args.lcm_url, [&](lcm::LCM& lcm, thicket::Loop& loop) {
    thicket::local_planner::LocalPlannerNode node(lcm, options, now_ms);
    if (options.replan_rate > 0) {
      loop.addTimer(static_cast<int64_t>(1e6 / options.replan_rate), [&node] { node.replan(); });
    }
    // The setpoint timer's state, here: the timer runs in loop.run(), after the block below.
    int64_t seen_utime = -1;
    int64_t seen_at = 0;
    if (options.setpoint_rate > 0) {
      // Setpoints are for the estimator's clock: the newest estimate's time plus the wall time
      // since it arrived.
      loop.addTimer(static_cast<int64_t>(1e6 / options.setpoint_rate), [&] {
        const auto& state = node.latestState();
        if (!state) return;
        const int64_t now = thicket::steadyClockMicros();
        if (state->utime != seen_utime) {
          seen_utime = state->utime;
          seen_at = now;
        }
        node.publishSetpoint(seen_utime + (now - seen_at));
      });
    }
    if (options.explorer_timeout > 0) {
      loop.addTimer(500'000, [&node] { node.expireExplorerWait(thicket::steadyClockMicros()); });
    }
    loop.run();
    std::printf("%s: %s\n", program.c_str(), node.summary().c_str());
    return 0;
  });
}
