// Text from the bus or from files, made safe to print on an operator's terminal: command output
// and sheet errors can hold escape sequences (ESC[2J clears the screen) or megabytes.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace thicket::procman {

/// `text` with control characters written as \xNN (tab kept): C0 controls, DEL and the UTF-8
/// encodings of the C1 controls (U+0080..U+009F, which some terminals obey). Other UTF-8 is
/// kept as it is.
std::string printable(std::string_view text);

/// printable(text) cut after `max_bytes` (at a character boundary) with "... (N bytes)" added,
/// for echoing untrusted names in messages.
std::string printableShort(std::string_view text, std::size_t max_bytes = 60);

}  // namespace thicket::procman
