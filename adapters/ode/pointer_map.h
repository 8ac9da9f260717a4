// A hash map from ODE handles (pointers) to small records, with open
// addressing and backward-shift deletion. ODE programs create and destroy
// contact joints every step; a node-based std::unordered_map would touch
// the heap for each of them, this map only when it grows.
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace blockstep::ode {

template <class Key, class Value>
class PointerMap {
 public:
  Value* find(Key key) {
    if (slots_.empty()) return nullptr;
    for (std::size_t i = home(key);; i = next(i)) {
      if (!slots_[i].used) return nullptr;
      if (slots_[i].key == key) return &slots_[i].value;
    }
  }
  const Value* find(Key key) const { return const_cast<PointerMap*>(this)->find(key); }

  // The value for key, default-constructed if it was absent. A free slot
  // holds a default value already (erase leaves one behind): the
  // registry's joint records are 488 bytes, and clearing each again here
  // was a fifth of what a contact joint cost.
  Value& operator[](Key key) {
    if (Value* v = find(key)) return *v;
    if ((size_ + 1) * 4 > slots_.size() * 3) grow();
    std::size_t i = home(key);
    while (slots_[i].used)
      i = next(i);
    slots_[i].used = true;
    slots_[i].key = key;
    ++size_;
    return slots_[i].value;
  }

  // The value for key as a default one: a present key's value starts over.
  Value& fresh(Key key) {
    if (Value* v = find(key)) return *v = Value{};
    return (*this)[key];
  }

  bool erase(Key key) {
    if (slots_.empty()) return false;
    std::size_t i = home(key);
    for (;; i = next(i)) {
      if (!slots_[i].used) return false;
      if (slots_[i].key == key) break;
    }
    // Backward shift: move later entries of the probe run into the hole
    // when their home position allows it, so no tombstones accumulate.
    std::size_t hole = i;
    for (std::size_t j = next(i);; j = next(j)) {
      if (!slots_[j].used) break;
      const std::size_t h = home(slots_[j].key);
      const bool movable = hole <= j ? (h <= hole || h > j) : (h <= hole && h > j);
      if (movable) {
        slots_[hole] = std::move(slots_[j]);
        hole = j;
      }
    }
    slots_[hole].used = false;
    slots_[hole].value = Value{};  // a free slot holds a default value
    --size_;
    return true;
  }

  std::size_t size() const { return size_; }

  template <class F>
  void forEach(F&& f) {
    for (Slot& s : slots_) {
      if (s.used) f(s.key, s.value);
    }
  }

  void clear() {
    slots_.clear();
    size_ = 0;
  }

 private:
  struct Slot {
    Key key{};
    Value value{};
    bool used = false;
  };

  std::size_t home(Key key) const {
    // Fibonacci hashing of the pointer bits (allocations are aligned, so
    // the low bits carry little).
    const auto bits = reinterpret_cast<std::uintptr_t>(key);
    return static_cast<std::size_t>((bits * 0x9E3779B97F4A7C15ull) >> 17) & (slots_.size() - 1);
  }
  std::size_t next(std::size_t i) const { return (i + 1) & (slots_.size() - 1); }

  void grow() {
    std::vector<Slot> old = std::move(slots_);
    slots_.clear();
    slots_.resize(old.empty() ? 64 : old.size() * 2);
    size_ = 0;
    for (Slot& s : old) {
      if (s.used) (*this)[s.key] = std::move(s.value);
    }
  }

  std::vector<Slot> slots_;
  std::size_t size_ = 0;
};

}  // namespace blockstep::ode
