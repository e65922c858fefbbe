// libFuzzer target: any bytes given to the MT file parser are rejected cleanly or give a model
// whose every index is in range (the parser's contract, core/FORMAT.md), read whole or viewed in
// place as the server maps files (blocks checked on first use: a refinement either finishes inside
// the arrays or stops with CorruptMt). Each input is parsed as it is, and again with its checksums
// recomputed, so mutations reach the validation behind them instead of all stopping there.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

#include "core/mt_format.hpp"
#include "core/refine.hpp"

namespace {

using namespace mtlod::core;

void walk(const Mt& mt) {
  // Every triangle's corners of an accepted file are vertices.
  std::uint32_t corners[3];
  for (std::uint32_t t = 0; t < mt.triangle_count(); ++t) {
    mt.triangle_vertices(t, corners);
    if (corners[0] >= mt.vertex_count() || corners[1] >= mt.vertex_count() || corners[2] >= mt.vertex_count())
      __builtin_trap();
  }
}

void refine(const Mt& mt) {
  CutMesh out;
  Refiner refiner(mt);
  refiner.refine(AllowedError::everywhere(0.0f), out);
  refiner.refine_budget(AllowedError::everywhere(0.0f), 64, out);
  for (const std::uint32_t v : out.triangles)
    if (v >= mt.vertex_count()) __builtin_trap();
}

void check(std::span<const std::uint8_t> bytes) {
  auto mt = deserialize_mt(bytes);
  if (mt.ok()) walk(*mt);
  // In place, as a mapped file: the copy is aligned as a mapping is.
  const std::vector<std::uint8_t> aligned(bytes.begin(), bytes.end());
  auto view = view_mt(aligned, nullptr);
  if (!view.ok()) return;
  try {
    refine(*view);
  } catch (const CorruptMt&) {
    if (mt.ok()) __builtin_trap();  // a block of a file accepted whole failed its check
  }
}

std::uint32_t word(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  std::uint32_t x;
  std::memcpy(&x, bytes.data() + at, 4);
  return x;
}

// Recomputes the checksums as a writer would: version 1 over the whole file, version 2 the blocks'
// and the header's (from the counts the header states, when the file is as long as they say).
void reseal(std::vector<std::uint8_t>& bytes) {
  constexpr std::size_t kChecksumOffset = 48;
  if (bytes.size() >= kMtHeaderBytesV1 && word(bytes, 8) == 1) {
    std::memset(bytes.data() + kChecksumOffset, 0, 8);
    const std::uint64_t sum = mt_checksum(bytes);
    std::memcpy(bytes.data() + kChecksumOffset, &sum, 8);
    return;
  }
  if (bytes.size() < kMtHeaderBytes || word(bytes, 8) != 2) return;
  auto counts = mt_header_counts(bytes);
  if (!counts.ok()) return;
  const MtCounts c = *counts;
  auto seal = seal_mt(c, [&](std::uint64_t offset, std::span<std::uint8_t> out) -> mtlod::Status {
    if (offset > bytes.size() || out.size() > bytes.size() - offset) __builtin_trap();  // seal_mt's contract
    std::memcpy(out.data(), bytes.data() + offset, out.size());
    return mtlod::Ok{};
  });
  if (!seal.ok()) return;
  // The input's own header fields stay (reserved bytes, bounds): only the checksums are the writer's.
  std::memcpy(bytes.data() + mt_layout(c).block_table, seal->block_table.data(), seal->block_table.size());
  // The header checksum covers the header as the input has it.
  std::memset(bytes.data() + kChecksumOffset, 0, 8);
  std::uint64_t sum = mt_checksum(std::span<const std::uint8_t>(bytes.data(), kMtHeaderBytes));
  sum = mt_checksum(
      std::span<const std::uint8_t>(bytes.data() + mt_layout(c).block_table, seal->block_table.size()), sum);
  std::memcpy(bytes.data() + kChecksumOffset, &sum, 8);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  check(std::span<const std::uint8_t>(data, size));
  std::vector<std::uint8_t> fixed(data, data + size);
  reseal(fixed);
  check(fixed);
  return 0;
}
