#include "thicket/common/time.h"

#include <stdexcept>
#include <utility>

namespace thicket {

Timeline::Timeline(std::string what, int reset_after)
    : what_(std::move(what)), reset_after_(reset_after) {
  if (reset_after < 0) throw std::invalid_argument("Timeline: reset_after must be >= 0");
}

std::string notATime(const std::string& what, int64_t utime) {
  return what + " utime " + std::to_string(utime) + " us is outside [0, 2^62] us: not a time";
}

Timeline::Result Timeline::offer(int64_t utime) {
  if (!isTime(utime)) return {Verdict::kRefused, notATime(what_, utime)};
  if (last_ && utime <= *last_) {
    const bool continues_run = utime < *last_ && run_ > 0 && utime > run_last_;
    run_ = utime < *last_ ? (continues_run ? run_ + 1 : 1) : 0;
    run_last_ = utime;
    if (reset_after_ > 0 && run_ >= reset_after_) {
      Result result{Verdict::kReanchored, "clock reset: " + std::to_string(run_) + " consecutive " +
                                              what_ + "s before the previous timeline's " +
                                              formatUtime(*last_) + "; re-anchored at " +
                                              formatUtime(utime)};
      last_ = utime;
      run_ = 0;
      ++reanchors_;
      return result;
    }
    return {Verdict::kRefused, (utime == *last_ ? "utime " + formatUtime(utime) + " repeats"
                                                : "utime " + formatUtime(utime) + " is before") +
                                   " the previous " + what_ + "'s " + formatUtime(*last_)};
  }
  run_ = 0;
  last_ = utime;
  return {};
}

}  // namespace thicket
