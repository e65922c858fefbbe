// Frame header coding (PROTOCOL.md, "Framing"). Little-endian by definition (read_u32_le,
// write_u32_le).
#include "protocol/frame.hpp"

#include "fmt/format.h"

namespace mtlod::protocol {

Result<FrameHeader> decode_frame_header(std::span<const std::uint8_t, kFrameHeaderBytes> bytes,
                                        std::size_t max_body_bytes) {
  FrameHeader h{read_u32_le(bytes.data()), read_u32_le(bytes.data() + 4)};
  if (h.json_bytes == 0) return make_error(ErrorCode::kCorrupt, "frame has an empty JSON header");
  if (h.body_bytes() > max_body_bytes) {
    return make_error(
        ErrorCode::kLimitExceeded,
        fmt::format("frame of {} bytes exceeds the limit of {} bytes", h.body_bytes(), max_body_bytes));
  }
  return h;
}

std::array<std::uint8_t, kFrameHeaderBytes> encode_frame_header(const FrameHeader& header) {
  std::array<std::uint8_t, kFrameHeaderBytes> bytes;
  write_u32_le(header.json_bytes, bytes.data());
  write_u32_le(header.payload_bytes, bytes.data() + 4);
  return bytes;
}

void append_frame(std::string_view json, std::span<const std::uint8_t> payload,
                  std::vector<std::uint8_t>& out) {
  const auto header = encode_frame_header(
      {static_cast<std::uint32_t>(json.size()), static_cast<std::uint32_t>(payload.size())});
  out.insert(out.end(), header.begin(), header.end());
  out.insert(out.end(), json.begin(), json.end());
  out.insert(out.end(), payload.begin(), payload.end());
}

Result<FrameReader::Next> FrameReader::next() {
  // Drop what earlier frames used once it is at least half the buffer: amortised O(1) per byte.
  if (consumed_ > 0 && consumed_ * 2 >= buffer_.size()) {
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(consumed_));
    consumed_ = 0;
  }
  const std::size_t available = buffer_.size() - consumed_;
  if (available < kFrameHeaderBytes) return Next{};
  const std::uint8_t* start = buffer_.data() + consumed_;
  MTLOD_TRY(const FrameHeader header,
            decode_frame_header(std::span<const std::uint8_t, kFrameHeaderBytes>(start, kFrameHeaderBytes),
                                max_body_bytes_));
  if (available < kFrameHeaderBytes + header.body_bytes()) return Next{};
  Next next;
  next.has_frame = true;
  next.frame.json =
      std::string_view(reinterpret_cast<const char*>(start + kFrameHeaderBytes), header.json_bytes);
  next.frame.payload =
      std::span<const std::uint8_t>(start + kFrameHeaderBytes + header.json_bytes, header.payload_bytes);
  consumed_ += kFrameHeaderBytes + header.body_bytes();
  return next;
}

}  // namespace mtlod::protocol
