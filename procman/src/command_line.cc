#include "thicket/procman/command_line.h"

#include <optional>

extern char** environ;

namespace thicket::procman {
namespace {

bool isNameStart(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
}
bool isNameChar(char c) {
  return isNameStart(c) || (c >= '0' && c <= '9');
}
bool isSpace(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

// One word being built. `assignment_at` is the position of the '=' that makes the word an
// assignment: set only when everything before it was an unquoted, unescaped name.
struct Word {
  std::string text;
  bool plain_prefix = true;
  std::optional<size_t> assignment_at;

  void literal(char c) {  // unquoted, unescaped source character
    if (!assignment_at && plain_prefix) {
      if (c == '=' && !text.empty()) {
        assignment_at = text.size();
      } else if (!(text.empty() ? isNameStart(c) : isNameChar(c))) {
        plain_prefix = false;
      }
    }
    text.push_back(c);
  }
  void special(const std::string& s) {  // quoted, escaped or expanded text
    if (!assignment_at) plain_prefix = false;
    text += s;
  }
};

class Splitter {
 public:
  Splitter(const std::string& exec, const Environment& environment)
      : in_(exec), env_(environment) {}

  Expected<std::vector<Word>> run() {
    std::vector<Word> words;
    while (true) {
      while (pos_ < in_.size() && isSpace(in_[pos_])) ++pos_;
      if (pos_ >= in_.size()) return words;
      Word word;
      while (pos_ < in_.size() && !isSpace(in_[pos_])) {
        const char c = in_[pos_];
        if (c == '\'') {
          const size_t start = pos_++;
          const size_t end = in_.find('\'', pos_);
          if (end == std::string::npos) return unterminated("single", start);
          // An empty quoted part still makes the word exist ('' is an empty argument).
          word.special(in_.substr(pos_, end - pos_));
          pos_ = end + 1;
        } else if (c == '"') {
          const size_t start = pos_++;
          std::string part;
          bool closed = false;
          while (pos_ < in_.size()) {
            const char d = in_[pos_];
            if (d == '"') {
              ++pos_;
              closed = true;
              break;
            }
            if (d == '\\' && pos_ + 1 < in_.size()) {
              part.push_back(in_[pos_ + 1]);
              pos_ += 2;
            } else if (d == '$') {
              part += expand();
            } else {
              part.push_back(d);
              ++pos_;
            }
          }
          if (!closed) return unterminated("double", start);
          word.special(part);
        } else if (c == '\\') {
          if (pos_ + 1 < in_.size()) {
            word.special(std::string(1, in_[pos_ + 1]));
            pos_ += 2;
          } else {
            word.special("\\");
            ++pos_;
          }
        } else if (c == '$') {
          const size_t before = pos_;
          const std::string value = expand();
          if (pos_ == before + 1 && value == "$") {
            word.literal('$');
          } else {
            word.special(value);
          }
        } else {
          word.literal(c);
          ++pos_;
        }
      }
      words.push_back(std::move(word));
    }
  }

 private:
  Unexpected unterminated(const char* kind, size_t at) const {
    return unexpected(std::string("unterminated ") + kind + " quote starting at column " +
                      std::to_string(at + 1));
  }

  // At a '$': consumes a variable reference and returns its value, or the source text when the
  // variable is undefined or the reference is malformed.
  std::string expand() {
    const size_t start = pos_++;
    const bool braces = pos_ < in_.size() && in_[pos_] == '{';
    size_t name_start = braces ? pos_ + 1 : pos_;
    size_t end = name_start;
    if (end < in_.size() && isNameStart(in_[end])) {
      ++end;
      while (end < in_.size() && isNameChar(in_[end])) ++end;
    }
    if (end == name_start || (braces && (end >= in_.size() || in_[end] != '}'))) {
      return "$";  // not a reference: only the '$' is consumed
    }
    const std::string name = in_.substr(name_start, end - name_start);
    pos_ = braces ? end + 1 : end;
    const auto found = env_.find(name);
    if (found == env_.end()) return in_.substr(start, pos_ - start);
    return found->second;
  }

  const std::string& in_;
  const Environment& env_;
  size_t pos_ = 0;
};

}  // namespace

Expected<CommandLine> splitCommandLine(const std::string& exec, const Environment& environment) {
  auto words = Splitter(exec, environment).run();
  if (!words) return unexpected(words.error());
  CommandLine command;
  for (Word& word : *words) {
    if (command.argv.empty() && word.assignment_at) {
      const size_t eq = *word.assignment_at;
      command.assignments.emplace_back(word.text.substr(0, eq), word.text.substr(eq + 1));
    } else {
      command.argv.push_back(std::move(word.text));
    }
  }
  if (command.argv.empty()) {
    return unexpected(command.assignments.empty() ? "empty command"
                                                  : "empty command: only variable assignments");
  }
  return command;
}

Environment currentEnvironment() {
  Environment environment;
  for (char** entry = environ; entry != nullptr && *entry != nullptr; ++entry) {
    const std::string text(*entry);
    const size_t eq = text.find('=');
    if (eq == std::string::npos || eq == 0) continue;
    environment.emplace(text.substr(0, eq), text.substr(eq + 1));
  }
  return environment;
}

std::vector<std::string> childEnvironment(const Environment& base, const CommandLine& command) {
  Environment merged = base;
  for (const auto& [name, value] : command.assignments) merged[name] = value;
  std::vector<std::string> result;
  result.reserve(merged.size());
  for (const auto& [name, value] : merged) result.push_back(name + "=" + value);
  return result;
}

}  // namespace thicket::procman
