// Parsing and validation of client requests (PROTOCOL.md, "Messages"). Every problem yields a
// ProtocolError naming the field, the value and the limit; nothing here throws.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/result.hpp"
#include "protocol/errors.hpp"
#include "protocol/messages.hpp"

namespace mtlod::protocol {

struct ParsedRequest {
  std::uint64_t id = 0;
  Request request;
};

// Parses one JSON request and checks it against `limits`. Unknown fields are errors (a typo must
// not silently fall back to a default). The error carries the request's id when it could be read.
Result<ParsedRequest, ProtocolError> parse_request(std::string_view json, const Limits& limits);

// A scene as an extract's "scene" object holds it, {"instances": [{"model", "matrix"}, ...]}: from a
// file a client or server reads, checked as a request's is.
Result<std::vector<Instance>, ProtocolError> parse_scene(std::string_view json, const Limits& limits);

// Why `codec` cannot encode what `request` asks for (a bad_request message), or nothing. The parser
// checks an extract's own codec; the server checks the connection's when the extract names none.
std::optional<std::string> codec_refusal(const Extract& request, core::codec::Codec codec);

// The JSON a client sends for `request` with id `id`; parse_request reads it back unchanged.
std::string to_json(const Request& request, std::uint64_t id);

}  // namespace mtlod::protocol
