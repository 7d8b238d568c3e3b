// The crash-safe store of finished trials: rows/*.csv read, checked, appended to, and trials.csv.
#pragma once

#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "plans.h"
#include "trials.h"

namespace thicket::bench {

// The columns of a rows file: trials.csv's fixed columns, then the timings of every stage in one
// cell ("<stage>=<median>/<p95>/<max>;...", ms).
const std::vector<std::string>& rowColumns();
// The index of column `name` in rowColumns().
size_t column(const std::string& name);

// One finished trial, as stored.
struct Row {
  std::vector<std::string> cells;  // under rowColumns()
  TrialSpec spec;                  // what the cells say, for keys and sorting
  std::map<std::string, StageTiming> timings;
  std::string source;  // the output folder the row was read from (merge copies its files)

  const std::string& cell(const std::string& name) const { return cells[column(name)]; }
  bool failed() const { return failedToRun(cell("end_reason")); }
};

// The row of a trial flown (or that could not run).
Row rowFromResult(const TrialSpec& spec, const TrialResult& result);

// Every row of DIR/rows/*.csv, in file name order: a torn last line (a run killed mid-write) is
// ignored, a line that is not a row is reported on stderr and ignored (its trial runs again).
// Throws when a file cannot be read or its header is not rowColumns().
std::vector<Row> readRows(const std::string& command, const std::string& dir);

// Each trial once: a later row replaces an earlier one, unless the later could not run and the
// earlier did. Sorted by experiment, scenario, density, method, goal finding, sensor, seed.
// Throws when a trial was flown with two replan limits (runs with different --replans in one
// folder): the rows would not describe one experiment.
std::vector<Row> uniqueRows(std::vector<Row> rows);

// Written beside `path` and renamed over it, so a reader never sees half a file.
void replaceFile(const std::string& path, const std::string& text);

// A rows file: the header, then the rows.
std::string rowsText(const std::vector<Row>& rows);

// trials.csv: the rows with their timings spread into three columns per stage seen in any row.
void writeTrialsCsv(const std::string& dir, const std::vector<Row>& rows);

// The rows file this shard appends to, locked against a second run of the same shard.
class RowsAppender {
 public:
  // Opens (creates) `path`; cuts a torn last line, so the next row starts on a line of its own;
  // writes the header into an empty file. Throws std::runtime_error saying what failed.
  RowsAppender(const std::string& command, const std::string& path);
  ~RowsAppender();
  RowsAppender(const RowsAppender&) = delete;
  RowsAppender& operator=(const RowsAppender&) = delete;

  // Appends a whole line; the kernel has it when this returns, so a killed run keeps it.
  void append(const std::string& line);

 private:
  std::string path_;
  int fd_ = -1;
};

}  // namespace thicket::bench
