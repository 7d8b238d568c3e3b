// The LCM side of a module. A module is a core library (no LCM inside) plus a thin node that
// adapts messages to the core. Nodes subscribe and publish through this base class, so several
// of them can share one lcm::LCM — one process per module on udpm://, or many nodes in one
// process on memq:// (a "composite", as the benchmark and replay tests run the graph).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <lcm/lcm-cpp.hpp>

namespace thicket {

/// How a message arrived.
struct MessageInfo {
  std::string_view channel;
  int64_t recv_utime = 0;  // when it was received (wall clock); decisions use the message utime
  size_t size = 0;         // encoded bytes
};

/// LCM 1.3.1 queues 30 messages per subscription and drops the newest when full (docs/design.md
/// §5). Nodes that receive bursts ask for more.
inline constexpr int kDefaultQueueCapacity = 30;

/// Checks that `data` holds exactly one encoded `Msg`; on success fills `msg` and returns an
/// empty string, else returns why not (truncated, another type's fingerprint, trailing bytes).
template <class Msg>
std::string decodeMessage(const void* data, size_t size, Msg& msg);

/// Base class of every thicket node. Not copyable; the lcm::LCM must outlive it.
class Node {
 public:
  Node(std::string name, lcm::LCM& lcm);
  virtual ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  const std::string& name() const { return name_; }
  lcm::LCM& lcm() { return lcm_; }

  /// Calls `handler` with every message on `channel` (an exact name, not a pattern) that
  /// decodes as `Msg`. Messages that do not decode are counted and reported through
  /// onBadMessage(), never passed on. An exception thrown by the handler is reported the same
  /// way and does not stop the node.
  template <class Msg>
  void subscribe(const std::string& channel,
                 std::function<void(const Msg&, const MessageInfo&)> handler,
                 int queue_capacity = kDefaultQueueCapacity);

  /// Undecoded bytes; for channels whose type is known only at run time (recorders, bridges).
  /// `channel_regex` is an LCM pattern (implicitly anchored).
  void subscribeRaw(const std::string& channel_regex,
                    std::function<void(const void* data, size_t size, const MessageInfo&)> handler,
                    int queue_capacity = kDefaultQueueCapacity);

  /// Encodes and publishes. Returns false, counts it and sets lastError() when it fails.
  template <class Msg>
  bool publish(const std::string& channel, const Msg& msg);
  bool publishRaw(const std::string& channel, const void* data, size_t size);

  /// Messages refused on each channel so far (decode failures and handler exceptions).
  const std::map<std::string, int64_t>& badMessageCounts() const { return bad_counts_; }
  int64_t badMessageCount() const;
  int64_t publishFailures() const { return publish_failures_; }
  /// The most recent problem in words, or empty.
  const std::string& lastError() const { return last_error_; }

 protected:
  /// Called for every refused message. The default prints to stderr: the first occurrence on a
  /// channel and then every 10th, 100th, ... so a flood of bad input cannot flood the log.
  virtual void onBadMessage(const std::string& channel, const std::string& reason);

  /// Refuses a message that decoded but is unusable (NaN values, time going backwards...):
  /// counts it, sets lastError() and calls onBadMessage().
  void reportBadMessage(const std::string& channel, const std::string& reason);

 private:
  struct Subscription;
  void addSubscription(const std::string& channel, int queue_capacity,
                       std::function<void(const void*, size_t, const MessageInfo&)> dispatch);
  bool publishFailed(const std::string& channel, const std::string& reason);

  std::string name_;
  lcm::LCM& lcm_;
  std::vector<std::unique_ptr<Subscription>> subscriptions_;
  std::map<std::string, int64_t> bad_counts_;
  int64_t publish_failures_ = 0;
  std::string last_error_;
  // publish()'s encoding buffer, kept between calls: a map update or an image is hundreds of
  // kilobytes, which a fresh buffer per message allocates and zeroes first.
  std::vector<uint8_t> publish_buffer_;
};

// ---- implementation of the templates ----

/// `channel` as an LCM pattern that matches exactly that name.
std::string exactChannelPattern(const std::string& channel);

/// Whether `data` holds exactly one encoded message of the type whose fingerprint is
/// `expected_hash`, checked against the built-in schema without allocating (lcm_schema.h):
/// empty when it does, else why not. decodeMessage runs it before the generated decoder.
std::string checkEncodedMessage(const void* data, size_t size, int64_t expected_hash,
                                const char* type_name);

template <class Msg>
std::string decodeMessage(const void* data, size_t size, Msg& msg) {
  std::string error = checkEncodedMessage(data, size, Msg::getHash(), Msg::getTypeName());
  if (!error.empty()) return error;
  const int decoded = msg.decode(data, 0, static_cast<int>(size));
  if (decoded >= 0 && static_cast<size_t>(decoded) == size) return {};
  return std::string("malformed ") + Msg::getTypeName() + ": the generated decoder refused it";
}

template <class Msg>
void Node::subscribe(const std::string& channel,
                     std::function<void(const Msg&, const MessageInfo&)> handler,
                     int queue_capacity) {
  addSubscription(
      exactChannelPattern(channel), queue_capacity,
      [this, handler = std::move(handler)](const void* data, size_t size, const MessageInfo& info) {
        Msg msg;
        const std::string error = decodeMessage(data, size, msg);
        if (!error.empty()) {
          reportBadMessage(std::string(info.channel), error);
          return;
        }
        handler(msg, info);
      });
}

template <class Msg>
bool Node::publish(const std::string& channel, const Msg& msg) {
  // LCM's generated sizes are ints: a message too large for one overflows to a negative size.
  const int size = msg.getEncodedSize();
  if (size < 0) {
    return publishFailed(channel, std::string("cannot encode ") + Msg::getTypeName() +
                                      ": its encoded size overflows");
  }
  // Grown as needed; a buffer over 4 MiB is given back once a message needs under a quarter of it.
  std::vector<uint8_t>& buffer = publish_buffer_;
  if (buffer.size() > (size_t{4} << 20) && static_cast<size_t>(size) * 4 < buffer.size()) {
    std::vector<uint8_t>().swap(buffer);
  }
  if (buffer.size() < static_cast<size_t>(size)) buffer.resize(static_cast<size_t>(size));
  if (msg.encode(buffer.data(), 0, size) != size) {
    return publishFailed(channel, std::string("cannot encode ") + Msg::getTypeName());
  }
  return publishRaw(channel, buffer.data(), static_cast<size_t>(size));
}

}  // namespace thicket
