// The progress lines of a run: the rate over the last trials and the ETA it gives.
#include "progress.h"

#include <cmath>
#include <cstdio>

#include "trials.h"

namespace thicket::bench {
namespace {

std::string formatDuration(double seconds) {
  const long s = std::lround(seconds);
  char text[32];
  if (s < 60) {
    std::snprintf(text, sizeof(text), "%lds", s);
  } else if (s < 3600) {
    std::snprintf(text, sizeof(text), "%ldm%02lds", s / 60, s % 60);
  } else {
    std::snprintf(text, sizeof(text), "%ldh%02ldm", s / 3600, s % 3600 / 60);
  }
  return text;
}

}  // namespace

Progress::Progress(const std::vector<const TrialSpec*>& shard, const std::set<std::string>& done,
                   size_t to_run)
    : to_run_(to_run) {
  for (const TrialSpec* spec : shard) {
    Count& count = counts_[spec->experiment];
    ++count.total;
    if (done.count(spec->key())) {
      ++count.done;
      ++count.resumed;
    }
  }
  if (!shard.empty()) experiment_ = shard.front()->experiment;
}

void Progress::finished(const TrialSpec& spec, const Row& row) {
  const std::lock_guard lock(mutex_);
  ++run_;
  const auto now = std::chrono::steady_clock::now();
  finish_times_.push_back(now);
  if (finish_times_.size() > kRateWindow) finish_times_.pop_front();
  ++counts_[spec.experiment].done;
  experiment_ = spec.experiment;
  last_ = spec.scenario + " d" + formatNumber("%g", spec.density) + " " + spec.method +
          (spec.goal_finding == "soft" ? "" : " " + spec.goal_finding) + " s" +
          std::to_string(spec.seed) + " " + row.cell("end_reason");
  unprinted_ = true;
  if (now - printed_ >= std::chrono::seconds(2)) {
    printed_ = now;
    unprinted_ = false;
    print(now);
  }
}

void Progress::end() {
  const std::lock_guard lock(mutex_);
  if (!counts_.empty() && (unprinted_ || run_ == 0)) print(std::chrono::steady_clock::now());
}

void Progress::print(std::chrono::steady_clock::time_point now) const {
  const Count& count = counts_.at(experiment_);
  // Trials per second: over the window once it is full, before that since the start.
  const bool full = finish_times_.size() == kRateWindow;
  const double elapsed =
      std::chrono::duration<double>(now - (full ? finish_times_.front() : started_)).count();
  const double trials = full ? static_cast<double>(kRateWindow - 1) : static_cast<double>(run_);
  const double rate = elapsed > 0 ? trials / elapsed : 0;
  const size_t left = to_run_ - run_;
  const std::string eta = left == 0  ? "0s"
                          : rate > 0 ? formatDuration(static_cast<double>(left) / rate)
                                     : "?";
  std::fprintf(stderr, "[%s] %d/%d done (%d resumed), %s trials/s, ETA %s%s\n", experiment_.c_str(),
               count.done, count.total, count.resumed, formatNumber("%.3g", rate).c_str(),
               eta.c_str(), last_.empty() ? "" : (", last: " + last_).c_str());
}

}  // namespace thicket::bench
