// The server's log lines: text for people (the default) or one JSON object per line for log
// shippers (--log-format json). Both carry the same fields; spdlog writes them to stderr.
#pragma once

#include <cstdint>
#include <string_view>

#include "protocol/replies.hpp"

namespace mtlod::server {

enum class LogFormat : std::uint8_t { kText, kJson };

// Parses "text" or "json"; returns false for anything else.
bool parse_log_format(std::string_view name, LogFormat& format);

// Sets the pattern of every line: "TIME LEVEL message", or {"time":…,"level":…,"msg":…} with the
// message escaped. Call once at start, before any other thread logs.
void setup_logging(LogFormat format);

// One line per extraction (extract or gaze): in text, "conn=… id=… extract model=… …"; in JSON, the
// same fields as members ("us" holds the stage timings).
void log_extraction(std::uint64_t connection, std::uint64_t id, bool gaze, const protocol::MeshReply& reply);

}  // namespace mtlod::server
