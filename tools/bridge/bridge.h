// thicket-lcm-bridge's core: copies LCM traffic between the vehicle's own bus and the bus it shares
// with the ground over the radio link, so that the on-board graph talks on a bus that needs no
// link (udpm with ttl=0 on the vehicle's loopback) and a radio dropout costs only what crosses it.
//
// Channels matching `up` (and not `up_exclude`) are copied from the vehicle bus to the link bus;
// channels matching `down`, from the link bus to the vehicle bus. A copy the bridge publishes comes
// back to it on the bus it went to (multicast loops back to the sending host): each side
// remembers what the bridge published there (channel and a hash of the bytes, the last
// `echo_memory` of them) and does not copy such an echo back, so overlapping patterns cannot
// loop. A publish that fails (the link is down: ENETUNREACH) is counted and the message dropped;
// the next one is tried again.
#pragma once

#include <cstdint>
#include <deque>
#include <regex>
#include <string>
#include <utility>

#include <lcm/lcm-cpp.hpp>

namespace thicket::bridge {

struct BridgeOptions {
  std::regex up{".*"};
  std::regex up_exclude{"$^"};  // matches no channel
  std::regex down{"$^"};
  size_t echo_memory = 4096;
};

// What crossed, per direction.
struct DirectionCounters {
  int64_t copied = 0;    ///< published on the other bus
  int64_t failed = 0;    ///< the publish failed (dropped)
  int64_t filtered = 0;  ///< its channel is not copied this way
  int64_t echoes = 0;    ///< the bridge's own copies coming back, not copied again
  int64_t bytes = 0;     ///< payload bytes copied
};

class Bridge {
 public:
  /// Subscribes to every channel of both buses; both must outlive the bridge.
  Bridge(lcm::LCM& vehicle, lcm::LCM& link, BridgeOptions options);
  ~Bridge();
  Bridge(const Bridge&) = delete;
  Bridge& operator=(const Bridge&) = delete;

  const DirectionCounters& up() const { return up_; }
  const DirectionCounters& down() const { return down_; }
  /// Whether the last copy toward the link was published (false after a failed one).
  bool linkUp() const { return link_up_; }

 private:
  // One side's record of what the bridge published on it.
  class Echoes {
   public:
    explicit Echoes(size_t capacity) : capacity_(capacity) {}
    void published(uint64_t key);
    /// True (and forgotten) when `key` is one the bridge published here.
    bool consume(uint64_t key);

   private:
    size_t capacity_;
    std::deque<uint64_t> keys_;
  };

  void copy(const lcm::ReceiveBuffer* rbuf, const std::string& channel, bool toward_link);

  lcm::LCM& vehicle_;
  lcm::LCM& link_;
  BridgeOptions options_;
  lcm::Subscription* vehicle_subscription_ = nullptr;
  lcm::Subscription* link_subscription_ = nullptr;
  Echoes vehicle_echoes_, link_echoes_;
  DirectionCounters up_, down_;
  bool link_up_ = true;
};

/// FNV-1a over the channel name, a separator and the bytes.
uint64_t messageKey(const std::string& channel, const void* data, size_t size);

}  // namespace thicket::bridge
