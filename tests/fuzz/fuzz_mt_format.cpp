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
#include "tests/core/mt_reseal.hpp"

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

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  check(std::span<const std::uint8_t>(data, size));
  std::vector<std::uint8_t> fixed(data, data + size);
  mtlod::test::reseal_mt_image(fixed);  // when it is an MT image at all
  check(fixed);
  return 0;
}
