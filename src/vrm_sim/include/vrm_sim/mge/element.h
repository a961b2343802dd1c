#pragma once
// Multigraph element (MGE), thesis §3.2 Def. 3.2: a scene is a triple (V, E, L) with E ⊆ V×V×L, labels
// L = ℤ\{0} and reference label r(x) = −x. Nodes *and* their relations (springs, triangles, transforms) are all MGEs;
// typing and attributes come from subclassing Element.
//
// Adjacency representation (a deliberate deviation from the thesis' per-element std::map label → vector, §3.3):
// all neighbours of one element live in ONE flat array, split into per-label ranges with spare capacity, plus a tiny
// table of (label, begin, count, capacity). Table and neighbour array share ONE heap block
// ([header][label table][neighbour pointers]), so navigating from an element touches the element and one block.
// An element has only a handful of labels, so a linear scan of that table beats a map. A full range grows in place if
// it is the last one, otherwise it moves to the end of the array (amortised O(1) append even for hub elements such as
// a tissue with 10^6 nodes); the holes left behind are reclaimed when they exceed half the array. Range entries are
// never erased (an emptied range keeps count 0), so a ListAccess binds to a range index once.
// Graph::shrinkToFit() packs the blocks of all elements, exact size and in element order, into one contiguous arena,
// so a sweep over the elements reads their adjacency sequentially (like a CSR array); an element whose list grows
// later moves its block back to the heap.

#include <cstddef>
#include <cstdint>
#include <new>
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
  virtual ~Element() { releaseBlock(); }

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

 protected:
  Element() : holes_(0), block_in_arena_(0) {}

 private:
  friend class Graph;
  template <typename T>
  friend class ListAccess;

  struct LabelRange {
    Label label;
    std::uint32_t begin;  // index into the block's neighbour array
    std::uint32_t count;
    std::uint32_t capacity;
  };

  // Header of the element's adjacency block: [Block][LabelRange × range_capacity][Element* × capacity].
  struct Block {
    std::uint32_t range_count;
    std::uint32_t range_capacity;
    std::uint32_t size;      // neighbour entries in use: the ranges' capacities plus holes
    std::uint32_t capacity;  // neighbour entries allocated

    LabelRange* ranges() { return reinterpret_cast<LabelRange*>(this + 1); }
    const LabelRange* ranges() const { return reinterpret_cast<const LabelRange*>(this + 1); }
    Element** neighbours() { return reinterpret_cast<Element**>(ranges() + range_capacity); }
    Element* const* neighbours() const { return reinterpret_cast<Element* const*>(ranges() + range_capacity); }
    static std::size_t bytes(std::size_t range_capacity, std::size_t capacity) {
      return sizeof(Block) + range_capacity * sizeof(LabelRange) + capacity * sizeof(Element*);
    }
  };
  static_assert(sizeof(Block) % alignof(Element*) == 0 && sizeof(LabelRange) % alignof(Element*) == 0,
                "neighbour pointers must be aligned inside the adjacency block");

  static constexpr std::uint32_t kNoRange = 0xffffffffu;

  std::uint32_t rangeCount() const { return block_ == nullptr ? 0 : block_->range_count; }
  const LabelRange& range(std::uint32_t index) const { return block_->ranges()[index]; }
  Element* const* rangeData(std::uint32_t index) const { return block_->neighbours() + block_->ranges()[index].begin; }

  std::uint32_t findRange(Label label) const {
    if (block_ == nullptr) return kNoRange;
    const LabelRange* ranges = block_->ranges();
    const std::uint32_t count = block_->range_count;
    for (std::uint32_t r = 0; r < count; ++r) {
      if (ranges[r].label == label) return r;
    }
    return kNoRange;
  }
  std::uint32_t findOrAddRange(Label label);
  void insertNeighbour(std::uint32_t range, std::size_t position, Element* neighbour);
  void growRange(std::uint32_t range);
  // Copies the adjacency into a new heap block with room for `range_capacity` labels and `capacity` entries, layout
  // unchanged (holes kept).
  void reallocateBlock(std::uint32_t range_capacity, std::uint32_t capacity);
  // Packs the ranges in order without holes into a new block; each range keeps its spare capacity.
  void compactRanges();
  // Bytes of the block with every range packed without spare capacity (0 without block).
  std::size_t tightBlockBytes() const;
  // Writes the tight block into `memory` (tightBlockBytes() bytes, owned by the graph's arena) and adopts it.
  void moveBlockToArena(void* memory);
  void adoptBlock(Block* block, bool in_arena);
  void releaseBlock() {
    if (block_ != nullptr && !block_in_arena_) ::operator delete(block_);
    block_ = nullptr;
  }
  // Removes the first occurrence of `neighbour` in the range; false if it is not there.
  bool removeNeighbour(std::uint32_t range, Element* neighbour);

  Block* block_ = nullptr;         // label table and neighbour lists; null until the first label is used
  std::uint64_t id_ = 0;
  std::uint32_t graph_index_ = 0;  // position in Graph::elements_, for O(1) unregistration
  std::uint32_t holes_ : 31;       // neighbour entries owned by no range (left behind by moved ranges)
  std::uint32_t block_in_arena_ : 1;  // block_ lies in the graph's arena (not freed by the element)
};

}  // namespace mge
}  // namespace vrm_sim
