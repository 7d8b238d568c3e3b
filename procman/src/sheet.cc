#include "thicket/procman/sheet.h"

#include <algorithm>
#include <climits>
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <map>
#include <string_view>
#include <utility>

#include "thicket/procman/printable.h"

namespace thicket::procman {
namespace {

// Deeper group nesting is refused so that a hostile sheet cannot exhaust the parser's stack.
constexpr int kMaxGroupDepth = 100;

constexpr const char* kKnownAttributes =
    "exec, host, deputy, auto_respawn, stop_signal, stop_time_allowed";

struct Position {
  int line = 1;
  int column = 1;
};

// A refusal inside the parser; parseSheet turns it into "<source>:<line>:<column>: <what>".
struct SheetError {
  Position at;
  std::string what;
};

[[noreturn]] void fail(Position at, std::string what) {
  throw SheetError{at, std::move(what)};
}

// The string as written in a sheet: double-quoted, with the escapes the lexer translates back.
std::string quote(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        out += c;
    }
  }
  return out + "\"";
}

// A name from the sheet as an error message shows it: quoted, controls escaped, and cut short,
// so that a 2 MB command id does not make a 2 MB message.
std::string quoteShort(const std::string& text) {
  return "\"" + printableShort(text) + "\"";
}

bool isLetter(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || c == '_';
}
bool isDigit(char c) {
  return c >= '0' && c <= '9';
}
bool isSpace(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
}
bool isContinuationByte(char c) {
  return (static_cast<unsigned char>(c) & 0xC0) == 0x80;
}

enum class TokenKind { kEnd, kIdentifier, kInteger, kString, kSymbol };

struct Token {
  TokenKind kind = TokenKind::kEnd;
  std::string text;  // the identifier, the digits, the string's value, or the symbol
  int64_t integer = 0;
  Position at;
};

// What a message says was found instead of what was expected.
std::string describe(const Token& token) {
  switch (token.kind) {
    case TokenKind::kEnd:
      return "end of file";
    case TokenKind::kInteger:
      return "integer " + token.text;
    case TokenKind::kString:
      return "string " + quoteShort(token.text);
    case TokenKind::kIdentifier:
    case TokenKind::kSymbol:
      break;
  }
  return "'" + printableShort(token.text) + "'";
}

bool isWord(const Token& token, std::string_view word) {
  return token.kind == TokenKind::kIdentifier && token.text == word;
}
bool isSymbol(const Token& token, std::string_view symbol) {
  return token.kind == TokenKind::kSymbol && token.text == symbol;
}

// Splits the text into tokens on demand, so that the first error in the text is the one reported.
class Lexer {
 public:
  explicit Lexer(std::string_view text) : text_(text) {}

  const Token& peek() {
    if (!peeked_) {
      next_ = scan();
      peeked_ = true;
    }
    return next_;
  }

  Token next() {
    peek();
    peeked_ = false;
    return std::move(next_);
  }

 private:
  bool atEnd() const { return offset_ == text_.size(); }
  char current() const { return text_[offset_]; }

  void advance() {
    const char c = text_[offset_++];
    if (c == '\n') {
      ++position_.line;
      position_.column = 1;
    } else if (!isContinuationByte(c)) {
      ++position_.column;
    }
  }

  void skipSpaceAndComments() {
    while (!atEnd()) {
      if (current() == '#') {
        while (!atEnd() && current() != '\n') advance();
      } else if (isSpace(current())) {
        advance();
      } else {
        return;
      }
    }
  }

  Token scan() {
    skipSpaceAndComments();
    Token token;
    token.at = position_;
    if (atEnd()) return token;
    const char c = current();
    const std::size_t start = offset_;
    if (isLetter(c)) {
      token.kind = TokenKind::kIdentifier;
      while (!atEnd() && (isLetter(current()) || isDigit(current()) || current() == '-')) advance();
      token.text = std::string(text_.substr(start, offset_ - start));
    } else if (isDigit(c)) {
      token.kind = TokenKind::kInteger;
      bool overflow = false;
      while (!atEnd() && isDigit(current())) {
        const int digit = current() - '0';
        if (token.integer > (INT64_MAX - digit) / 10) overflow = true;
        if (!overflow) token.integer = token.integer * 10 + digit;
        advance();
      }
      token.text = std::string(text_.substr(start, offset_ - start));
      if (overflow) {
        fail(token.at,
             "integer " + token.text + " is too large (at most " + std::to_string(INT64_MAX) + ")");
      }
    } else if (c == '"') {
      token.kind = TokenKind::kString;
      token.text = scanString(token.at);
    } else if (c == '=' || c == ';' || c == '{' || c == '}') {
      token.kind = TokenKind::kSymbol;
      token.text = std::string(1, c);
      advance();
    } else {
      fail(token.at, "unexpected character " + describeCharacter());
    }
    return token;
  }

  // The value of the string starting at the current '"'.
  std::string scanString(Position start) {
    advance();
    std::string value;
    for (;;) {
      if (atEnd()) fail(start, "unterminated string: the file ends before its closing '\"'");
      char c = current();
      if (c == '"') {
        advance();
        return value;
      }
      if (c == '\\') {
        advance();
        if (atEnd()) fail(start, "unterminated string: the file ends before its closing '\"'");
        c = current();
        if (c != '\n') c = c == 'n' ? '\n' : c == 'r' ? '\r' : c == 't' ? '\t' : c;
      }
      if (current() == '\n') {
        fail(start,
             "unterminated string: it runs into the end of the line (write a newline as \\n)");
      }
      value += c;
      advance();
    }
  }

  // The character at the current offset as a message shows it: UTF-8 as is, controls in hex.
  std::string describeCharacter() const {
    const auto byte = static_cast<unsigned char>(current());
    if (byte >= 0x80) {
      std::size_t end = offset_ + 1;
      while (end < text_.size() && isContinuationByte(text_[end])) ++end;
      return "'" + std::string(text_.substr(offset_, end - offset_)) + "'";
    }
    if (byte < 0x20 || byte == 0x7F) {
      constexpr char kHex[] = "0123456789ABCDEF";
      return std::string("0x") + kHex[byte >> 4] + kHex[byte & 0xF];
    }
    return "'" + std::string(1, current()) + "'";
  }

  std::string_view text_;
  std::size_t offset_ = 0;
  Position position_;
  Token next_;
  bool peeked_ = false;
};

class Parser {
 public:
  explicit Parser(std::string_view text) : lexer_(text) {}

  Sheet parse() {
    for (;;) {
      const Token& token = lexer_.peek();
      if (token.kind == TokenKind::kEnd) break;
      if (isWord(token, "cmd")) {
        parseCommand("");
      } else if (isWord(token, "group")) {
        parseGroup("", 1);
      } else if (isWord(token, "script")) {
        parseScript();
      } else {
        unexpected(token, "'cmd', 'group' or 'script'");
      }
    }
    checkReferences();
    checkCycles();
    return std::move(sheet_);
  }

 private:
  [[noreturn]] static void unexpected(const Token& token, const std::string& expected) {
    if (token.kind == TokenKind::kEnd)
      fail(token.at, "unexpected end of file, expected " + expected);
    fail(token.at, "expected " + expected + ", got " + describe(token));
  }

  void expectSymbol(std::string_view symbol, const std::string& expected) {
    const Token token = lexer_.next();
    if (!isSymbol(token, symbol)) unexpected(token, expected);
  }

  Token expectKind(TokenKind kind, const std::string& expected) {
    Token token = lexer_.next();
    if (token.kind != kind) unexpected(token, expected);
    return token;
  }

  void parseCommand(const std::string& group) {
    const Token keyword = lexer_.next();
    const Token id = expectKind(TokenKind::kString, "the command id (a string) after 'cmd'");
    if (id.text.empty()) fail(id.at, "empty command id");
    if (id.text.find('/') != std::string::npos) {
      fail(id.at, "command id " + quoteShort(id.text) +
                      " contains '/' (a command's group comes from the enclosing group blocks)");
    }
    if (const SheetCommand* first = sheet_.command(id.text)) {
      fail(id.at, "duplicate command id " + quoteShort(id.text) + " (first defined at line " +
                      std::to_string(first->line) + "; ids are global to the sheet)");
    }
    expectSymbol("{", "'{' after the command id");

    SheetCommand command;
    command.id = id.text;
    command.group = group;
    command.line = keyword.at.line;
    std::map<std::string, Position> given;  // attribute name -> where
    for (;;) {
      const Token name = lexer_.next();
      if (isSymbol(name, "}")) break;
      if (name.kind != TokenKind::kIdentifier) {
        unexpected(name, "an attribute name or '}' closing command " + quoteShort(command.id));
      }
      expectSymbol("=", "'=' after '" + name.text + "'");
      const Token value = lexer_.next();
      if (value.kind != TokenKind::kString && value.kind != TokenKind::kInteger) {
        unexpected(value, "a string or an integer as the value of '" + name.text + "'");
      }
      setAttribute(command, name, value, given);
      expectSymbol(";", "';' after the value of '" + name.text + "'");
    }
    if (!given.contains("exec")) {
      fail(keyword.at, "command " + quoteShort(command.id) + " has no 'exec' attribute");
    }
    if (!given.contains("deputy") && !given.contains("host")) {
      fail(keyword.at,
           "command " + quoteShort(command.id) + " has no 'deputy' (or 'host') attribute");
    }
    sheet_.commands.push_back(std::move(command));
  }

  static void setAttribute(SheetCommand& command, const Token& name, const Token& value,
                           std::map<std::string, Position>& given) {
    const std::string& key = name.text;
    const bool is_string =
        key == "exec" || key == "host" || key == "deputy" || key == "auto_respawn";
    const bool is_integer = key == "stop_signal" || key == "stop_time_allowed";
    if (!is_string && !is_integer) {
      fail(name.at, "unknown attribute '" + key + "' (known: " + kKnownAttributes + ")");
    }
    if (const auto it = given.find(key); it != given.end()) {
      fail(name.at, "duplicate attribute '" + key + "' (already given at line " +
                        std::to_string(it->second.line) + ")");
    }
    const std::string other = key == "host" ? "deputy" : key == "deputy" ? "host" : "";
    if (!other.empty() && given.contains(other)) {
      fail(name.at,
           "both 'host' and 'deputy' given; they are two spellings of the same "
           "attribute, keep one");
    }
    given[key] = name.at;

    if (is_string && value.kind != TokenKind::kString) {
      fail(value.at, "attribute '" + key + "' takes a string, got " + describe(value));
    }
    if (is_integer && value.kind != TokenKind::kInteger) {
      fail(value.at, "attribute '" + key + "' takes an integer, got " + describe(value));
    }
    if (key == "exec") {
      command.exec = value.text;
    } else if (key == "host" || key == "deputy") {
      command.deputy = value.text;
    } else if (key == "auto_respawn") {
      std::string lower = value.text;
      std::transform(lower.begin(), lower.end(), lower.begin(),
                     [](char c) { return c >= 'A' && c <= 'Z' ? char(c - 'A' + 'a') : c; });
      command.auto_respawn = lower == "true" || lower == "yes";
    } else if (key == "stop_signal") {
      if (value.integer < 1 || value.integer > 64) {
        fail(value.at, "stop_signal " + value.text + " is out of range (1..64)");
      }
      command.stop_signal = static_cast<int>(value.integer);
    } else {
      if (value.integer > INT_MAX) {
        fail(value.at, "stop_time_allowed " + value.text + " is out of range (0.." +
                           std::to_string(INT_MAX) + " seconds)");
      }
      command.stop_time_allowed = static_cast<int>(value.integer);
    }
  }

  void parseGroup(const std::string& parent, int depth) {
    const Token keyword = lexer_.next();
    const Token name = expectKind(TokenKind::kString, "the group name (a string) after 'group'");
    if (name.text.empty()) fail(name.at, "empty group name");
    if (name.text.find('/') != std::string::npos) {
      fail(name.at, "group name " + quoteShort(name.text) +
                        " contains '/' (write nested group blocks for a subgroup)");
    }
    if (depth > kMaxGroupDepth) {
      fail(keyword.at,
           "groups nest too deeply (at most " + std::to_string(kMaxGroupDepth) + " levels)");
    }
    const std::string path = parent.empty() ? name.text : parent + "/" + name.text;
    if (std::find(sheet_.groups.begin(), sheet_.groups.end(), path) == sheet_.groups.end()) {
      sheet_.groups.push_back(path);
    }
    expectSymbol("{", "'{' after the group name");
    for (;;) {
      const Token& token = lexer_.peek();
      if (isSymbol(token, "}")) {
        lexer_.next();
        return;
      }
      if (isWord(token, "cmd")) {
        parseCommand(path);
      } else if (isWord(token, "group")) {
        parseGroup(path, depth + 1);
      } else {
        unexpected(token, "'cmd', 'group' or '}' closing group " + quoteShort(path) +
                              " (opened at line " + std::to_string(keyword.at.line) + ")");
      }
    }
  }

  void parseScript() {
    const Token keyword = lexer_.next();
    const Token name = expectKind(TokenKind::kString, "the script name (a string) after 'script'");
    if (name.text.empty()) fail(name.at, "empty script name");
    if (const SheetScript* first = sheet_.script(name.text)) {
      fail(name.at, "duplicate script name " + quoteShort(name.text) + " (first defined at line " +
                        std::to_string(first->line) + ")");
    }
    expectSymbol("{", "'{' after the script name");
    SheetScript script;
    script.name = name.text;
    script.line = keyword.at.line;
    std::vector<Position>& name_at = reference_at_.emplace_back();
    for (;;) {
      const Token keyword = lexer_.next();
      if (isSymbol(keyword, "}")) break;
      SheetAction action;
      action.line = keyword.at.line;
      action.column = keyword.at.column;
      Position reference = keyword.at;
      if (isWord(keyword, "start") || isWord(keyword, "stop") || isWord(keyword, "restart")) {
        action.kind = isWord(keyword, "start")  ? SheetAction::Kind::kStart
                      : isWord(keyword, "stop") ? SheetAction::Kind::kStop
                                                : SheetAction::Kind::kRestart;
        reference = parseTarget(action.target, true,
                                "'everything', 'cmd' or 'group' after '" + keyword.text + "'");
        if (isWord(lexer_.peek(), "wait")) {
          lexer_.next();
          action.wait = parseStatus();
        }
      } else if (isWord(keyword, "wait")) {
        if (isWord(lexer_.peek(), "ms")) {
          lexer_.next();
          action.kind = SheetAction::Kind::kWaitMs;
          action.ms =
              expectKind(TokenKind::kInteger, "a number of milliseconds after 'wait ms'").integer;
        } else {
          action.kind = SheetAction::Kind::kWaitStatus;
          reference = parseTarget(action.target, false, "'ms', 'cmd' or 'group' after 'wait'");
          const Token status = lexer_.next();
          if (!isWord(status, "status")) unexpected(status, "'status' after the wait target");
          action.wait = parseStatus();
        }
      } else if (isWord(keyword, "run_script")) {
        action.kind = SheetAction::Kind::kRunScript;
        const Token callee =
            expectKind(TokenKind::kString, "the script name (a string) after 'run_script'");
        action.script = callee.text;
        reference = callee.at;
      } else {
        unexpected(keyword,
                   "an action ('start', 'stop', 'restart', 'wait' or 'run_script') or "
                   "'}' closing script " +
                       quoteShort(script.name));
      }
      expectSymbol(";", "';' after the action");
      script.actions.push_back(std::move(action));
      name_at.push_back(reference);
    }
    sheet_.scripts.push_back(std::move(script));
  }

  // Reads `cmd "id"`, `group "path"` or, when allowed, `everything`; returns where the name is.
  // `expected` is what an error says was expected instead.
  Position parseTarget(SheetTarget& target, bool allow_everything, const std::string& expected) {
    const Token kind = lexer_.next();
    if (allow_everything && isWord(kind, "everything")) {
      target.kind = SheetTarget::Kind::kEverything;
      return kind.at;
    }
    if (!isWord(kind, "cmd") && !isWord(kind, "group")) unexpected(kind, expected);
    target.kind = isWord(kind, "cmd") ? SheetTarget::Kind::kCommand : SheetTarget::Kind::kGroup;
    const Token name =
        expectKind(TokenKind::kString, (isWord(kind, "cmd") ? "the command id" : "the group path") +
                                           std::string(" (a string) after '") + kind.text + "'");
    target.name = name.text;
    return name.at;
  }

  SheetAction::WaitFor parseStatus() {
    const Token status = lexer_.next();
    if (status.kind == TokenKind::kString && status.text == "running") {
      return SheetAction::WaitFor::kRunning;
    }
    if (status.kind == TokenKind::kString && status.text == "stopped") {
      return SheetAction::WaitFor::kStopped;
    }
    unexpected(status, "\"running\" or \"stopped\"");
  }

  // Scripts may name what is defined further down, so names are checked once all is read.
  void checkReferences() const {
    for (std::size_t s = 0; s < sheet_.scripts.size(); ++s) {
      const SheetScript& script = sheet_.scripts[s];
      for (std::size_t a = 0; a < script.actions.size(); ++a) {
        const SheetAction& action = script.actions[a];
        const Position at = reference_at_[s][a];
        if (action.kind == SheetAction::Kind::kRunScript) {
          if (!sheet_.script(action.script)) {
            fail(at, "script " + quoteShort(script.name) + " runs unknown script " +
                         quoteShort(action.script));
          }
        } else if (action.target.kind == SheetTarget::Kind::kCommand) {
          if (!sheet_.command(action.target.name)) {
            fail(at, "script " + quoteShort(script.name) + " names unknown command " +
                         quoteShort(action.target.name));
          }
        } else if (action.target.kind == SheetTarget::Kind::kGroup) {
          checkGroup(script, action.target.name, at);
        }
      }
    }
  }

  void checkGroup(const SheetScript& script, const std::string& path, Position at) const {
    const auto& groups = sheet_.groups;
    if (std::find(groups.begin(), groups.end(), path) != groups.end()) return;
    std::string what =
        "script " + quoteShort(script.name) + " names unknown group " + quoteShort(path);
    // An inner group named by its own name alone: point at the full path.
    const auto full = std::find_if(groups.begin(), groups.end(), [&](const std::string& group) {
      return group.size() > path.size() && group.ends_with("/" + path);
    });
    if (full != groups.end()) {
      what += " (groups are named by their full path, e.g. " + quoteShort(*full) + ")";
    }
    fail(at, what);
  }

  // Depth-first over the run_script graph from every script in sheet order; the first run_script
  // that reaches a script still being explored closes a cycle.
  void checkCycles() const {
    enum class State { kUnvisited, kActive, kDone };
    const auto& scripts = sheet_.scripts;
    std::map<std::string, std::size_t> index;
    for (std::size_t s = 0; s < scripts.size(); ++s) index[scripts[s].name] = s;
    std::vector<State> state(scripts.size(), State::kUnvisited);
    for (std::size_t root = 0; root < scripts.size(); ++root) {
      if (state[root] != State::kUnvisited) continue;
      std::vector<std::pair<std::size_t, std::size_t>> stack{{root, 0}};  // script, next action
      state[root] = State::kActive;
      while (!stack.empty()) {
        const std::size_t s = stack.back().first;
        const std::size_t a = stack.back().second++;
        if (a == scripts[s].actions.size()) {
          state[s] = State::kDone;
          stack.pop_back();
          continue;
        }
        const SheetAction& action = scripts[s].actions[a];
        if (action.kind != SheetAction::Kind::kRunScript) continue;
        const std::size_t callee = index.at(action.script);
        if (state[callee] == State::kActive) {
          std::string chain;
          const auto from = std::find_if(stack.begin(), stack.end(),
                                         [&](const auto& frame) { return frame.first == callee; });
          for (auto frame = from; frame != stack.end(); ++frame) {
            chain += scripts[frame->first].name + " -> ";
          }
          fail(reference_at_[s][a], "script " + quoteShort(scripts[callee].name) +
                                        " would run itself: " + chain + scripts[callee].name);
        }
        if (state[callee] == State::kUnvisited) {
          state[callee] = State::kActive;
          stack.emplace_back(callee, 0);
        }
      }
    }
  }

  Lexer lexer_;
  Sheet sheet_;
  // Per script, per action: where the name it refers to is (the keyword when it names nothing).
  std::vector<std::vector<Position>> reference_at_;
};

std::vector<std::string> splitPath(const std::string& path) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (start < path.size()) {
    std::size_t end = path.find('/', start);
    if (end == std::string::npos) end = path.size();
    parts.push_back(path.substr(start, end - start));
    start = end + 1;
  }
  return parts;
}

// Writes blocks at the right nesting, opening and closing group blocks as it moves between paths.
class SheetWriter {
 public:
  // Closes the open groups that are not ancestors of `path` and opens the rest of `path`.
  void moveTo(const std::string& path) {
    const std::vector<std::string> target = splitPath(path);
    std::size_t common = 0;
    while (common < open_.size() && common < target.size() && open_[common] == target[common]) {
      ++common;
    }
    while (open_.size() > common) {
      open_.pop_back();
      line(0, "}");
    }
    while (open_.size() < target.size()) {
      separateTopLevel();
      line(0, "group " + quote(target[open_.size()]) + " {");
      open_.push_back(target[open_.size()]);
    }
  }

  void command(const SheetCommand& command) {
    separateTopLevel();
    line(0, "cmd " + quote(command.id) + " {");
    line(1, "exec = " + quote(command.exec) + ";");
    line(1, "deputy = " + quote(command.deputy) + ";");
    if (command.auto_respawn) line(1, "auto_respawn = \"true\";");
    if (command.stop_signal != SheetCommand{}.stop_signal) {
      line(1, "stop_signal = " + std::to_string(command.stop_signal) + ";");
    }
    if (command.stop_time_allowed != SheetCommand{}.stop_time_allowed) {
      line(1, "stop_time_allowed = " + std::to_string(command.stop_time_allowed) + ";");
    }
    line(0, "}");
  }

  void script(const SheetScript& script) {
    moveTo("");
    separateTopLevel();
    line(0, "script " + quote(script.name) + " {");
    for (const SheetAction& action : script.actions) line(1, actionText(action));
    line(0, "}");
  }

  std::string text() {
    moveTo("");
    return std::move(out_);
  }

 private:
  static std::string targetText(const SheetTarget& target) {
    if (target.kind == SheetTarget::Kind::kCommand) return "cmd " + quote(target.name);
    if (target.kind == SheetTarget::Kind::kGroup) return "group " + quote(target.name);
    return "everything";
  }

  static std::string statusText(SheetAction::WaitFor wait) {
    return wait == SheetAction::WaitFor::kRunning ? "\"running\"" : "\"stopped\"";
  }

  static std::string actionText(const SheetAction& action) {
    using Kind = SheetAction::Kind;
    switch (action.kind) {
      case Kind::kWaitMs:
        return "wait ms " + std::to_string(action.ms) + ";";
      case Kind::kWaitStatus:
        return "wait " + targetText(action.target) + " status " + statusText(action.wait) + ";";
      case Kind::kRunScript:
        return "run_script " + quote(action.script) + ";";
      case Kind::kStart:
      case Kind::kStop:
      case Kind::kRestart:
        break;
    }
    const char* verb = action.kind == Kind::kStart  ? "start"
                       : action.kind == Kind::kStop ? "stop"
                                                    : "restart";
    std::string text = std::string(verb) + " " + targetText(action.target);
    if (action.wait != SheetAction::WaitFor::kNothing) text += " wait " + statusText(action.wait);
    return text + ";";
  }

  // A blank line before each top-level block but the first.
  void separateTopLevel() {
    if (open_.empty() && !out_.empty()) out_ += "\n";
  }

  void line(std::size_t indent, const std::string& text) {
    out_ += std::string(4 * (open_.size() + indent), ' ') + text + "\n";
  }

  std::string out_;
  std::vector<std::string> open_;  // the names of the open group blocks, outermost first
};

}  // namespace

const SheetCommand* Sheet::command(const std::string& id) const {
  const auto it = std::find_if(commands.begin(), commands.end(),
                               [&](const SheetCommand& command) { return command.id == id; });
  return it == commands.end() ? nullptr : &*it;
}

const SheetScript* Sheet::script(const std::string& name) const {
  const auto it = std::find_if(scripts.begin(), scripts.end(),
                               [&](const SheetScript& script) { return script.name == name; });
  return it == scripts.end() ? nullptr : &*it;
}

std::vector<const SheetCommand*> Sheet::commandsInGroup(const std::string& group) const {
  std::vector<const SheetCommand*> found;
  for (const SheetCommand& command : commands) {
    if (group.empty() || command.group == group || command.group.starts_with(group + "/")) {
      found.push_back(&command);
    }
  }
  return found;
}

Expected<Sheet> parseSheet(const std::string& text, const std::string& source) {
  try {
    return Parser(text).parse();
  } catch (const SheetError& error) {
    return unexpected(source + ":" + std::to_string(error.at.line) + ":" +
                      std::to_string(error.at.column) + ": " + error.what);
  }
}

Expected<Sheet> loadSheet(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) return unexpected(path + ": cannot read");
  const std::string text{std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
  if (file.bad()) return unexpected(path + ": cannot read");
  return parseSheet(text, path);
}

std::string formatSheet(const Sheet& sheet) {
  SheetWriter writer;
  // Groups are opened in the order of sheet.groups, each no later than its first command, so
  // that the text parses back to the same command and group order.
  std::size_t next_group = 0;
  const auto opened = [&](const std::string& path) {
    const auto end = sheet.groups.begin() + static_cast<std::ptrdiff_t>(next_group);
    return std::find(sheet.groups.begin(), end, path) != end;
  };
  for (const SheetCommand& command : sheet.commands) {
    while (!command.group.empty() && !opened(command.group) && next_group < sheet.groups.size()) {
      writer.moveTo(sheet.groups[next_group++]);
    }
    writer.moveTo(command.group);
    writer.command(command);
  }
  while (next_group < sheet.groups.size()) writer.moveTo(sheet.groups[next_group++]);
  for (const SheetScript& script : sheet.scripts) writer.script(script);
  return writer.text();
}

}  // namespace thicket::procman
