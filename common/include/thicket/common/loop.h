// The event loop of one process: handles the messages of every node on an lcm::LCM, runs
// periodic timers, and stops cleanly on SIGINT/SIGTERM. It can be run to completion (a node's
// main), polled (a host that does other work), or drained (memq:// composites and replay, where
// everything pending is handled without waiting).
#pragma once

#include <cstdint>
#include <functional>
#include <map>

#include <lcm/lcm-cpp.hpp>

namespace thicket {

/// Microseconds of a monotonic clock. Timers only pace I/O (status at 1 Hz, setpoints); core
/// decisions never read it.
using MonotonicClock = std::function<int64_t()>;
int64_t steadyClockMicros();
/// The same clock in milliseconds: what nodes measure their stage durations with.
inline double steadyClockMillis() {
  return static_cast<double>(steadyClockMicros()) * 1e-3;
}

class Loop {
 public:
  /// `clock` is replaceable so tests can drive timers without sleeping.
  explicit Loop(lcm::LCM& lcm, MonotonicClock clock = steadyClockMicros);

  /// Handles pending messages, waiting up to `timeout_ms` for the first one, and runs the
  /// timers that are due. Returns the number of messages handled, or -1 when LCM failed.
  int poll(int timeout_ms);

  /// Handles everything already pending without waiting (and what handling it publishes, on
  /// memq://), up to `max_messages`. Returns the number handled.
  int drain(int max_messages = 1'000'000);

  /// Runs until stop() is called or the process receives SIGINT or SIGTERM (see
  /// installSignalHandlers). Returns the signal that stopped it, or 0.
  int run();

  /// Makes run() return after the current message or timer.
  void stop() { stop_requested_ = true; }
  bool stopRequested() const;

  using TimerId = int;
  /// Calls `callback` every `period_us` from now on, at a fixed rate; when the loop falls
  /// behind by whole periods, missed calls are skipped, not bunched.
  TimerId addTimer(int64_t period_us, std::function<void()> callback);
  void removeTimer(TimerId id);

  /// SIGINT and SIGTERM set a process-wide flag that makes every Loop stop. Idempotent.
  static void installSignalHandlers();
  /// The signal received, or 0.
  static int terminationSignal();
  /// Forgets a received signal (for tests that raise one on purpose).
  static void clearTerminationSignal();

 private:
  struct Timer {
    int64_t period_us;
    int64_t next_us;
    std::function<void()> callback;
  };
  void runDueTimers();
  int64_t microsToNextTimer() const;

  lcm::LCM& lcm_;
  MonotonicClock clock_;
  std::map<TimerId, Timer> timers_;
  TimerId next_timer_id_ = 1;
  bool stop_requested_ = false;
};

}  // namespace thicket
