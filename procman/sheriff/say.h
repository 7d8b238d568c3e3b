// say(): one message to the operator on stdout, ended by a newline.
#pragma once

#include <cstdio>
#include <string>

namespace thicket::sheriff {

inline void say(const std::string& text) {
  std::fputs(text.c_str(), stdout);
  if (text.empty() || text.back() != '\n') std::fputc('\n', stdout);
}

}  // namespace thicket::sheriff
