// A value or the reason there is none. thicket validates everything it receives; functions that
// can refuse their input return Expected<T> with a human-readable error instead of throwing.
#pragma once

#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

namespace thicket {

/// The error half of Expected: a message meant for an operator.
struct Unexpected {
  std::string message;
};

inline Unexpected unexpected(std::string message) {
  return Unexpected{std::move(message)};
}

template <class T>
class Expected {
 public:
  Expected(T value) : value_(std::move(value)) {}                   // NOLINT: implicit by design
  Expected(Unexpected error) : error_(std::move(error.message)) {}  // NOLINT

  bool ok() const { return value_.has_value(); }
  explicit operator bool() const { return ok(); }

  /// The value; throws std::logic_error with the error message when there is none.
  const T& value() const& {
    if (!ok()) throw std::logic_error("Expected has no value: " + error_);
    return *value_;
  }
  T& value() & {
    if (!ok()) throw std::logic_error("Expected has no value: " + error_);
    return *value_;
  }
  T&& value() && {
    if (!ok()) throw std::logic_error("Expected has no value: " + error_);
    return std::move(*value_);
  }
  const T& operator*() const& { return value(); }
  T& operator*() & { return value(); }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }

  /// Empty when ok().
  const std::string& error() const { return error_; }

 private:
  std::optional<T> value_;
  std::string error_;
};

}  // namespace thicket
