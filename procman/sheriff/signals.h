// SIGINT and SIGTERM for thicket-sheriff: counted by a handler, blocked except inside ppoll().
#pragma once

#include <signal.h>

#include <csignal>

namespace thicket::sheriff {

// How many SIGINT or SIGTERM have arrived, and the last of them.
extern volatile std::sig_atomic_t g_signal_count;
extern volatile std::sig_atomic_t g_last_signal;

// Installs the handler, ignores SIGPIPE and blocks SIGINT and SIGTERM, so that none is lost
// between checks; returns the signal mask to wait with (ppoll), which lets them through.
sigset_t installSignals();

}  // namespace thicket::sheriff
