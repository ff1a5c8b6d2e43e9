// Result<T>: a value or an error message, returned at file, network and config boundaries.
// Thread-safety: plain value types.
#pragma once

#include <cstdlib>
#include <string>
#include <utility>
#include <variant>

namespace driftlab {

/// A user-facing error: one line that names the file and the place (offset, key, line). Control characters that
/// came in with user text (a YAML key or value, a parser's quote of the input) are escaped as \xNN, so the message
/// stays one printable line.
struct Error {
  Error() = default;
  Error(std::string m) : message(std::move(m)) {  // NOLINT(google-explicit-constructor)
    static constexpr char kHex[] = "0123456789abcdef";
    for (size_t i = 0; i < message.size(); ++i) {
      const auto c = static_cast<unsigned char>(message[i]);
      if (c >= 0x20 && c != 0x7f) continue;
      message.replace(i, 1, std::string{'\\', 'x', kHex[c >> 4], kHex[c & 15]});
      i += 3;
    }
  }
  std::string message;
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

/// Either a T or an Error. Accessing the wrong alternative aborts (a broken invariant).
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
    if (ok()) std::abort();
    return std::get<1>(v_);
  }

 private:
  void check() const {
    if (!ok()) std::abort();
  }
  std::variant<T, Error> v_;
};

/// Result of an operation that returns nothing but may fail.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Error error) : error_(std::move(error.message)), failed_(true) {}  // NOLINT

  bool ok() const { return !failed_; }
  explicit operator bool() const { return ok(); }
  const std::string& message() const { return error_; }

 private:
  std::string error_;
  bool failed_ = false;
};

}  // namespace driftlab
