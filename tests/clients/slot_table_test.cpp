// SlotTable (clients/common/slot_table.hpp) against std::unordered_map over random inserts, lookups and
// erasures, growth included: every key present maps to its value, every other key is absent.
#include "clients/common/slot_table.hpp"

#include <gtest/gtest.h>

#include <random>
#include <unordered_map>
#include <vector>

namespace mtlod::clients {
namespace {

TEST(SlotTable, AgreesWithAHashMapUnderRandomEdits) {
  std::mt19937 rng(17);
  // Keys from a small range collide often; from the whole range they spread.
  for (const std::uint32_t range : {200u, 4'000'000'000u}) {
    std::uniform_int_distribution<std::uint32_t> key(0, range);
    SlotTable table;
    table.reset(4);  // grows many times below
    std::unordered_map<std::uint32_t, std::uint32_t> reference;
    for (int step = 0; step < 20'000; ++step) {
      const std::uint32_t k = key(rng);
      const std::size_t at = table.find(k);
      ASSERT_EQ(at != SlotTable::kAbsent, reference.count(k) == 1) << "step " << step;
      if (at == SlotTable::kAbsent) {
        if (step % 2 == 0) {
          table.insert(k, static_cast<std::uint32_t>(step));
        } else {
          ASSERT_TRUE(table.try_insert(k, static_cast<std::uint32_t>(step)));
        }
        ASSERT_FALSE(table.try_insert(k, 99));  // present now: left as it is
        reference[k] = static_cast<std::uint32_t>(step);
      } else if (step % 3 == 0) {
        ASSERT_EQ(table.value_at(at), reference[k]);
        table.assign(k, 7);
        reference[k] = 7;
      } else {
        ASSERT_EQ(at, table.position(k));
        table.erase_at(at);
        reference.erase(k);
      }
      ASSERT_EQ(table.size(), reference.size());
    }
    for (const auto& [k, v] : reference) {
      ASSERT_NE(table.find(k), SlotTable::kAbsent);
      EXPECT_EQ(table.value_at(table.find(k)), v);
    }
  }
  EXPECT_EQ(SlotTable().find(3), SlotTable::kAbsent);  // never sized
  EXPECT_EQ(SlotTable().find(SlotTable::kEmpty), SlotTable::kAbsent);
}

}  // namespace
}  // namespace mtlod::clients
