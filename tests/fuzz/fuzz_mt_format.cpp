// libFuzzer target: any bytes given to the MT file parser are rejected cleanly or give a model
// whose every index is in range (the parser's contract, core/model/FORMAT.md), read whole or viewed in
// place as the server maps files (blocks checked on first use: a refinement either finishes inside
// the arrays or fails, kCorrupt). Each input is parsed as it is, and again with its checksums
// recomputed, so mutations reach the validation behind them instead of all stopping there.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

#include "core/cut/refine.hpp"
#include "core/model/mt_format.hpp"
#include "tests/core/mt_reseal.hpp"

namespace {

using namespace mtlod::core;
using mtlod::Status;

void walk(const model::Mt& mt) {
  // Every triangle's corners of an accepted file are vertices.
  std::uint32_t corners[3];
  for (std::uint32_t t = 0; t < mt.triangle_count(); ++t) {
    mt.triangle_vertices(t, corners);
    if (corners[0] >= mt.vertex_count() || corners[1] >= mt.vertex_count() || corners[2] >= mt.vertex_count())
      __builtin_trap();
  }
}

// Whether both refinements succeeded; one that reaches a block failing its check fails.
bool refine(const model::Mt& mt) {
  cut::CutMesh out;
  cut::Refiner refiner(mt);
  bool all = true;
  auto check = [&](const Status& refined) {
    if (!refined) {
      all = false;
      return;
    }
    for (const std::uint32_t v : out.triangles)
      if (v >= mt.vertex_count()) __builtin_trap();
  };
  check(refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)), out));
  check(refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(64), out));
  return all;
}

void check(std::span<const std::uint8_t> bytes) {
  auto mt = model::deserialize_mt(bytes);
  if (mt.ok()) walk(*mt);
  // In place, as a mapped file: the copy is aligned as a mapping is.
  const std::vector<std::uint8_t> aligned(bytes.begin(), bytes.end());
  auto view = model::view_mt(aligned, nullptr);
  if (!view.ok()) return;
  if (!refine(*view) && mt.ok()) __builtin_trap();  // a block of a file accepted whole failed its check
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  check(std::span<const std::uint8_t>(data, size));
  std::vector<std::uint8_t> fixed(data, data + size);
  mtlod::test::reseal_mt_image(fixed);  // when it is an MT image at all
  check(fixed);
  return 0;
}
