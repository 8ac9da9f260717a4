// Counts heap allocations: the test binary that links allocation_counter.cpp
// replaces the global operator new with one that counts.
#pragma once

namespace blockstep::test {

long allocationCount();

}  // namespace blockstep::test
