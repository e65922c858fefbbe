// mtlod::Result<T, E>: a value or an error, the one shape of every fallible result in the tree. E is
// Error{code, message} for everything that reads untrusted bytes (files, frames, JSON); the protocol
// uses its own error (protocol/errors.hpp), whose codes are the wire's. Modelled on Draco's StatusOr;
// GCC 12 has no std::expected.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <variant>

namespace mtlod {

enum class ErrorCode : std::uint8_t {
  kInvalidArgument,  // a caller or request gave a value outside its domain
  kNotFound,         // a named file, model or field does not exist
  kIoError,          // the operating system refused a read or write
  kCorrupt,          // bytes do not follow the format (bad magic, checksum, index, truncation)
  kUnsupported,      // valid but not handled (unknown version, unknown property type)
  kLimitExceeded,    // a size is over a configured limit
  kBusy,             // another process holds the resource (a file open for writing); try later
  kInternal,         // a library we call failed in a way we did not foresee
};

const char* to_string(ErrorCode code);

struct Error {
  ErrorCode code = ErrorCode::kInternal;
  std::string message;
};

template <class T, class E = Error>
class [[nodiscard]] Result {
 public:
  Result(T value) : data_(std::move(value)) {}  // NOLINT: implicit by design, like StatusOr
  Result(E error) : data_(std::move(error)) {}  // NOLINT

  bool ok() const { return data_.index() == 0; }
  explicit operator bool() const { return ok(); }

  T& value() & { return std::get<0>(data_); }
  const T& value() const& { return std::get<0>(data_); }
  T&& value() && { return std::get<0>(std::move(data_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

  const E& error() const { return std::get<1>(data_); }
  E&& take_error() { return std::get<1>(std::move(data_)); }

 private:
  std::variant<T, E> data_;
};

// Result<void>: success or an Error.
struct Ok {};
using Status = Result<Ok>;

inline Error make_error(ErrorCode code, std::string message) {
  return Error{code, std::move(message)};
}

}  // namespace mtlod

#define MTLOD_CONCAT_INNER_(a, b) a##b
#define MTLOD_CONCAT_(a, b) MTLOD_CONCAT_INNER_(a, b)

// MTLOD_TRY(auto x, expr): evaluates a Result expression, returns its Error from the enclosing
// function on failure, otherwise binds the value to the declaration.
#define MTLOD_TRY(decl, expr) MTLOD_TRY_IMPL_(MTLOD_CONCAT_(mtlod_try_, __LINE__), decl, expr)
#define MTLOD_TRY_IMPL_(tmp, decl, expr)  \
  auto tmp = (expr);                      \
  if (!tmp.ok()) return tmp.take_error(); \
  decl = std::move(tmp).value()

// MTLOD_RETURN_IF_ERROR(expr): for Status-returning calls.
#define MTLOD_RETURN_IF_ERROR(expr)                             \
  do {                                                          \
    auto mtlod_status_ = (expr);                                \
    if (!mtlod_status_.ok()) return mtlod_status_.take_error(); \
  } while (0)
