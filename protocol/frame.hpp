// Framing of mtlod messages over a byte stream (protocol/PROTOCOL.md, "Framing"): an 8-byte header
// holding the JSON length and the binary payload length (both uint32 little-endian), then the JSON
// text, then the raw payload. Pure functions over spans: no sockets.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "core/result.hpp"

namespace mtlod::protocol {

inline constexpr std::size_t kFrameHeaderBytes = 8;

// 32-bit little-endian values, assembled byte by byte so the code does not depend on the host's
// byte order (frame headers, delta replies' ids).
inline std::uint32_t read_u32_le(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | std::uint32_t{p[1]} << 8 | std::uint32_t{p[2]} << 16 |
         std::uint32_t{p[3]} << 24;
}
inline void write_u32_le(std::uint32_t v, std::uint8_t* p) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

struct FrameHeader {
  std::uint32_t json_bytes = 0;
  std::uint32_t payload_bytes = 0;
  std::size_t body_bytes() const { return std::size_t{json_bytes} + payload_bytes; }
};

// Decodes a frame header and checks it against the receiver's limit on the body (JSON + payload).
// Errors: kLimitExceeded when the body is larger than max_body_bytes, kCorrupt for an empty JSON part.
Result<FrameHeader> decode_frame_header(std::span<const std::uint8_t, kFrameHeaderBytes> bytes,
                                        std::size_t max_body_bytes);

std::array<std::uint8_t, kFrameHeaderBytes> encode_frame_header(const FrameHeader& header);

// Appends a whole frame (header, JSON, payload) to `out`.
void append_frame(std::string_view json, std::span<const std::uint8_t> payload,
                  std::vector<std::uint8_t>& out);

// A frame taken apart; the views point into the buffer it was split from.
struct FrameView {
  std::string_view json;
  std::span<const std::uint8_t> payload;
};

// Incremental splitter for a client or a test reading a stream: feed bytes, take frames.
class FrameReader {
 public:
  explicit FrameReader(std::size_t max_body_bytes) : max_body_bytes_(max_body_bytes) {}

  void feed(std::span<const std::uint8_t> bytes) {
    buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
  }

  // The next complete frame, an empty optional-like result (ok with `has_frame == false`) when more
  // bytes are needed, or an error when the stream is broken. A returned frame stays valid until
  // the next call to next() or feed().
  struct Next {
    bool has_frame = false;
    FrameView frame;
  };
  Result<Next> next();

 private:
  std::size_t max_body_bytes_;
  std::vector<std::uint8_t> buffer_;
  std::size_t consumed_ = 0;  // bytes of buffer_ already returned as frames
};

}  // namespace mtlod::protocol
