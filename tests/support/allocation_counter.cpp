// The replaced global operator new (and its deletes) behind
// allocationCount(). Linked only into the allocation test binaries.
#include "allocation_counter.h"

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
std::atomic<long> allocations{0};
}

void* operator new(std::size_t n) {
  ++allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace blockstep::test {

long allocationCount() {
  return allocations.load();
}

}  // namespace blockstep::test
