#include "thicket/common/loop.h"

#include <fcntl.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <vector>

namespace thicket {
namespace {

// Self-pipe: the handler writes one byte so that a loop blocked in poll() wakes at once. The
// byte is left in the pipe, so every loop in the process sees it.
volatile std::sig_atomic_t g_signal = 0;
int g_signal_pipe[2] = {-1, -1};

void onTerminationSignal(int signal) {
  g_signal = signal;
  const char byte = 1;
  const int saved_errno = errno;
  [[maybe_unused]] ssize_t written = ::write(g_signal_pipe[1], &byte, 1);
  errno = saved_errno;
}

}  // namespace

int64_t steadyClockMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void Loop::installSignalHandlers() {
  if (g_signal_pipe[0] >= 0) return;
  if (::pipe2(g_signal_pipe, O_NONBLOCK | O_CLOEXEC) != 0) {
    throw std::runtime_error(std::string("cannot create the signal pipe: ") + std::strerror(errno));
  }
  struct sigaction action {};
  action.sa_handler = onTerminationSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

int Loop::terminationSignal() {
  return g_signal;
}

void Loop::clearTerminationSignal() {
  g_signal = 0;
  char buffer[64];
  while (g_signal_pipe[0] >= 0 && ::read(g_signal_pipe[0], buffer, sizeof(buffer)) > 0) {
  }
}

Loop::Loop(lcm::LCM& lcm, MonotonicClock clock) : lcm_(lcm), clock_(std::move(clock)) {
  if (!lcm_.good()) {
    throw std::runtime_error(
        "LCM is not usable (bad URL, or no multicast route: see docs/design.md §5 for loopback "
        "setup)");
  }
}

bool Loop::stopRequested() const {
  return stop_requested_ || g_signal != 0;
}

Loop::TimerId Loop::addTimer(int64_t period_us, std::function<void()> callback) {
  if (period_us <= 0) throw std::invalid_argument("timer period must be positive");
  const TimerId id = next_timer_id_++;
  timers_[id] = Timer{period_us, clock_() + period_us, std::move(callback)};
  return id;
}

void Loop::removeTimer(TimerId id) {
  timers_.erase(id);
}

void Loop::runDueTimers() {
  // Collect first: a callback may add or remove timers.
  std::vector<TimerId> due;
  const int64_t now = clock_();
  for (const auto& [id, timer] : timers_) {
    if (timer.next_us <= now) due.push_back(id);
  }
  for (TimerId id : due) {
    auto it = timers_.find(id);
    if (it == timers_.end()) continue;
    Timer& timer = it->second;
    const int64_t periods_behind = (now - timer.next_us) / timer.period_us;
    timer.next_us += (periods_behind + 1) * timer.period_us;
    auto callback = timer.callback;  // the timer may be removed while it runs
    callback();
    if (stopRequested()) return;
  }
}

int64_t Loop::microsToNextTimer() const {
  int64_t next = INT64_MAX;
  for (const auto& [id, timer] : timers_) next = std::min(next, timer.next_us);
  return next == INT64_MAX ? -1 : std::max<int64_t>(0, next - clock_());
}

int Loop::poll(int timeout_ms) {
  runDueTimers();
  if (stopRequested()) return 0;

  int wait_ms = timeout_ms;
  const int64_t timer_us = microsToNextTimer();
  if (timer_us >= 0) {
    const int timer_ms = static_cast<int>(std::min<int64_t>((timer_us + 999) / 1000, INT32_MAX));
    wait_ms = wait_ms < 0 ? timer_ms : std::min(wait_ms, timer_ms);
  }
  pollfd fds[2] = {{lcm_.getFileno(), POLLIN, 0}, {g_signal_pipe[0], POLLIN, 0}};
  const int ready = ::poll(fds, 2, wait_ms);
  if (ready < 0 && errno != EINTR) return -1;

  int handled = 0;
  if (ready > 0 && (fds[0].revents & POLLIN) != 0) {
    // Take what is complete now; a partial fragmented message is not waited for. A bounded
    // batch, so that a flood of messages cannot starve the timers.
    constexpr int kMaxBatch = 1000;
    while (handled < kMaxBatch && !stopRequested()) {
      const int status = lcm_.handleTimeout(0);
      if (status < 0) return -1;
      if (status == 0) break;
      ++handled;
    }
  }
  runDueTimers();
  return handled;
}

int Loop::drain(int max_messages) {
  int handled = 0;
  while (handled < max_messages && lcm_.handleTimeout(0) > 0) ++handled;
  return handled;
}

int Loop::run() {
  while (!stopRequested()) {
    if (poll(-1) < 0) {
      std::fprintf(stderr, "LCM failed while handling messages; stopping\n");
      break;
    }
  }
  return terminationSignal();
}

}  // namespace thicket
