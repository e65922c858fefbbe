// Text that came from a client, made safe to put in a reply or a log line. Request frames may
// carry any bytes, and error messages quote them (a bad value, the parser's "last read" context):
// nlohmann::json refuses to serialise invalid UTF-8, and raw control bytes would let a client
// forge log lines.
#pragma once

#include <string>
#include <string_view>

namespace mtlod::protocol {

// `text` with every invalid or truncated UTF-8 sequence replaced by U+FFFD and every control
// character (C0 and DEL) written as \xNN. Valid printable text comes back unchanged.
std::string printable(std::string_view text);

// The longest prefix of `text` of at most `max_bytes` bytes that does not end inside a UTF-8
// sequence (for quoting the start of a long value).
std::string_view utf8_prefix(std::string_view text, std::size_t max_bytes);

}  // namespace mtlod::protocol
