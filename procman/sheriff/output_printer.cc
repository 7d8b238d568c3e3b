// The commands' output, split into lines, labelled and printed with its controls escaped.
#include "output_printer.h"

#include <algorithm>
#include <cstdint>

#include "say.h"
#include "thicket/procman/printable.h"

namespace thicket::sheriff {

using namespace thicket::procman;

void OutputPrinter::handle(const procman_lcm::output_t& msg) {
  const size_t n = std::min({static_cast<size_t>(std::max<int16_t>(0, msg.num_commands)),
                             msg.command_ids.size(), msg.text.size()});
  for (size_t i = 0; i < n; ++i) {
    const std::string label = labelFor(msg.deputy_id, msg.command_ids[i]);
    std::string& partial = partial_[label];
    partial += msg.text[i];
    size_t start = 0;
    for (size_t newline; (newline = partial.find('\n', start)) != std::string::npos;) {
      emit(label, partial.substr(start, newline - start));
      start = newline + 1;
    }
    partial.erase(0, start);
    if (partial.size() > 4096) flush(label);
  }
  // Unfinished lines of commands nobody runs (junk on PM_OUTPUT) must not pile up.
  if (partial_.size() > kMaxPartialLines) flushAll();
}

void OutputPrinter::flushAll() {
  for (auto& [label, partial] : partial_) flush(label);
  partial_.clear();
}

std::string OutputPrinter::labelFor(const std::string& deputy, const std::string& id) const {
  if (id.empty()) return "[deputy " + printableShort(deputy) + "]";
  if (sheriff_.command(deputy, id)) return "[" + id + "]";
  return "[" + printableShort(deputy) + "/" + printableShort(id) + "]";
}

void OutputPrinter::flush(const std::string& label) {
  std::string& partial = partial_[label];
  if (!partial.empty()) emit(label, partial);
  partial.clear();
}

// Controls are escaped: a command (or a stranger on the bus) printing ESC[2J must not clear the
// operator's screen.
void OutputPrinter::emit(const std::string& label, std::string line) {
  while (!line.empty() && (line.back() == '\r' || line.back() == '\n')) line.pop_back();
  say(printable(label + " " + line));
}

}  // namespace thicket::sheriff
