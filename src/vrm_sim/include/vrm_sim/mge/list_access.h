#pragma once
// ListAccess<T>, thesis §3.3.1 (idea by J. Grimm): a view on ONE adjacency list Γ(v, l), bound at construction.
// Binding resolves the label once, so later accesses are O(1) (the thesis' motivation: no per-access label search),
// and the element type T replaces the casts from the MGE base class at every call site.
//
// The view stays valid while the element lives, also across insertions and removals of edges (it stores the range
// index, which never changes, not a pointer into the adjacency block). Iterators are invalidated by edge changes on the same
// element, like std::vector iterators.

#include <cassert>
#include <cstddef>
#include <cstdint>
#include <iterator>

#include "vrm_sim/mge/element.h"

namespace vrm_sim {
namespace mge {

template <typename T>
class ListAccess {
 public:
  class Iterator {
   public:
    using iterator_category = std::random_access_iterator_tag;
    using value_type = T*;
    using difference_type = std::ptrdiff_t;
    using pointer = T* const*;
    using reference = T*;

    Iterator() = default;
    explicit Iterator(Element* const* position) : position_(position) {}
    T* operator*() const { return checkedCast(*position_); }
    T* operator[](difference_type offset) const { return checkedCast(position_[offset]); }
    Iterator& operator++() {
      ++position_;
      return *this;
    }
    Iterator operator++(int) { return Iterator(position_++); }
    Iterator& operator--() {
      --position_;
      return *this;
    }
    Iterator& operator+=(difference_type offset) {
      position_ += offset;
      return *this;
    }
    Iterator operator+(difference_type offset) const { return Iterator(position_ + offset); }
    Iterator operator-(difference_type offset) const { return Iterator(position_ - offset); }
    difference_type operator-(const Iterator& other) const { return position_ - other.position_; }
    bool operator==(const Iterator& other) const { return position_ == other.position_; }
    bool operator!=(const Iterator& other) const { return position_ != other.position_; }
    bool operator<(const Iterator& other) const { return position_ < other.position_; }

   private:
    Element* const* position_ = nullptr;
  };

  // Binds to Γ(element, label). If the element has no such list yet an empty one is created (graph unchanged), so
  // the view sees neighbours inserted later.
  ListAccess(Element& element, Label label) : element_(&element), range_(element.findRange(label)) {
    if (range_ == Element::kNoRange) range_ = element.findOrAddRange(label);  // rare: keep the common path inline
  }

  std::size_t size() const { return element_->range(range_).count; }
  bool empty() const { return size() == 0; }
  T* operator[](std::size_t index) const {
    assert(index < size());
    return checkedCast(element_->rangeData(range_)[index]);
  }
  T* front() const { return (*this)[0]; }
  T* back() const { return (*this)[size() - 1]; }
  Iterator begin() const { return Iterator(first()); }
  Iterator end() const {
    // One read of the range entry for both the start and the length.
    const Element::LabelRange& range = element_->range(range_);
    return Iterator(element_->block_->neighbours() + range.begin + range.count);
  }
  // Position of the first occurrence of `neighbour`, or size() if absent.
  std::size_t indexOf(const Element* neighbour) const {
    Element* const* list = first();
    const std::size_t count = size();
    for (std::size_t i = 0; i < count; ++i) {
      if (list[i] == neighbour) return i;
    }
    return count;
  }

  Label label() const { return element_->range(range_).label; }
  Element& element() const { return *element_; }

 private:
  Element* const* first() const { return element_->rangeData(range_); }

  static T* checkedCast(Element* element) {
    // Type safety of the thesis' template parameter: a wrong T is a programming error, caught in debug builds.
    assert(element == nullptr || dynamic_cast<T*>(element) != nullptr);
    return static_cast<T*>(element);
  }

  Element* element_;
  std::uint32_t range_;
};

}  // namespace mge
}  // namespace vrm_sim
