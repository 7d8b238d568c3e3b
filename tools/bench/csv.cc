#include "csv.h"

#include <fstream>
#include <iterator>
#include <stdexcept>
#include <utility>

namespace thicket::bench {

CsvText parseCsv(const std::string& text) {
  enum class State { kFieldStart, kUnquoted, kQuoted, kAfterQuote };
  CsvText csv;
  State state = State::kFieldStart;
  CsvRecord record{1, {}};
  std::string field;
  int line = 1, quote_line = 1;
  const auto fail = [&](int at_line, const char* message) {
    if (!csv.error) csv.error = CsvError{at_line, record.cells.size(), message};
  };
  const auto endField = [&] {
    record.cells.push_back(std::move(field));
    field.clear();
  };
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (state == State::kQuoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        state = State::kAfterQuote;
      } else {
        line += c == '\n';
        field += c;
      }
      continue;
    }
    if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') continue;  // CRLF
    if (c == ',') {
      endField();
      state = State::kFieldStart;
    } else if (c == '\n') {
      const bool blank = record.cells.empty() && field.empty() && state != State::kAfterQuote;
      endField();
      if (!blank) csv.records.push_back(std::move(record));
      record = {line + 1, {}};
      ++line;
      state = State::kFieldStart;
      csv.complete_bytes = i + 1;
    } else if (c == '"') {
      if (state != State::kFieldStart) {
        fail(line, "a quote inside a field that did not start with one");
      }
      state = State::kQuoted;
      quote_line = line;
    } else {
      if (state == State::kAfterQuote) fail(line, "text after a closing quote");
      field += c;
      state = State::kUnquoted;
    }
  }
  if (state == State::kQuoted) fail(quote_line, "the quote opened here is never closed");
  if (csv.complete_bytes < text.size()) {
    endField();
    csv.torn_tail = std::move(record);
  }
  return csv;
}

Expected<CsvTable> readCsv(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) return unexpected("cannot read " + path);
  const std::string text((std::istreambuf_iterator<char>(file)), {});
  if (file.bad()) return unexpected("cannot read " + path);

  CsvText csv = parseCsv(text);
  if (csv.error) {
    return unexpected(csvWhere(path, csv.error->line, csv.error->cell) + ": " + csv.error->message);
  }
  if (csv.torn_tail) csv.records.push_back(std::move(*csv.torn_tail));
  if (csv.records.empty()) return unexpected(path + ": empty, not even a header");
  CsvTable table;
  table.header = std::move(csv.records.front().cells);
  for (size_t r = 1; r < csv.records.size(); ++r) {
    if (csv.records[r].cells.size() != table.header.size()) {
      return unexpected(path + " line " + std::to_string(csv.records[r].line) + ": " +
                        std::to_string(csv.records[r].cells.size()) + " cells, the header has " +
                        std::to_string(table.header.size()));
    }
    table.rows.push_back(std::move(csv.records[r]));
  }
  return table;
}

std::string csvWhere(const std::string& file, int line, size_t cell) {
  return file + " line " + std::to_string(line) + ", column " + std::to_string(cell + 1);
}

std::string csvCell(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

std::string csvLine(const std::vector<std::string>& cells) {
  std::string line;
  for (size_t i = 0; i < cells.size(); ++i) line += (i ? "," : "") + csvCell(cells[i]);
  return line + "\n";
}

std::string readWholeFile(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw std::runtime_error("cannot read " + path);
  std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  if (file.bad()) throw std::runtime_error("cannot read " + path);
  return text;
}

}  // namespace thicket::bench
