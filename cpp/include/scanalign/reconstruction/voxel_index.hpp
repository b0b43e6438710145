// A hash map from integer voxel coordinates to a point index: lets the reconstruction
// fold each new point into its voxel of the model in O(1) instead of re-gridding the model
// (see FrameToModel::merge).
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

namespace scanalign {

/// Open addressing with linear probing over a power-of-two table, kept at most half full.
/// Keys are voxel coordinates (x, y, z), each in [-2^20, 2^20), packed into 63 bits by
/// pack(); values are 32-bit indices. Each entry also has a scratch word (`mark`, 0 when
/// inserted) that a caller may use to tag entries during one pass and must reset after
/// it. No erase (a model's voxels only appear).
class VoxelIndex {
 public:
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  static constexpr std::int64_t kLimit = std::int64_t{1} << 20;  ///< |coordinate| bound (exclusive above)

  /// Whether voxel coordinates can be packed: each in [-2^20, 2^20).
  static bool packable(std::int64_t x, std::int64_t y, std::int64_t z) {
    return x >= -kLimit && x < kLimit && y >= -kLimit && y < kLimit && z >= -kLimit && z < kLimit;
  }
  /// The key of packable voxel coordinates.
  static std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
    const auto u = [](std::int64_t v) { return static_cast<std::uint64_t>(v + kLimit); };
    return (u(z) << 42) | (u(y) << 21) | u(x);
  }

  void clear() {
    slots_.clear();
    size_ = 0;
  }
  std::size_t size() const { return size_; }

  /// Makes room for `entries` entries: positions stay valid until the size exceeds it.
  void reserve(std::size_t entries) {
    while (2 * entries > slots_.size()) grow();
  }

  /// The value stored under key, or kNone.
  std::uint32_t find(std::uint64_t key) const {
    if (slots_.empty()) return kNone;
    for (std::size_t i = home(key);; i = (i + 1) & mask()) {
      if (slots_[i].key == key) return slots_[i].value;
      if (slots_[i].key == kEmpty) return kNone;
    }
  }

  /// Hints the memory of key's slot into the cache (lookups of scattered voxels are memory
  /// bound: issuing the next ones' loads early overlaps their latencies).
  void prefetch(std::uint64_t key) const {
#if defined(__GNUC__)
    if (!slots_.empty()) __builtin_prefetch(&slots_[home(key)]);
#else
    (void)key;
#endif
  }

  /// The position of key's entry; stores (key, value) first if key is absent and then sets
  /// `inserted`. Positions stay valid until the table grows (see reserve()).
  std::size_t findOrInsert(std::uint64_t key, std::uint32_t value, bool& inserted) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    for (std::size_t i = home(key);; i = (i + 1) & mask()) {
      if (slots_[i].key == key) {
        inserted = false;
        return i;
      }
      if (slots_[i].key == kEmpty) {
        slots_[i] = {key, value, 0};
        ++size_;
        inserted = true;
        return i;
      }
    }
  }
  std::uint32_t value(std::size_t position) const { return slots_[position].value; }
  std::uint32_t& mark(std::size_t position) { return slots_[position].mark; }

 private:
  struct Slot {
    std::uint64_t key;
    std::uint32_t value;
    std::uint32_t mark;
  };
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};  // never a packed key (bit 63)

  std::size_t mask() const { return slots_.size() - 1; }
  std::size_t home(std::uint64_t key) const {
    // Fibonacci hashing (the top bits of key * 2^64 / golden ratio): neighbouring voxels
    // land far apart.
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
  }
  void grow() {
    std::vector<Slot> old = std::move(slots_);
    slots_.assign(old.empty() ? 1024 : 2 * old.size(), Slot{kEmpty, kNone, 0});
    shift_ = 64;
    for (std::size_t n = slots_.size(); n > 1; n >>= 1) --shift_;
    size_ = 0;
    for (const Slot& s : old)
      if (s.key != kEmpty) {
        bool inserted;
        slots_[findOrInsert(s.key, s.value, inserted)].mark = s.mark;
      }
  }

  std::vector<Slot> slots_;
  std::size_t size_ = 0;
  int shift_ = 64;  // 64 - log2(table size)
};

}  // namespace scanalign
