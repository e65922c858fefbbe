// ZeroedArray: zeros without writing them, and only the pages written count as resident, so a
// session's per-node and per-vertex state costs what its cut touches.
#include "core/util/zeroed_array.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>

namespace mtlod::core {
namespace {

TEST(ZeroedArray, ReadsZeroAndOnlyWrittenPagesAreResident) {
  const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  constexpr std::size_t kCount = std::size_t{64} << 20;  // 256 MiB of floats
  util::ZeroedArray<float> a(kCount);
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
  util::ZeroedArray<std::uint64_t> moved(16);
  moved[3] = 7;
  util::ZeroedArray<std::uint64_t> to = std::move(moved);
  EXPECT_EQ(to[3], 7u);
  EXPECT_TRUE(moved.empty());
}

TEST(PagedArray, ReadsOfPagesNeverWrittenTouchNothing) {
  const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  if (page != 4096) GTEST_SKIP() << "pages of " << page << " bytes";
  constexpr std::size_t kCount = std::size_t{64} << 20;  // 64 MiB of bytes
  util::PagedArray<std::uint8_t> a(kCount);
  ASSERT_EQ(a.size(), kCount);
  const std::size_t bitmap = a.resident_bytes();  // the bitmap alone
  EXPECT_LT(bitmap, std::size_t{4096});
  // Reads everywhere: zeros, and not a page of the values mapped.
  std::size_t sum = 0;
  for (std::size_t i = 7; i < kCount; i += 4099) sum += a[i];
  EXPECT_EQ(sum, 0u);
  EXPECT_EQ(a.resident_bytes(), bitmap);
  // Writes make their pages resident and readable; their neighbours on the page read as written.
  a.set(5 * 4096 + 17, 3);
  a.set(kCount - 1, 9);
  EXPECT_EQ(a[5 * 4096 + 17], 3);
  EXPECT_EQ(a[5 * 4096 + 18], 0);
  EXPECT_EQ(a[kCount - 1], 9);
  EXPECT_EQ(a[6 * 4096], 0);
  EXPECT_EQ(a.resident_bytes(), bitmap + 2 * page);
  // A prefix, across a page boundary.
  a.fill_prefix(4096 + 10, 1);
  EXPECT_EQ(a[0], 1);
  EXPECT_EQ(a[4096 + 9], 1);
  EXPECT_EQ(a[4096 + 10], 0);
  EXPECT_EQ(a.resident_bytes(), bitmap + 4 * page);
}

}  // namespace
}  // namespace mtlod::core
