// libFuzzer target: any bytes given to the MT file parser are rejected cleanly or give a model
// whose every index is in range (the parser's contract, core/FORMAT.md). Each input is parsed as
// it is, and again with its checksum field recomputed, so mutations reach the validation behind
// the checksum instead of all stopping at it.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

#include "core/mt_format.hpp"

namespace {

void check(std::span<const std::uint8_t> bytes) {
  auto mt = mtlod::core::deserialize_mt(bytes);
  if (mt.ok()) {
    // Touch every triangle: indices must be valid for an accepted file.
    std::uint32_t corners[3];
    std::uint64_t sum = 0;
    for (std::uint32_t t = 0; t < mt->triangle_count(); ++t) {
      mt->triangle_vertices(t, corners);
      sum += corners[0] + corners[1] + corners[2];
      if (corners[0] >= mt->vertex_count() || corners[1] >= mt->vertex_count() ||
          corners[2] >= mt->vertex_count()) {
        __builtin_trap();
      }
    }
    (void)sum;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  check(std::span<const std::uint8_t>(data, size));
  constexpr std::size_t kChecksumOffset = 48, kHeaderBytes = 64;
  if (size >= kHeaderBytes) {
    std::vector<std::uint8_t> fixed(data, data + size);
    std::memset(fixed.data() + kChecksumOffset, 0, 8);
    const std::uint64_t sum = mtlod::core::mt_checksum(fixed);
    for (int i = 0; i < 8; ++i) fixed[kChecksumOffset + i] = static_cast<std::uint8_t>(sum >> (8 * i));
    check(fixed);
  }
  return 0;
}
