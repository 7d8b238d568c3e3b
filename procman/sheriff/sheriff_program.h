// runSheriffProgram(): the sheriff's loop over LCM, stdin, the script and the orders.
#pragma once

#include "args.h"
#include "thicket/procman/sheet.h"

namespace thicket::sheriff {

// Runs the sheriff on `sheet` until it quits; the exit status.
int runSheriffProgram(const Args& args, procman::Sheet sheet);

}  // namespace thicket::sheriff
