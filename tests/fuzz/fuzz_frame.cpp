// libFuzzer target: a byte stream split into frames never overruns, whatever the headers claim.
#include <cstddef>
#include <cstdint>
#include <span>

#include "protocol/frame.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  mtlod::protocol::FrameReader reader(1 << 16);
  // Feed in two pieces so partial frames are exercised too.
  const std::size_t half = size / 2;
  reader.feed(std::span<const std::uint8_t>(data, half));
  for (int pass = 0; pass < 2; ++pass) {
    for (;;) {
      auto next = reader.next();
      if (!next.ok() || !next->has_frame) break;
      volatile std::size_t touched = next->frame.json.size() + next->frame.payload.size();
      (void)touched;
    }
    if (pass == 0) reader.feed(std::span<const std::uint8_t>(data + half, size - half));
  }
  return 0;
}
