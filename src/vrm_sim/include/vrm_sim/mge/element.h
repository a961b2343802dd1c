#pragma once
// Multigraph element (MGE), thesis §3.2 Def. 3.2: a scene is a triple (V, E, L) with E ⊆ V×V×L, labels
// L = ℤ\{0} and reference label r(x) = −x. Nodes *and* their relations (springs, triangles, transforms) are all MGEs;
// typing and attributes come from subclassing Element.
//
// Adjacency representation (a deliberate deviation from the thesis' per-element std::map label → vector, §3.3):
// all neighbours of one element live in ONE flat vector, split into per-label ranges with spare capacity, plus a tiny
// table of (label, begin, count, capacity). An element has only a handful of labels, so a linear scan of that table
// beats a map, and two heap blocks per element (instead of a map node + one vector per label) keep navigation
// cache-friendly. A full range grows in place if it is the last one, otherwise it moves to the end of the vector
// (amortised O(1) append even for hub elements such as a tissue with 10^6 nodes); the holes left behind are
// reclaimed when they exceed half the vector. Range entries are never erased (an emptied range keeps count 0), so a
// ListAccess binds to a range index once.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace vrm_sim {
namespace mge {

// Edge label; 0 is not a label (thesis §3.2: an unlabelled "default" relation broke combinability of algorithms).
using Label = int;

constexpr Label referenceLabel(Label label) { return -label; }

class Graph;
class PoolBase;
template <typename T>
class ListAccess;

class Element {
 public:
  Element(const Element&) = delete;
  Element& operator=(const Element&) = delete;
  virtual ~Element() = default;

  // Unique within its graph, never reused; useful for debugging and reference models in tests.
  std::uint64_t id() const { return id_; }

  // Number of l-neighbours |Γ(v, l)|; 0 for a label the element has never seen.
  std::size_t neighbourCount(Label label) const;
  // The i-th l-neighbour (untyped). Typed, O(1)-bound access is ListAccess<T>.
  Element* neighbour(Label label, std::size_t index) const;
  // Copy of Γ(v, l) in order (convenience for tests and tools; algorithms use ListAccess).
  std::vector<Element*> neighbours(Label label) const;
  // Labels with a non-empty neighbour list, in the order they were first used.
  std::vector<Label> labels() const;
  // Total number of outgoing edges over all labels.
  std::size_t degree() const;
  // Releases spare capacity of all label ranges (e.g. after building a large graph).
  void shrinkAdjacency();

 protected:
  Element() = default;

 private:
  friend class Graph;
  template <typename T>
  friend class ListAccess;

  struct LabelRange {
    Label label;
    std::uint32_t begin;
    std::uint32_t count;
    std::uint32_t capacity;
  };

  static constexpr std::uint32_t kNoRange = 0xffffffffu;

  std::uint32_t findRange(Label label) const {
    for (std::uint32_t r = 0; r < ranges_.size(); ++r) {
      if (ranges_[r].label == label) return r;
    }
    return kNoRange;
  }
  std::uint32_t findOrAddRange(Label label);
  void insertNeighbour(std::uint32_t range, std::size_t position, Element* neighbour);
  void growRange(std::uint32_t range);
  void compactRanges(bool tight);
  // Removes the first occurrence of `neighbour` in the range; false if it is not there.
  bool removeNeighbour(std::uint32_t range, Element* neighbour);

  std::vector<LabelRange> ranges_;    // in order of first use; [begin, begin + capacity) in neighbours_
  std::vector<Element*> neighbours_;  // all labels' neighbour lists (+ spare capacity and holes)
  std::uint64_t id_ = 0;
  PoolBase* pool_ = nullptr;       // the pool that owns this element's storage
  std::uint32_t graph_index_ = 0;  // position in Graph::elements_, for O(1) unregistration
  std::uint32_t holes_ = 0;        // neighbours_ entries owned by no range (left behind by moved ranges)
};

}  // namespace mge
}  // namespace vrm_sim
