#include "replay.h"

#include <algorithm>
#include <deque>
#include <memory>
#include <set>
#include <stdexcept>
#include <utility>

#include <lcm/lcm-cpp.hpp>

#include "thicket/common/loop.h"
#include "thicket/common/node.h"

namespace thicket::replay {

const std::vector<ReplayedModule>& replayedModules() {
  // From the nodes' constructors (subscriptions) and their publish calls.
  static const std::vector<ReplayedModule> modules = {
      {"vio_bridge", {"VIO_ODOMETRY"}, {"STATE_ESTIMATE", "MODULE_TIMING"}},
      {"mapper",
       {"CAMERA_DEPTH", "STATE_ESTIMATE", "MAP_REQUEST"},
       {"MAP_TSDF", "MAP_ESDF", "MAPPER_STATUS", "MODULE_TIMING"}},
      {"explorer",
       {"MAP_TSDF", "MAP_ESDF", "PLANNER_STATUS"},
       {"EXPLORER_GOAL", "MAP_REQUEST", "MODULE_TIMING"}},
      {"local_planner",
       {"MAP_ESDF", "STATE_ESTIMATE", "MISSION_GOAL", "EXPLORER_GOAL"},
       {"PLANNER_TRAJECTORY", "PLANNER_STATUS", "CONTROL_SETPOINT", "MAP_REQUEST",
        "MODULE_TIMING"}},
  };
  return modules;
}

Expected<GraphOptions> trialGraphOptions(const sim_world_t& world, const std::string& method) {
  const Eigen::Vector3d bounds_min(world.bounds_min[0], world.bounds_min[1], world.bounds_min[2]);
  const Eigen::Vector3d bounds_max(world.bounds_max[0], world.bounds_max[1], world.bounds_max[2]);
  try {
    return bench::trialGraphOptions(method, "soft", static_cast<uint64_t>(world.seed), bounds_min,
                                    bounds_max, world.robot_radius);
  } catch (const std::exception& e) {
    return unexpected(e.what());
  }
}

Expected<sim_world_t> simWorld(const std::vector<LogEvent>& events) {
  for (const LogEvent& event : events) {
    if (event.channel != "SIM_WORLD") continue;
    sim_world_t world;
    const std::string error = event.decode(world);
    if (!error.empty()) return unexpected("its SIM_WORLD message does not decode: " + error);
    return world;
  }
  return unexpected("it has no SIM_WORLD message, which gives the trial's seed and flight volume");
}

namespace {

struct Published {
  std::string channel;
  std::vector<uint8_t> data;
};

// One replayed node on a memq:// LCM of its own, with a recorder of what it publishes.
class Island {
 public:
  explicit Island(const ReplayedModule& module)
      : module_(module), lcm_("memq://"), loop_(lcm_), capture_("replay_capture", lcm_) {
    if (!lcm_.good()) throw std::runtime_error("cannot open an LCM on memq://");
  }

  template <class NodeType, class... Args>
  void host(Args&&... args) {
    node_ = std::make_unique<NodeType>(lcm_, std::forward<Args>(args)...);
    // A full map snapshot answers one request with many parts in a single drain.
    capture_.subscribeRaw(
        ".*",
        [this](const void* data, size_t size, const MessageInfo& info) {
          if (delivering_) return;
          const auto* bytes = static_cast<const uint8_t*>(data);
          published_.push_back({std::string(info.channel), {bytes, bytes + size}});
        },
        1'000'000);
  }

  const ReplayedModule& module() const { return module_; }
  const Node& node() const { return *node_; }

  // Hands one message to the node and returns what it published in answer, in order. The
  // queue is empty before, so the first message handled is this one.
  std::vector<Published> deliver(const std::string& channel, const std::vector<uint8_t>& data) {
    delivering_ = true;
    if (lcm_.publish(channel, data.data(), static_cast<unsigned>(data.size())) != 0) {
      throw std::runtime_error("replay: cannot publish on " + channel);
    }
    loop_.drain(1);
    delivering_ = false;
    loop_.drain();
    return std::exchange(published_, {});
  }

 private:
  const ReplayedModule& module_;
  lcm::LCM lcm_;
  Loop loop_;
  Node capture_;
  std::unique_ptr<Node> node_;
  bool delivering_ = false;
  std::vector<Published> published_;
};

const ReplayedModule& module(const char* name) {
  for (const ReplayedModule& m : replayedModules()) {
    if (std::string(name) == m.name) return m;
  }
  throw std::logic_error(std::string("no replayed module ") + name);
}

// A replayed message and the node that published it.
struct Produced {
  std::vector<uint8_t> data;
  size_t island;
};

class Router {
 public:
  Router(const std::vector<LogEvent>& events, const GraphOptions& options) {
    // The recorded graph's subscription order (tools/bench/trials.cc).
    islands_.push_back(std::make_unique<Island>(module("vio_bridge")));
    islands_.back()->host<vio_bridge::VioBridgeNode>(options.bridge, steadyClockMillis);
    islands_.push_back(std::make_unique<Island>(module("mapper")));
    islands_.back()->host<mapper::MapperNode>(options.mapper, options.mapper.map_id,
                                              steadyClockMillis);
    if (options.explorer) {
      islands_.push_back(std::make_unique<Island>(module("explorer")));
      islands_.back()->host<explorer::ExplorerNode>(*options.explorer, steadyClockMillis);
    }
    islands_.push_back(std::make_unique<Island>(module("local_planner")));
    islands_.back()->host<local_planner::LocalPlannerNode>(options.planner, steadyClockMillis);

    for (const auto& island : islands_) {
      for (const std::string& channel : island->module().outputs) outputs_.insert(channel);
    }
    for (const LogEvent& event : events) {
      if (outputs_.count(event.channel)) ++recorded_total_[event.channel];
    }
  }

  ReplayResult run(const std::vector<LogEvent>& events) {
    for (const LogEvent& event : events) {
      if (outputs_.count(event.channel)) {
        // Where the log holds the k-th recorded message, the others get the k-th replayed one.
        result_.recorded[event.channel].push_back(event.data);
        ++recorded_seen_[event.channel];
        due_.push_back(event.channel);
      } else {
        ++result_.inputs[event.channel];
        deliver(event.channel, event.data, islands_.size());
      }
      while (!due_.empty()) {
        const std::string channel = due_.front();
        due_.pop_front();
        release(channel);
      }
    }
    for (auto& [channel, produced] : produced_) {
      auto& replayed = result_.replayed[channel];
      for (Produced& message : produced) replayed.push_back(std::move(message.data));
    }
    addNotes(events);
    return std::move(result_);
  }

 private:
  // Delivers the channel's replayed messages whose time has come, in their order: the k-th once
  // the log has passed the k-th recorded one; one without a recorded counterpart (the replay
  // published more than was recorded) right after the one before it.
  void release(const std::string& channel) {
    auto& produced = produced_[channel];
    size_t& next = delivered_[channel];
    while (next < produced.size() &&
           (next < recorded_seen_[channel] || next >= recorded_total_[channel])) {
      // A copy: delivering may add to `produced`.
      const Produced message = produced[next++];
      deliver(channel, message.data, message.island);
    }
  }

  // To every node but the one that published it (`from`).
  void deliver(const std::string& channel, const std::vector<uint8_t>& data, size_t from) {
    for (size_t i = 0; i < islands_.size(); ++i) {
      if (i == from) continue;
      for (Published& out : islands_[i]->deliver(channel, data)) {
        const auto& declared = islands_[i]->module().outputs;
        if (std::find(declared.begin(), declared.end(), out.channel) == declared.end()) {
          undeclared_.insert(std::string(islands_[i]->module().name) + " published on " +
                             out.channel + ", which is not among its outputs in replay.cc");
        }
        produced_[out.channel].push_back({std::move(out.data), i});
        due_.push_back(out.channel);
      }
    }
  }

  void addNotes(const std::vector<LogEvent>& events) {
    std::set<std::string> in_log;
    for (const LogEvent& event : events) in_log.insert(event.channel);
    // The inputs from outside the replayed modules (the simulator, the operator): every recorded
    // flight has them. (EXPLORER_GOAL without an explorer, MAP_REQUEST: only when needed.)
    std::set<std::string> internal;
    for (const ReplayedModule& module : replayedModules()) {
      internal.insert(module.outputs.begin(), module.outputs.end());
    }
    for (const auto& island : islands_) {
      for (const std::string& input : island->module().inputs) {
        if (!internal.count(input) && !in_log.count(input)) {
          result_.notes.push_back("the log has no " + input + " (an input of " +
                                  island->module().name + ")");
        }
      }
    }
    for (const auto& [output, messages] : result_.replayed) {
      if (!in_log.count(output) && !messages.empty()) {
        result_.notes.push_back("the log has no " + output + ", which the replay published");
      }
    }
    for (const auto& island : islands_) {
      const Node& node = island->node();
      if (node.badMessageCount() > 0) {
        result_.notes.push_back(std::string(island->module().name) + " refused " +
                                std::to_string(node.badMessageCount()) +
                                " messages (the last: " + node.lastError() + ")");
      }
    }
    result_.notes.insert(result_.notes.end(), undeclared_.begin(), undeclared_.end());
  }

  std::vector<std::unique_ptr<Island>> islands_;
  std::set<std::string> outputs_;
  std::map<std::string, size_t> recorded_total_;
  std::map<std::string, size_t> recorded_seen_;
  std::map<std::string, std::vector<Produced>> produced_;
  std::map<std::string, size_t> delivered_;  // per channel: produced_[channel][0, n) delivered
  std::deque<std::string> due_;              // channels that may have messages to deliver
  std::set<std::string> undeclared_;
  ReplayResult result_;
};

}  // namespace

ReplayResult replayEvents(const std::vector<LogEvent>& events, const GraphOptions& options) {
  Router router(events, options);
  return router.run(events);
}

}  // namespace thicket::replay
