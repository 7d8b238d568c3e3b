#include "bridge.h"

#include <algorithm>

namespace thicket::bridge {

uint64_t messageKey(const std::string& channel, const void* data, size_t size) {
  uint64_t h = 14695981039346656037ull;
  const auto mix = [&h](unsigned char c) {
    h ^= c;
    h *= 1099511628211ull;
  };
  for (const char c : channel) mix(static_cast<unsigned char>(c));
  mix(0);
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) mix(bytes[i]);
  return h;
}

void Bridge::Echoes::published(uint64_t key) {
  keys_.push_back(key);
  while (keys_.size() > capacity_) keys_.pop_front();
}

bool Bridge::Echoes::consume(uint64_t key) {
  const auto it = std::find(keys_.begin(), keys_.end(), key);
  if (it == keys_.end()) return false;
  keys_.erase(it);
  return true;
}

Bridge::Bridge(lcm::LCM& vehicle, lcm::LCM& link, BridgeOptions options)
    : vehicle_(vehicle),
      link_(link),
      options_(std::move(options)),
      vehicle_echoes_(options_.echo_memory),
      link_echoes_(options_.echo_memory) {
  vehicle_subscription_ = vehicle_.subscribeFunction(
      ".*",
      +[](const lcm::ReceiveBuffer* rbuf, const std::string& channel, Bridge* self) {
        self->copy(rbuf, channel, /*toward_link=*/true);
      },
      this);
  link_subscription_ = link_.subscribeFunction(
      ".*",
      +[](const lcm::ReceiveBuffer* rbuf, const std::string& channel, Bridge* self) {
        self->copy(rbuf, channel, /*toward_link=*/false);
      },
      this);
}

Bridge::~Bridge() {
  if (vehicle_subscription_ != nullptr) vehicle_.unsubscribe(vehicle_subscription_);
  if (link_subscription_ != nullptr) link_.unsubscribe(link_subscription_);
}

void Bridge::copy(const lcm::ReceiveBuffer* rbuf, const std::string& channel, bool toward_link) {
  DirectionCounters& counters = toward_link ? up_ : down_;
  Echoes& here = toward_link ? vehicle_echoes_ : link_echoes_;
  Echoes& there = toward_link ? link_echoes_ : vehicle_echoes_;
  const uint64_t key = messageKey(channel, rbuf->data, rbuf->data_size);
  if (here.consume(key)) {
    ++counters.echoes;
    return;
  }
  const bool wanted = toward_link ? std::regex_match(channel, options_.up) &&
                                        !std::regex_match(channel, options_.up_exclude)
                                  : std::regex_match(channel, options_.down);
  if (!wanted) {
    ++counters.filtered;
    return;
  }
  lcm::LCM& target = toward_link ? link_ : vehicle_;
  there.published(key);  // before publishing: the echo can come back within the publish
  const int status = target.publish(channel, rbuf->data, rbuf->data_size);
  if (status != 0) {
    there.consume(key);
    ++counters.failed;
    if (toward_link) link_up_ = false;
    return;
  }
  ++counters.copied;
  counters.bytes += rbuf->data_size;
  if (toward_link) link_up_ = true;
}

}  // namespace thicket::bridge
