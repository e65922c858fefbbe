// What the server tests ask and read back alike: an extract that frames a model from the front,
// and a WebSocket message read as a reply frame.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "clients/common/server_connection.hpp"
#include "protocol/camera.hpp"
#include "protocol/frame.hpp"
#include "protocol/replies.hpp"

namespace mtlod::test {

// An extract of the model within bounds lo..hi seen whole from its front (4:3), with a W×H grid and
// an error in pixels.
inline protocol::Extract framing_extract(const std::string& name, const std::array<double, 3>& lo,
                                         const std::array<double, 3>& hi, std::array<std::uint32_t, 2> grid,
                                         double error_px) {
  protocol::Extract e;
  e.model = name;
  protocol::look_at_camera(protocol::frame_bounds(lo, hi), 4.0 / 3.0, e.view, e.projection);
  e.grid = grid;
  e.error = error_px;
  e.error_unit = core::view::ErrorUnits::kScreenPixels;
  return e;
}
inline protocol::Extract framing_extract(const std::string& name, const protocol::ModelInfoReply& model,
                                         std::array<std::uint32_t, 2> grid, double error_px) {
  return framing_extract(name, model.bounds_min, model.bounds_max, grid, error_px);
}

// A message the server sent on its WebSocket (PROTOCOL.md, "WebSocket"): a text message is a
// reply's JSON, a binary one a whole frame, header included, and nothing after it.
inline Result<clients::ReplyFrame> reply_from_message(bool text, std::string_view message) {
  clients::ReplyFrame out;
  if (text) {
    out.json = message;
  } else {
    protocol::FrameReader reader(message.size());
    reader.feed(std::span(reinterpret_cast<const std::uint8_t*>(message.data()), message.size()));
    MTLOD_TRY(const protocol::FrameReader::Next next, reader.next());
    const std::size_t framed =
        next.has_frame ? protocol::kFrameHeaderBytes + next.frame.json.size() + next.frame.payload.size() : 0;
    if (framed != message.size()) {
      return make_error(ErrorCode::kCorrupt,
                        "a binary message of " + std::to_string(message.size()) + " bytes is not one frame");
    }
    out.json = next.frame.json;
    out.payload.assign(next.frame.payload.begin(), next.frame.payload.end());
  }
  MTLOD_TRY(out.header, protocol::parse_reply(out.json));
  return out;
}

}  // namespace mtlod::test
