// thicket-bench's CSV output as tables of strings, for tests that compare runs: the same trials
// must give the same rows at any thread count, shard or resume, wall-clock times aside.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "csv.h"

namespace thicket::bench::testing {

using Table = std::vector<std::vector<std::string>>;

/// The header, then the rows; a failure (and an empty table) when the file does not read.
inline Table readTable(const std::string& path) {
  const auto csv = readCsv(path);
  EXPECT_TRUE(csv) << path << ": " << csv.error();
  if (!csv) return {};
  Table table = {csv->header};
  for (const CsvRecord& row : csv->rows) table.push_back(row.cells);
  return table;
}

/// Row `row` of a table (1: the first after the header) as cells by column name; a failure (and
/// no cells) when the table has no such row.
inline std::map<std::string, std::string> cellsByColumn(const Table& table, size_t row = 1) {
  EXPECT_LT(row, table.size()) << "no row " << row;
  std::map<std::string, std::string> cells;
  if (row >= table.size()) return cells;
  for (size_t i = 0; i < table[0].size() && i < table[row].size(); ++i) {
    cells[table[0][i]] = table[row][i];
  }
  return cells;
}

/// A table without the columns that measure wall-clock time (wall_time_s and the stage timings):
/// what must not depend on threads, shards or resuming.
inline Table withoutTimes(const Table& table) {
  if (table.empty()) return {};
  std::vector<bool> keep;
  for (const std::string& column : table.front()) {
    keep.push_back(column != "wall_time_s" && column.find("_ms_") == std::string::npos &&
                   column != "timings");
  }
  Table kept;
  for (const std::vector<std::string>& row : table) {
    EXPECT_EQ(row.size(), keep.size());
    std::vector<std::string> cells;
    for (size_t i = 0; i < row.size() && i < keep.size(); ++i) {
      if (keep[i]) cells.push_back(row[i]);
    }
    kept.push_back(cells);
  }
  return kept;
}

}  // namespace thicket::bench::testing
