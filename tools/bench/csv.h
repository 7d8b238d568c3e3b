// CSV (RFC 4180) as the benchmark writes and reads it: trials.csv, the rows files, run_log.csv,
// e5_subsampling.csv and the report's figure tables. One tokenizer (parseCsv) serves both the
// driver's resume and merge code, which must tell a last line torn by a killed writer from the
// complete records, and the report's strict reader (readCsv), whose errors name file, line and
// column.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "thicket/common/expected.h"

namespace thicket::bench {

/// One record: its cells and the line it starts on (1-based; a quoted cell may span lines).
struct CsvRecord {
  int line = 0;
  std::vector<std::string> cells;
};

/// A malformed quote: where (the record's line, or the quote's for one never closed) and what.
struct CsvError {
  int line = 0;
  size_t cell = 0;  ///< 0-based, in its record
  std::string message;
};

/// A CSV text's records.
struct CsvText {
  /// The records that end with a line end. A blank line is no record.
  std::vector<CsvRecord> records;
  /// The text after the last line end, when there is any, as a record: a last line without a
  /// line end (a writer killed mid-line, or a file without a final line end), or a quote never
  /// closed. Not in `records`.
  std::optional<CsvRecord> torn_tail;
  /// Byte offset just after the last line end (outside quotes): the complete records' text.
  size_t complete_bytes = 0;
  /// The first malformed quote, if any. The records are read on regardless: a quote inside an
  /// unquoted cell opens a quoted section, text after a closing quote is kept.
  std::optional<CsvError> error;
};

/// Reads `text` as RFC 4180 records: quoted cells with doubled quotes, separators and line breaks
/// inside quotes, LF or CRLF line ends.
CsvText parseCsv(const std::string& text);

/// A CSV file as read: the header's cells, then the data rows with the lines they start on (the
/// header being line 1) for messages.
struct CsvTable {
  std::vector<std::string> header;
  std::vector<CsvRecord> rows;
};

/// Reads an RFC 4180 CSV file (parseCsv; a final line end is optional). Refuses, naming the file,
/// line and column: an unreadable or empty file, a quote inside an unquoted field, text after a
/// closing quote, an unterminated quote, and a row with more or fewer cells than the header.
Expected<CsvTable> readCsv(const std::string& path);

/// "<file> line <line>, column <cell + 1>": a place in a CSV file for messages.
std::string csvWhere(const std::string& file, int line, size_t cell);

/// `text` as a CSV cell: quoted (quotes doubled) when it holds a comma, quote or line break.
std::string csvCell(const std::string& text);

/// One CSV line of `cells` (csvCell), with "\n".
std::string csvLine(const std::vector<std::string>& cells);

/// The whole file at `path`, for parseCsv; throws std::runtime_error when it cannot be read.
std::string readWholeFile(const std::string& path);

}  // namespace thicket::bench
