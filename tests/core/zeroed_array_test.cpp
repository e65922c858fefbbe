// ZeroedArray: zeros without writing them, and only the pages written count as resident, so a
// session's per-node and per-vertex state costs what its cut touches.
#include "core/zeroed_array.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>

namespace mtlod::core {
namespace {

TEST(ZeroedArray, ReadsZeroAndOnlyWrittenPagesAreResident) {
  const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  constexpr std::size_t kCount = std::size_t{64} << 20;  // 256 MiB of floats
  ZeroedArray<float> a(kCount);
  ASSERT_EQ(a.size(), kCount);
  EXPECT_EQ(a.resident_bytes(), 0u);
  // One write per MiB: 256 pages.
  const std::size_t stride = (std::size_t{1} << 20) / sizeof(float);
  for (std::size_t i = 0; i < kCount; i += stride) a[i] = 1.0f;
  EXPECT_EQ(a.resident_bytes(), (kCount / stride) * page);
  EXPECT_EQ(a[1], 0.0f);
  EXPECT_EQ(a[stride], 1.0f);
  // A reset gives fresh zeros and the pages back.
  a.reset(kCount);
  EXPECT_EQ(a[stride], 0.0f);
  EXPECT_LE(a.resident_bytes(), page);  // the page just read may map the shared zero page
  ZeroedArray<std::uint64_t> moved(16);
  moved[3] = 7;
  ZeroedArray<std::uint64_t> to = std::move(moved);
  EXPECT_EQ(to[3], 7u);
  EXPECT_TRUE(moved.empty());
}

}  // namespace
}  // namespace mtlod::core
