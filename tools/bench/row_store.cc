// The rows files: their columns, a row's cells and timings, reading and checking them, appending.
#include "row_store.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "csv.h"
#include "flags.h"
#include "plans.h"
#include "thicket/common/number_text.h"

namespace thicket::bench {

namespace fs = std::filesystem;

namespace {

// "a,b," -> {"a", "b", ""}; "" -> {}.
std::vector<std::string> split(const std::string& text, char separator = ',') {
  std::vector<std::string> items;
  std::stringstream stream(text);
  for (std::string item; std::getline(stream, item, separator);) items.push_back(item);
  if (!text.empty() && text.back() == separator) items.emplace_back();
  return items;
}

const std::vector<std::string>& idColumns() {
  static const std::vector<std::string> columns = {"experiment",   "trial",   "seed",
                                                   "scenario",     "density", "method",
                                                   "goal_finding", "sensor",  "replan_limit"};
  return columns;
}

std::string timingsText(const std::map<std::string, StageTiming>& timings) {
  std::string text;
  for (const auto& [stage, t] : timings) {
    text += (text.empty() ? "" : ";") + stage + "=" + formatNumber("%.3f", t.median_ms) + "/" +
            formatNumber("%.3f", t.p95_ms) + "/" + formatNumber("%.3f", t.max_ms);
  }
  return text;
}

bool parseDouble(const std::string& text, double& value) {
  const std::optional<double> parsed = finiteNumber(text);
  if (parsed) value = *parsed;
  return parsed.has_value();
}

template <class Int>
bool parseInt(const std::string& text, Int& value) {
  const std::optional<Int> parsed = integerNumber<Int>(text);
  if (parsed) value = *parsed;
  return parsed.has_value();
}

std::optional<std::map<std::string, StageTiming>> parseTimings(const std::string& text) {
  std::map<std::string, StageTiming> timings;
  if (text.empty()) return timings;
  for (const std::string& item : split(text, ';')) {
    const size_t equals = item.find('=');
    if (equals == 0 || equals == std::string::npos) return std::nullopt;
    const std::vector<std::string> numbers = split(item.substr(equals + 1), '/');
    StageTiming t;
    if (numbers.size() != 3 || !parseDouble(numbers[0], t.median_ms) ||
        !parseDouble(numbers[1], t.p95_ms) || !parseDouble(numbers[2], t.max_ms)) {
      return std::nullopt;
    }
    timings[item.substr(0, equals)] = t;
  }
  return timings;
}

// The row a stored line holds, or why it is not one.
Expected<Row> rowFromCells(std::vector<std::string> cells) {
  if (cells.size() != rowColumns().size()) {
    return unexpected(std::to_string(cells.size()) + " cells instead of " +
                      std::to_string(rowColumns().size()));
  }
  Row row;
  row.cells = std::move(cells);
  TrialSpec& s = row.spec;
  s.experiment = row.cell("experiment");
  s.scenario = row.cell("scenario");
  s.method = row.cell("method");
  s.goal_finding = row.cell("goal_finding");
  s.sensor = row.cell("sensor");
  const auto plan = std::find_if(plans().begin(), plans().end(),
                                 [&](const Plan& p) { return s.experiment == p.id; });
  if (plan == plans().end()) return unexpected("unknown experiment '" + s.experiment + "'");
  s.dynamic_obstacle = plan->dynamic_obstacle;
  if (!parseInt(row.cell("trial"), s.trial) || !parseInt(row.cell("seed"), s.seed) ||
      !parseDouble(row.cell("density"), s.density) ||
      !parseInt(row.cell("replan_limit"), s.replans)) {
    return unexpected("trial, seed, density or replan_limit is not a number");
  }
  for (const char* flag : {"success", "collision", "feasible", "solvable",
                           "solvable_collision_radius", "needs_overflight"}) {
    if (row.cell(flag) != "0" && row.cell(flag) != "1") {
      return unexpected(std::string(flag) + " is neither 0 nor 1");
    }
  }
  double clearance = 0;
  int blocked = 0;
  if (!row.cell("obstacle_clearance_m").empty() &&
      !parseDouble(row.cell("obstacle_clearance_m"), clearance)) {
    return unexpected("obstacle_clearance_m is neither empty nor a number");
  }
  if (!parseInt(row.cell("blocked_cycles"), blocked) || blocked < 0) {
    return unexpected("blocked_cycles is not a count");
  }
  auto timings = parseTimings(row.cell("timings"));
  if (!timings) return unexpected("timings is not stage=median/p95/max;...");
  row.timings = std::move(*timings);
  return row;
}

// Throws unless `csv` is empty or starts with the rows header. Rows of an older thicket-bench
// are refused with what they lack, not read with the new columns empty: those written before the
// oracle had two radii have `solvable` at the collision radius, where new rows have it at the
// planning radius; those written before the dynamic obstacle have no obstacle_clearance_m and
// blocked_cycles, which an E6 row must have.
void checkRowsHeader(const std::string& path, const CsvText& csv) {
  if (csv.records.empty() || csv.records[0].cells == rowColumns()) return;
  const std::vector<std::string>& header = csv.records[0].cells;
  const auto has = [&](const char* column) {
    return std::find(header.begin(), header.end(), column) != header.end();
  };
  const auto older = [&](const std::string& what) {
    return std::runtime_error(path + ": rows of an older thicket-bench, " + what +
                              "; they cannot be resumed or merged with new rows (use another "
                              "--out; the report still reads that folder's trials.csv)");
  };
  if (has("solvable") && !has("solvable_collision_radius")) {
    throw older(
        "whose solvable is the oracle at the collision radius and which lack "
        "solvable_collision_radius, bottleneck_m and needs_overflight");
  }
  if (has("end_reason") && !has("obstacle_clearance_m") && !has("blocked_cycles")) {
    throw older(
        "written before the dynamic obstacle (E6), which lack obstacle_clearance_m and "
        "blocked_cycles");
  }
  throw std::runtime_error(path + ": not a rows file of this thicket-bench (its header is '" +
                           joined(header, ",") + "', expected '" + joined(rowColumns(), ",") +
                           "')");
}

// The rows of `text` (the file `path`); a torn last line is ignored (a run killed mid-write), a
// line that is not a row is reported and ignored (its trial runs again). Throws when the header
// is not rowColumns(): that is another program's file, or another version's.
std::vector<Row> parseRows(const std::string& command, const std::string& path,
                           const std::string& text, const std::string& source) {
  const CsvText csv = parseCsv(text);
  std::vector<Row> rows;
  checkRowsHeader(path, csv);
  if (csv.records.empty()) return rows;  // empty, or a header torn while being written
  if (csv.torn_tail) warn(command, "ignoring the torn last line of " + path + " (a killed run)");
  for (size_t i = 1; i < csv.records.size(); ++i) {
    Expected<Row> row = rowFromCells(csv.records[i].cells);
    if (!row) {
      warn(command, path + " line " + std::to_string(csv.records[i].line) + ": " + row.error() +
                        "; ignored");
      continue;
    }
    row->source = source;
    rows.push_back(std::move(*row));
  }
  return rows;
}

}  // namespace

const std::vector<std::string>& rowColumns() {
  static const std::vector<std::string> columns = [] {
    std::vector<std::string> all = idColumns();
    all.insert(all.end(), outcomeColumns().begin(), outcomeColumns().end());
    all.emplace_back("timings");
    return all;
  }();
  return columns;
}

size_t column(const std::string& name) {
  const auto& columns = rowColumns();
  return static_cast<size_t>(std::find(columns.begin(), columns.end(), name) - columns.begin());
}

Row rowFromResult(const TrialSpec& spec, const TrialResult& result) {
  Row row;
  row.spec = spec;
  row.cells = {spec.experiment,
               std::to_string(spec.trial),
               std::to_string(spec.seed),
               spec.scenario,
               formatNumber("%g", spec.density),
               spec.method,
               spec.goal_finding,
               spec.sensor,
               std::to_string(spec.replans)};
  const std::vector<std::string> outcome = outcomeCells(result);
  row.cells.insert(row.cells.end(), outcome.begin(), outcome.end());
  row.cells.push_back(timingsText(result.timings));
  row.timings = result.timings;
  return row;
}

std::vector<Row> readRows(const std::string& command, const std::string& dir) {
  std::vector<std::string> files;
  if (fs::is_directory(dir + "/rows")) {
    for (const fs::directory_entry& entry : fs::directory_iterator(dir + "/rows")) {
      if (entry.is_regular_file() && entry.path().extension() == ".csv") {
        files.push_back(entry.path().string());
      }
    }
  }
  std::sort(files.begin(), files.end());
  std::vector<Row> rows;
  for (const std::string& file : files) {
    std::vector<Row> more = parseRows(command, file, readWholeFile(file), dir);
    std::move(more.begin(), more.end(), std::back_inserter(rows));
  }
  return rows;
}

std::vector<Row> uniqueRows(std::vector<Row> rows) {
  std::map<std::string, Row> by_key;
  for (Row& row : rows) {
    const std::string key = row.spec.key();
    const auto existing = by_key.find(key);
    if (existing == by_key.end()) {
      by_key.emplace(key, std::move(row));
      continue;
    }
    const Row& kept = existing->second;
    if (!row.failed() && !kept.failed() && row.spec.replans != kept.spec.replans) {
      throw std::runtime_error(
          key + " was flown with replan limit " + std::to_string(kept.spec.replans) + " (in " +
          kept.source + ") and " + std::to_string(row.spec.replans) + " (in " + row.source + ")");
    }
    if (!row.failed() || kept.failed()) {
      existing->second = std::move(row);
    }
  }
  std::vector<Row> unique;
  for (auto& [key, row] : by_key) unique.push_back(std::move(row));
  const auto order = [](const Row& r) {
    const TrialSpec& s = r.spec;
    return std::tie(s.experiment, s.scenario, s.density, s.method, s.goal_finding, s.sensor,
                    s.seed);
  };
  std::sort(unique.begin(), unique.end(),
            [&](const Row& a, const Row& b) { return order(a) < order(b); });
  return unique;
}

void replaceFile(const std::string& path, const std::string& text) {
  const std::string temporary = path + ".tmp";
  writeTextFile(temporary, text);
  std::error_code error;
  fs::rename(temporary, path, error);
  if (error) throw std::runtime_error("cannot write " + path + ": " + error.message());
}

std::string rowsText(const std::vector<Row>& rows) {
  std::string text = csvLine(rowColumns());
  for (const Row& row : rows) text += csvLine(row.cells);
  return text;
}

void writeTrialsCsv(const std::string& dir, const std::vector<Row>& rows) {
  std::set<std::string> stages;
  for (const Row& row : rows) {
    for (const auto& [stage, timing] : row.timings) stages.insert(stage);
  }
  std::vector<std::string> header(rowColumns().begin(), rowColumns().end() - 1);
  const std::vector<std::string> stage_columns = stageColumns(stages);
  header.insert(header.end(), stage_columns.begin(), stage_columns.end());
  std::string text = csvLine(header);
  for (const Row& row : rows) {
    std::vector<std::string> cells(row.cells.begin(), row.cells.end() - 1);
    const std::vector<std::string> timing_cells = stageCells(stages, row.timings);
    cells.insert(cells.end(), timing_cells.begin(), timing_cells.end());
    text += csvLine(cells);
  }
  replaceFile(dir + "/trials.csv", text);
}

RowsAppender::RowsAppender(const std::string& command, const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd_ < 0) throw std::runtime_error("cannot open " + path + ": " + std::strerror(errno));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd_);
    throw std::runtime_error("another thicket-bench experiment is writing " + path +
                             " (same --out and --shard)");
  }
  try {
    const std::string text = readWholeFile(path);
    const CsvText csv = parseCsv(text);
    checkRowsHeader(path, csv);
    if (csv.torn_tail || csv.records.empty()) {
      if (csv.torn_tail) {
        warn(command, "cutting the torn last line of " + path + " (a killed run)");
      }
      if (::ftruncate(fd_, csv.records.empty() ? 0 : static_cast<off_t>(csv.complete_bytes)) != 0) {
        throw std::runtime_error("cannot cut " + path + ": " + std::strerror(errno));
      }
    }
    if (csv.records.empty()) append(csvLine(rowColumns()));
  } catch (...) {
    ::close(fd_);
    throw;
  }
}

RowsAppender::~RowsAppender() {
  ::close(fd_);
}

void RowsAppender::append(const std::string& line) {
  size_t written = 0;
  while (written < line.size()) {
    const ssize_t n = ::write(fd_, line.data() + written, line.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw std::runtime_error("cannot write " + path_ + ": " + std::strerror(errno));
    written += static_cast<size_t>(n);
  }
}

}  // namespace thicket::bench
