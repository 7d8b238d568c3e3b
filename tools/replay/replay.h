// Replaying a recorded flight into the real nodes (docs/design.md §4): the VIO bridge, the mapper,
// the explorer and the local planner, each hosted on its own memq:// LCM, fed the log's inputs in
// log order, with every message they publish captured.
//
// Why one LCM per node, not one for all: in the recorded graph everything shared one memq://
// queue, so each node saw its inputs in the queue's order, and the log (written by a recorder on
// that queue) holds exactly that order. The simulator publishes a whole frame at once (odometry,
// then the depth image), and the bridge's STATE_ESTIMATE for the first pose queued behind the
// image; replayed through one queue, drained after each event, the mapper would see that estimate
// before the image and answer differently (no "pending" status). So the replay routes messages
// itself: a log event from outside the replayed modules goes to every node when the log reaches
// it; the k-th replayed message on an output channel goes to the other nodes where the log holds
// the k-th recorded one. Each node then sees its inputs in the recorded order, the outputs of the
// other replayed nodes standing in for the recorded ones.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <thicket/sim_world_t.hpp>

#include "thicket/common/expected.h"
#include "thicket/common/lcm_log.h"
#include "trials.h"

namespace thicket::replay {

/// What a replayed module consumes and publishes, as its node subscribes and publishes.
struct ReplayedModule {
  const char* name;
  std::vector<std::string> inputs;
  std::vector<std::string> outputs;
};
/// The replayed modules, in the order the recorded graph subscribed them (tools/bench/trials.cc),
/// which is the order each message reached them.
const std::vector<ReplayedModule>& replayedModules();

/// The nodes' options, as the recorded trial built them.
using GraphOptions = bench::TrialGraphOptions;

/// The options a benchmark trial gives the nodes (bench::trialGraphOptions) for `method` (soft
/// goal finding) on the world `world` (its SIM_WORLD message: the seed and the flight volume).
/// The error names an unknown method.
Expected<GraphOptions> trialGraphOptions(const sim_world_t& world, const std::string& method);

/// The SIM_WORLD message of a log's events, or why there is none.
Expected<sim_world_t> simWorld(const std::vector<LogEvent>& events);

struct ReplayResult {
  /// The replayed modules' outputs as recorded in the log, and as replayed, per channel.
  std::map<std::string, std::vector<std::vector<uint8_t>>> recorded;
  std::map<std::string, std::vector<std::vector<uint8_t>>> replayed;
  /// Log events fed to the nodes, per channel.
  std::map<std::string, int64_t> inputs;
  /// What the reader of a diff should know: inputs the log lacks, messages the nodes refused.
  std::vector<std::string> notes;
};

/// Replays `events` (a whole log, in order) into the nodes built with `options`. Throws
/// std::runtime_error when a node cannot be built or an LCM cannot be opened.
ReplayResult replayEvents(const std::vector<LogEvent>& events, const GraphOptions& options);

}  // namespace thicket::replay
