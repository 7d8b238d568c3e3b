// The summary's text: numbers, durations and success cells formatted, and markdown tables.
#pragma once

#include <cstdio>
#include <string>
#include <vector>

#include "report_statistics.h"

namespace thicket::bench::report_internal {

// snprintf into a string of at most 255 characters.
template <class... Args>
std::string print(const char* spec, Args... args) {
  char text[256];
  std::snprintf(text, sizeof(text), spec, args...);
  return text;
}

std::string densityText(double density);

// Whole percent, halves rounded up (5/8 is 63 %, where printf would give 62).
std::string percent(double fraction);

// "46/50 = 92 % [81, 97]": successes, rate and Wilson 95 % interval in percent.
std::string successCell(const Tally& tally);

// Three significant digits for durations from microseconds to seconds.
std::string milliseconds(double ms);

std::string meters(double m);

std::string duration(double s);

std::string escapeCell(const std::string& text);

std::string markdownTable(const std::vector<std::string>& header,
                          const std::vector<std::vector<std::string>>& rows);

std::string medianOrDash(const std::vector<double>& values);

std::string successMatrix(const SuccessTable& table, const std::vector<std::string>& order,
                          const std::string& first_column);

}  // namespace thicket::bench::report_internal
