// An indexed binary heap of small integer ids (vertex ids, triangle slots), shared by the two
// stages of the thinning (greedy.cpp, thinning.cpp).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace tinstream::lod::detail {

// Binary min-heap of ids ordered by (key, id), with positions so that a key changes in place: the
// heap never holds more than one entry per id (no stale entries to skip).
class IndexedHeap {
 public:
  explicit IndexedHeap(std::size_t ids) : pos_(ids, kAbsent), key_(ids, 0.0) {}
  // Makes room for ids < `ids` (never shrinks; at least doubles, so that growing by one id at a
  // time is amortised).
  void grow(std::size_t ids) {
    if (ids <= pos_.size()) return;
    ids = std::max(ids, 2 * pos_.size());
    pos_.resize(ids, kAbsent), key_.resize(ids, 0.0);
  }
  std::size_t size() const { return heap_.size(); }
  bool empty() const { return heap_.empty(); }
  std::uint32_t top() const { return heap_.front(); }
  double key(std::uint32_t id) const { return key_[id]; }
  void set(std::uint32_t id, double key) {
    if (pos_[id] == kAbsent) {
      key_[id] = key;
      pos_[id] = static_cast<std::uint32_t>(heap_.size());
      heap_.push_back(id);
      up(pos_[id]);
      return;
    }
    const double old = key_[id];
    key_[id] = key;
    if (key < old) {
      up(pos_[id]);
    } else {
      down(pos_[id]);
    }
  }
  void erase(std::uint32_t id) {
    const std::uint32_t i = pos_[id];
    if (i == kAbsent) return;
    const std::uint32_t last = heap_.back();
    heap_.pop_back();
    pos_[id] = kAbsent;
    if (i == heap_.size()) return;
    heap_[i] = last;
    pos_[last] = i;
    up(i);
    down(pos_[last]);
  }
  void pop() { erase(heap_.front()); }

 private:
  static constexpr std::uint32_t kAbsent = 0xFFFFFFFFu;
  bool less(std::uint32_t a, std::uint32_t b) const {
    return key_[a] < key_[b] || (key_[a] == key_[b] && a < b);
  }
  void place(std::uint32_t i, std::uint32_t id) {
    heap_[i] = id;
    pos_[id] = i;
  }
  void up(std::uint32_t i) {
    const std::uint32_t id = heap_[i];
    while (i > 0) {
      const std::uint32_t parent = (i - 1) / 2;
      if (!less(id, heap_[parent])) break;
      place(i, heap_[parent]);
      i = parent;
    }
    place(i, id);
  }
  void down(std::uint32_t i) {
    const std::uint32_t id = heap_[i];
    const auto n = static_cast<std::uint32_t>(heap_.size());
    for (;;) {
      std::uint32_t c = 2 * i + 1;
      if (c >= n) break;
      if (c + 1 < n && less(heap_[c + 1], heap_[c])) ++c;
      if (!less(heap_[c], id)) break;
      place(i, heap_[c]);
      i = c;
    }
    place(i, id);
  }
  std::vector<std::uint32_t> heap_;
  std::vector<std::uint32_t> pos_;  // by id
  std::vector<double> key_;         // by id
};

}  // namespace tinstream::lod::detail
