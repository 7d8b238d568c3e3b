// The SIGINT and SIGTERM handler of thicket-sheriff and the signal mask it waits with.
#include "signals.h"

namespace thicket::sheriff {

volatile std::sig_atomic_t g_signal_count = 0;
volatile std::sig_atomic_t g_last_signal = 0;

namespace {

void onSignal(int signal) {
  g_last_signal = signal;
  g_signal_count = g_signal_count + 1;
}

}  // namespace

sigset_t installSignals() {
  struct sigaction action {};
  action.sa_handler = onSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
  sigset_t blocked, previous;
  sigemptyset(&blocked);
  sigaddset(&blocked, SIGINT);
  sigaddset(&blocked, SIGTERM);
  sigprocmask(SIG_BLOCK, &blocked, &previous);
  sigdelset(&previous, SIGINT);
  sigdelset(&previous, SIGTERM);
  return previous;  // the mask to wait with
}

}  // namespace thicket::sheriff
