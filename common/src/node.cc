#include "thicket/common/node.h"

#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <exception>

#include "thicket/common/lcm_schema.h"

namespace thicket {

// Owns one LCM subscription; LCM calls onMessage with the raw bytes.
struct Node::Subscription {
  std::function<void(const void*, size_t, const MessageInfo&)> dispatch;
  lcm::Subscription* handle = nullptr;

  void onMessage(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    dispatch(rbuf->data, rbuf->data_size, MessageInfo{channel, rbuf->recv_utime, rbuf->data_size});
  }
};

std::string exactChannelPattern(const std::string& channel) {
  std::string pattern;
  for (char c : channel) {
    if (c != '\0' && std::strchr("\\^$.|?*+()[]{}", c) != nullptr) pattern += '\\';
    pattern += c;
  }
  return pattern;
}

std::string checkEncodedMessage(const void* data, size_t size, int64_t expected_hash,
                                const char* type_name) {
  if (size > static_cast<size_t>(INT32_MAX)) {
    return std::string(type_name) + " of " + std::to_string(size) +
           " bytes: more than LCM can decode";
  }
  const LcmStruct* type = builtinLcmTypes().findByFingerprint(static_cast<uint64_t>(expected_hash));
  if (type == nullptr) return std::string(type_name) + " is not one of thicket's LCM types";
  return LcmTypeSet::check(*type, data, size);  // too short, another type's fingerprint, ...
}

Node::Node(std::string name, lcm::LCM& lcm) : name_(std::move(name)), lcm_(lcm) {}

Node::~Node() {
  for (auto& subscription : subscriptions_) lcm_.unsubscribe(subscription->handle);
}

void Node::subscribeRaw(const std::string& channel_regex,
                        std::function<void(const void*, size_t, const MessageInfo&)> handler,
                        int queue_capacity) {
  addSubscription(channel_regex, queue_capacity, std::move(handler));
}

void Node::addSubscription(const std::string& channel, int queue_capacity,
                           std::function<void(const void*, size_t, const MessageInfo&)> dispatch) {
  auto subscription = std::make_unique<Subscription>();
  // Exceptions must not unwind through LCM's C dispatch loop: report and go on.
  subscription->dispatch = [this, dispatch = std::move(dispatch)](const void* data, size_t size,
                                                                  const MessageInfo& info) {
    try {
      dispatch(data, size, info);
    } catch (const std::exception& e) {
      reportBadMessage(std::string(info.channel), std::string("handler failed: ") + e.what());
    }
  };
  subscription->handle = lcm_.subscribe(channel, &Subscription::onMessage, subscription.get());
  if (subscription->handle == nullptr) {
    throw std::runtime_error(name_ + ": cannot subscribe to '" + channel + "'");
  }
  subscription->handle->setQueueCapacity(queue_capacity);
  subscriptions_.push_back(std::move(subscription));
}

bool Node::publishRaw(const std::string& channel, const void* data, size_t size) {
  if (lcm_.publish(channel, data, static_cast<unsigned int>(size)) != 0) {
    return publishFailed(channel, "LCM refused " + std::to_string(size) + " bytes");
  }
  return true;
}

int64_t Node::badMessageCount() const {
  int64_t total = 0;
  for (const auto& [channel, count] : bad_counts_) total += count;
  return total;
}

void Node::reportBadMessage(const std::string& channel, const std::string& reason) {
  ++bad_counts_[channel];
  last_error_ = channel + ": " + reason;
  onBadMessage(channel, reason);
}

bool Node::publishFailed(const std::string& channel, const std::string& reason) {
  ++publish_failures_;
  last_error_ = "publish " + channel + ": " + reason;
  std::fprintf(stderr, "[%s] cannot publish on %s: %s\n", name_.c_str(), channel.c_str(),
               reason.c_str());
  return false;
}

void Node::onBadMessage(const std::string& channel, const std::string& reason) {
  const int64_t count = bad_counts_[channel];
  int64_t power = 1;
  while (power * 10 <= count) power *= 10;
  if (count == power) {
    std::fprintf(stderr, "[%s] refused message %" PRId64 " on %s: %s\n", name_.c_str(), count,
                 channel.c_str(), reason.c_str());
  }
}

}  // namespace thicket
