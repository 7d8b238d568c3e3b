// OutputPrinter: the commands' output (PM_OUTPUT), printed line by line with its command.
#pragma once

#include <cstddef>
#include <map>
#include <string>

#include <procman_lcm/output_t.hpp>

#include "thicket/procman/sheriff.h"

namespace thicket::sheriff {

class OutputPrinter {
 public:
  explicit OutputPrinter(const procman::Sheriff& sheriff) : sheriff_(sheriff) {}

  void handle(const procman_lcm::output_t& msg);

  /// Prints lines that have waited for their end.
  void flushAll();

 private:
  std::string labelFor(const std::string& deputy, const std::string& id) const;
  void flush(const std::string& label);
  static void emit(const std::string& label, std::string line);

  static constexpr size_t kMaxPartialLines = 256;
  const procman::Sheriff& sheriff_;
  std::map<std::string, std::string> partial_;
};

}  // namespace thicket::sheriff
