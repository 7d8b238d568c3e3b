// Progress: the progress lines of a run on stderr (counts, trials per second, ETA, the last trial).
#pragma once

#include <chrono>
#include <cstddef>
#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "plans.h"
#include "row_store.h"

namespace thicket::bench {

// One stderr line at most every 2 s and one at the end:
// "[E2] 1234/3000 done (12 resumed), 2.1 trials/s, ETA 14m10s, last: paper d0.2 random s7 goal
// reached". The counts are those of the last trial's experiment in this shard; the rate is that
// of the last kRateWindow trials this invocation finished (E4's trials take several times as
// long as E2's), the ETA the trials left in the whole run at that rate.
class Progress {
 public:
  Progress(const std::vector<const TrialSpec*>& shard, const std::set<std::string>& done,
           size_t to_run);

  // Counts `spec` finished as `row`; prints a line when the last printed is 2 s old or more.
  void finished(const TrialSpec& spec, const Row& row);

  // The last line, unless the last trial's line was it.
  void end();

 private:
  void print(std::chrono::steady_clock::time_point now) const;

  struct Count {
    int total = 0, done = 0, resumed = 0;
  };
  static constexpr size_t kRateWindow = 50;
  std::mutex mutex_;
  std::deque<std::chrono::steady_clock::time_point> finish_times_;
  std::map<std::string, Count> counts_;
  std::string experiment_;
  std::string last_;
  size_t to_run_ = 0;
  size_t run_ = 0;
  bool unprinted_ = false;
  const std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point printed_ = started_;
};

}  // namespace thicket::bench
