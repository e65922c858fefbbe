// Frame coding: headers round-trip, limits are enforced before any body is read, and a stream
// split at every byte boundary yields the same frames.
#include "protocol/frame.hpp"

#include <gtest/gtest.h>

#include <string>

namespace mtlod::protocol {
namespace {

TEST(FrameHeader, IsLittleEndianJsonLengthThenPayloadLength) {
  const auto bytes = encode_frame_header({0x01020304, 0x0A0B0C0D});
  const std::array<std::uint8_t, 8> expected{0x04, 0x03, 0x02, 0x01, 0x0D, 0x0C, 0x0B, 0x0A};
  EXPECT_EQ(bytes, expected);
  auto decoded = decode_frame_header(bytes, 1u << 30);
  ASSERT_TRUE(decoded.ok());
  EXPECT_EQ(decoded->json_bytes, 0x01020304u);
  EXPECT_EQ(decoded->payload_bytes, 0x0A0B0C0Du);
}

TEST(FrameHeader, RejectsBodiesOverTheLimitAndEmptyJson) {
  const auto big = encode_frame_header({1000, 25});
  EXPECT_TRUE(decode_frame_header(big, 1025).ok());
  auto over = decode_frame_header(big, 1024);
  ASSERT_FALSE(over.ok());
  EXPECT_EQ(over.error().code, ErrorCode::kLimitExceeded);
  EXPECT_NE(over.error().message.find("1025"), std::string::npos);
  // The largest header a peer can send must not overflow the sum.
  EXPECT_FALSE(decode_frame_header(encode_frame_header({UINT32_MAX, UINT32_MAX}), 1u << 20).ok());
  EXPECT_FALSE(decode_frame_header(encode_frame_header({0, 10}), 1u << 20).ok());
}

TEST(FrameReader, SplitsAStreamFedOneByteAtATime) {
  std::vector<std::uint8_t> stream;
  const std::vector<std::uint8_t> payload{1, 2, 3, 0, 255};
  append_frame(R"({"type":"ping","id":1})", {}, stream);
  append_frame(R"({"type":"mesh","id":2})", payload, stream);
  append_frame(R"({"type":"pong","id":3})", {}, stream);
  FrameReader reader(1 << 20);
  std::vector<std::string> jsons;
  std::vector<std::vector<std::uint8_t>> payloads;
  for (std::uint8_t byte : stream) {
    reader.feed({&byte, 1});
    auto next = reader.next();
    ASSERT_TRUE(next.ok());
    if (next->has_frame) {
      jsons.emplace_back(next->frame.json);
      payloads.emplace_back(next->frame.payload.begin(), next->frame.payload.end());
    }
  }
  ASSERT_EQ(jsons.size(), 3u);
  EXPECT_EQ(jsons[1], R"({"type":"mesh","id":2})");
  EXPECT_EQ(payloads[1], payload);
  EXPECT_TRUE(payloads[2].empty());
}

TEST(FrameReader, ReportsAnOversizedFrameAsAnError) {
  std::vector<std::uint8_t> stream;
  append_frame(std::string(100, 'x'), {}, stream);
  FrameReader reader(99);
  reader.feed(stream);
  EXPECT_FALSE(reader.next().ok());
}

}  // namespace
}  // namespace mtlod::protocol
