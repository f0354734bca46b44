// tinstream/base/result.hpp — how library code reports bad input.
//
// Contract: functions that can fail because of their *input* (a malformed file, a bad quadkey,
// a hostile request) return Result<T> or Status instead of throwing through a library boundary.
// An Error carries a human-readable message that names what was wrong (file, record, tile,
// request) and a coarse Code so callers (e.g. the HTTP server) can map it to a response.
// Programmer errors (violated preconditions) are asserts, not Errors.
#pragma once

#include <cassert>
#include <string>
#include <utility>
#include <variant>

namespace tinstream {

enum class ErrorCode {
  invalid_argument,  // malformed input: quadkey, option, request
  not_found,         // absent tile, layer, file
  corrupt_data,      // truncated or inconsistent file contents
  unsupported,       // valid but not handled (format version, CRS)
  io_error,          // the operating system refused
  cancelled,         // the operation was asked to stop
  internal,          // a broken invariant that was caught instead of crashing
};

struct Error {
  ErrorCode code = ErrorCode::internal;
  std::string message;

  Error() = default;
  Error(ErrorCode c, std::string m) : code(c), message(std::move(m)) {}
};

inline Error invalid_argument(std::string m) { return {ErrorCode::invalid_argument, std::move(m)}; }
inline Error not_found(std::string m) { return {ErrorCode::not_found, std::move(m)}; }
inline Error corrupt_data(std::string m) { return {ErrorCode::corrupt_data, std::move(m)}; }
inline Error unsupported(std::string m) { return {ErrorCode::unsupported, std::move(m)}; }
inline Error io_error(std::string m) { return {ErrorCode::io_error, std::move(m)}; }

// A value or an Error. Accessing the wrong alternative is a programmer error (assert).
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}      // NOLINT(google-explicit-constructor)
  Result(Error error) : v_(std::move(error)) {}  // NOLINT(google-explicit-constructor)

  bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }

  T& value() & {
    assert(ok());
    return std::get<0>(v_);
  }
  const T& value() const& {
    assert(ok());
    return std::get<0>(v_);
  }
  T&& value() && {
    assert(ok());
    return std::get<0>(std::move(v_));
  }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }

  const Error& error() const {
    assert(!ok());
    return std::get<1>(v_);
  }

 private:
  std::variant<T, Error> v_;
};

// Success or an Error.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Error error)
      : error_(std::move(error)), ok_(false) {}  // NOLINT(google-explicit-constructor)

  bool ok() const { return ok_; }
  explicit operator bool() const { return ok_; }
  const Error& error() const {
    assert(!ok_);
    return error_;
  }

 private:
  Error error_;
  bool ok_ = true;
};

}  // namespace tinstream
