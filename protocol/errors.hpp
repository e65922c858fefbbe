// Error codes of the mtlod protocol (PROTOCOL.md, "Errors"). Each becomes the `code` string of an
// `error` reply; the message says which field, which value and which limit.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>

namespace mtlod::protocol {

enum class ErrorKind : std::uint8_t {
  kBadFrame,            // frame header broken or frame larger than the limit (connection closes)
  kBadJson,             // the JSON text does not parse
  kBadRequest,          // a field is missing, has the wrong type, a bad value, or is unknown
  kUnknownType,         // the `type` is not a request this server knows
  kUnsupportedVersion,  // hello asked for a protocol version the server does not speak
  kLimitExceeded,       // grid, budget, foci or in-flight requests over the server's limits
  kUnknownModel,        // no model of that name is loaded
  kNoView,              // gaze before any extract on this connection
  kCancelled,           // the request was cancelled before it ran
  kSuperseded,          // a newer gaze replaced this one before it ran
  kShuttingDown,        // the server is draining and takes no new work
  kUnauthorized,        // the server wants an access token and the connection has not shown a valid one
  kUnavailable,         // the model's file is being rewritten in place; retry once the new one is loaded
  kInternal,            // the server failed; the message says how (kept last: counters size by it)
};

const char* to_string(ErrorKind kind);

struct ProtocolError {
  ProtocolError() = default;
  ProtocolError(ErrorKind code, std::string message, std::optional<std::uint64_t> request_id = std::nullopt)
      : code(code), message(std::move(message)), request_id(request_id) {}

  ErrorKind code = ErrorKind::kInternal;
  std::string message;
  // The id of the request that failed, when it could be read: even a bad request's error reply
  // carries it. parse_request sets it; later stages know the id and leave it empty.
  std::optional<std::uint64_t> request_id;
};

}  // namespace mtlod::protocol
