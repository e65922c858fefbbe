// Rewrites an MT image's checksums as a writer would, so that a deliberate change to its arrays
// reaches the content checks behind them (tests/core/mt_format_test.cpp, the mt_format fuzz target).
#pragma once

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <span>
#include <vector>

#include "core/model/mt_format.hpp"

namespace mtlod::test {

// Version 1: the checksum over the whole image. Version 2: each block's checksum and the header's,
// from the counts the header states; the header's other fields (bounds, reserved bytes) stay the
// image's. False, leaving the image as it was, when it is neither or its counts do not fit it.
inline bool reseal_mt_image(std::vector<std::uint8_t>& bytes) {
  constexpr std::size_t kChecksumOffset = 48;
  auto word = [&](std::size_t at) {
    std::uint32_t x;
    std::memcpy(&x, bytes.data() + at, 4);
    return x;
  };
  if (bytes.size() >= core::model::kMtHeaderBytesV1 && word(8) == 1) {
    std::memset(bytes.data() + kChecksumOffset, 0, 8);
    const std::uint64_t sum = core::model::mt_checksum(bytes);
    std::memcpy(bytes.data() + kChecksumOffset, &sum, 8);
    return true;
  }
  if (bytes.size() < core::model::kMtHeaderBytes || word(8) != 2) return false;
  auto counts = core::model::mt_header_counts(bytes);
  if (!counts.ok()) return false;
  const std::size_t table = core::model::mt_layout(*counts).block_table;
  auto seal = core::model::seal_mt(*counts, [&](std::uint64_t offset, std::span<std::uint8_t> out) -> Status {
    // seal_mt checks the block table's order before it reads by it: never outside the image.
    if (offset > bytes.size() || out.size() > bytes.size() - offset) std::abort();
    std::memcpy(out.data(), bytes.data() + offset, out.size());
    return Ok{};
  });
  if (!seal.ok()) return false;
  std::memcpy(bytes.data() + table, seal->block_table.data(), seal->block_table.size());
  // The header checksum covers the header as the image has it, then the block table.
  std::memset(bytes.data() + kChecksumOffset, 0, 8);
  std::uint64_t sum =
      core::model::mt_checksum(std::span<const std::uint8_t>(bytes.data(), core::model::kMtHeaderBytes));
  sum = core::model::mt_checksum(
      std::span<const std::uint8_t>(bytes.data() + table, seal->block_table.size()), sum);
  std::memcpy(bytes.data() + kChecksumOffset, &sum, 8);
  return true;
}

}  // namespace mtlod::test
