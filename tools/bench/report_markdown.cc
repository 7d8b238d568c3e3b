// Formatting the summary's numbers and cells, and writing its markdown tables.
#include "report_markdown.h"

#include <cctype>
#include <cmath>
#include <set>

#include "report.h"
#include "thicket/common/statistics.h"

namespace thicket::bench::report_internal {

std::string densityText(double density) {
  return print("%g", density);
}

std::string percent(double fraction) {
  return print("%.0f", std::round(100 * fraction));
}

std::string successCell(const Tally& tally) {
  if (tally.trials == 0) return "–";
  const Interval ci = wilsonInterval(tally.successes, tally.trials);
  return std::to_string(tally.successes) + "/" + std::to_string(tally.trials) + " = " +
         percent(static_cast<double>(tally.successes) / tally.trials) + " % [" + percent(ci.low) +
         ", " + percent(ci.high) + "]";
}

std::string milliseconds(double ms) {
  const double magnitude = std::fabs(ms);
  if (magnitude >= 100) return print("%.0f", ms);
  if (magnitude >= 10) return print("%.1f", ms);
  if (magnitude >= 1) return print("%.2f", ms);
  return print("%.3f", ms);
}

std::string meters(double m) {
  return print("%.2f", m);
}

std::string duration(double s) {
  if (s < 600) return print("%.1f s", s);
  if (s < 2 * 3600) return print("%.1f min", s / 60);
  return print("%.2f h", s / 3600);
}

std::string escapeCell(const std::string& text) {
  std::string escaped;
  for (char c : text) {
    if (c == '|')
      escaped += "\\|";
    else if (c == '\n' || c == '\r')
      escaped += ' ';
    else
      escaped += c;
  }
  return escaped;
}

std::string markdownTable(const std::vector<std::string>& header,
                          const std::vector<std::vector<std::string>>& rows) {
  auto line = [](const std::vector<std::string>& cells) {
    std::string text = "|";
    for (const std::string& cell : cells) text += " " + escapeCell(cell) + " |";
    return text + "\n";
  };
  // Numbers right-aligned: a column whose every cell starts with a digit or is a dash.
  std::string text = line(header) + "|";
  for (size_t i = 0; i < header.size(); ++i) {
    bool numeric = i > 0 && !rows.empty();
    for (const auto& row : rows) {
      const std::string& cell = i < row.size() ? row[i] : std::string();
      numeric = numeric && !cell.empty() &&
                (std::isdigit(static_cast<unsigned char>(cell[0])) || cell == "–");
    }
    text += numeric ? "--:|" : "---|";
  }
  text += "\n";
  for (const auto& row : rows) text += line(row);
  return text + "\n";
}

std::string medianOrDash(const std::vector<double>& values) {
  return values.empty() ? "–" : meters(median(values));
}

std::string successMatrix(const SuccessTable& table, const std::vector<std::string>& order,
                          const std::string& first_column) {
  std::set<double> densities;
  for (const auto& [variant, by_density] : table) {
    for (const auto& [density, tally] : by_density) densities.insert(density);
  }
  std::vector<std::string> header = {first_column};
  header.insert(header.end(), order.begin(), order.end());
  std::vector<std::vector<std::string>> rows;
  for (double density : densities) {
    std::vector<std::string> row = {densityText(density)};
    for (const std::string& variant : order) {
      const auto& by_density = table.at(variant);
      const auto found = by_density.find(density);
      row.push_back(found == by_density.end() ? "–" : successCell(found->second));
    }
    rows.push_back(row);
  }
  return markdownTable(header, rows);
}

}  // namespace thicket::bench::report_internal
