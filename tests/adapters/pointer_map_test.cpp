// PointerMap: the registry's hash map from ODE handles to records. A key
// inserted again after its erase, or into a slot an erased entry's
// backward shift freed, must get a default record, never what was there.
#include "adapters/ode/pointer_map.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <random>

namespace blockstep::ode {
namespace {

struct Record {
  int value = -1;
  double data[8] = {};
};

int* handle(std::uintptr_t i) {
  return reinterpret_cast<int*>(0x1000 + 16 * i);
}

TEST(PointerMap, NewKeysGetDefaultRecordsAfterEraseAndShifts) {
  PointerMap<int*, Record> map;
  std::map<std::uintptr_t, int> expected;  // key -> value, what the map must hold
  std::mt19937 random(7);
  for (int round = 0; round < 20000; ++round) {
    const std::uintptr_t key = random() % 300;  // few keys: long probe runs, many reuses
    if (random() % 3 == 0) {
      EXPECT_EQ(map.erase(handle(key)), expected.erase(key) == 1);
      continue;
    }
    const bool restart = random() % 4 == 0;  // fresh(): a present key starts over too
    Record& r = restart ? map.fresh(handle(key)) : map[handle(key)];
    const auto it = expected.find(key);
    if (it == expected.end() || restart) {
      ASSERT_EQ(r.value, -1) << "round " << round;
      for (double d : r.data)
        ASSERT_EQ(d, 0.0) << "round " << round;
    } else {
      ASSERT_EQ(r.value, it->second) << "round " << round;
    }
    r.value = round;
    r.data[round % 8] = 1.0 + round;
    expected[key] = round;
  }
  EXPECT_EQ(map.size(), expected.size());
  for (const auto& [key, value] : expected) {
    const Record* r = map.find(handle(key));
    ASSERT_NE(r, nullptr);
    EXPECT_EQ(r->value, value);
  }
}

}  // namespace
}  // namespace blockstep::ode
