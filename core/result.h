// Result<T>: a value or an error message, returned at file, network and config boundaries.
// Thread-safety: plain value types.
#pragma once

#include <string>
#include <utility>
#include <variant>

#include "core/check.h"

namespace driftlab {

/// What kind of failure an error is, so that a caller decides by it and never by the message's words. The programs'
/// exit codes follow it (apps/cli_util.h): bad input 2, the others 1.
enum class ErrorCode {
  kBadInput,     ///< the input (a file, an option, a config) is wrong: the user fixes it
  kCannotWrite,  ///< an output or a cache could not be written (a full disk, a read-only folder)
};

/// A user-facing error: one line that names the file and the place (offset, key, line), and its code. Control
/// characters that came in with user text (a YAML key or value, a parser's quote of the input) are escaped as \xNN,
/// so the message stays one printable line.
struct Error {
  Error() = default;
  Error(std::string m, ErrorCode c = ErrorCode::kBadInput)  // NOLINT(google-explicit-constructor)
      : message(std::move(m)), code(c) {
    static constexpr char kHex[] = "0123456789abcdef";
    for (size_t i = 0; i < message.size(); ++i) {
      const auto ch = static_cast<unsigned char>(message[i]);
      if (ch >= 0x20 && ch != 0x7f) continue;
      message.replace(i, 1, std::string{'\\', 'x', kHex[ch >> 4], kHex[ch & 15]});
      i += 3;
    }
  }
  std::string message;
  ErrorCode code = ErrorCode::kBadInput;
};

/// An exception's what() in one line for a user: its first line, or for an MRPT exception (a banner line, then
/// "Message: ...", the source location and a call stack) the message.
inline std::string one_line(std::string what) {
  if (const auto at = what.find("Message:"); what.rfind("==== MRPT exception", 0) == 0 && at != std::string::npos) {
    const auto begin = what.find_first_not_of(' ', at + 8);
    what = begin == std::string::npos ? std::string() : what.substr(begin);
  }
  return what.substr(0, what.find('\n'));
}

/// Either a T or an Error. Accessing the wrong alternative is a broken invariant (core/check.h), said with the error.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}  // NOLINT(google-explicit-constructor)
  Result(Error error) : v_(std::move(error)) {}  // NOLINT(google-explicit-constructor)

  bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }

  T& value() & { return check(), std::get<0>(v_); }
  const T& value() const& { return check(), std::get<0>(v_); }
  T&& value() && { return check(), std::get<0>(std::move(v_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }

  const Error& error() const {
    DRIFTLAB_CHECK(!ok(), "error() of a Result that holds a value");
    return std::get<1>(v_);
  }

 private:
  void check() const {
    if (!ok()) {
      const std::string what = "value() of a Result that holds an error: " + std::get<1>(v_).message;
      internal_error(__FILE__, __LINE__, what.c_str());
    }
  }
  std::variant<T, Error> v_;
};

/// Result of an operation that returns nothing but may fail.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Error error) : error_(std::move(error.message)), code_(error.code), failed_(true) {}  // NOLINT

  bool ok() const { return !failed_; }
  explicit operator bool() const { return ok(); }
  const std::string& message() const { return error_; }
  ErrorCode code() const { return code_; }
  /// The failure as an Error again, its code kept (a Status handed up as a Result's error).
  Error error() const { return Error(error_, code_); }

 private:
  std::string error_;
  ErrorCode code_ = ErrorCode::kBadInput;
  bool failed_ = false;
};

}  // namespace driftlab
