#pragma once
// The MGE graph: owns all elements (pooled, stable addresses) and is the only place where edges change, so that the
// reference-edge rule of thesis §3.2 Def. 3.2 (every (v1, v2, l) has its (v2, v1, −l)) holds by construction.
//
// Storage: one chunked pool per element type. Elements of a type created together lie together in memory, which
// limits the fragmentation the thesis names as the first problem of a pointer-based MGE (§3.3); freed slots are
// reused, addresses never move (ListAccess and neighbour pointers stay valid until the element itself is destroyed).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <typeindex>
#include <unordered_map>
#include <utility>
#include <vector>

#include "vrm_sim/mge/element.h"

namespace vrm_sim {
namespace mge {

class PoolBase {
 public:
  virtual ~PoolBase() = default;
  virtual void destroy(Element* element) = 0;
  virtual std::size_t liveCount() const = 0;
};

// Fixed-size-slot pool for one element type. Chunks grow geometrically (small graphs stay small) and are never moved.
template <typename T>
class Pool final : public PoolBase {
 public:
  Pool() = default;
  Pool(const Pool&) = delete;
  Pool& operator=(const Pool&) = delete;
  // Elements still alive are destroyed by their Graph before the pools go away.
  ~Pool() override = default;

  template <typename... Args>
  T* create(Args&&... args) {
    Slot* slot = acquireSlot();
    try {
      T* element = new (slot->bytes) T(std::forward<Args>(args)...);
      ++live_count_;
      return element;
    } catch (...) {
      free_slots_.push_back(slot);
      throw;
    }
  }

  void destroy(Element* element) override {
    T* typed = static_cast<T*>(element);
    typed->~T();
    free_slots_.push_back(reinterpret_cast<Slot*>(typed));
    --live_count_;
  }

  std::size_t liveCount() const override { return live_count_; }

 private:
  struct alignas(T) Slot {
    unsigned char bytes[sizeof(T)];
  };

  Slot* acquireSlot() {
    if (!free_slots_.empty()) {
      Slot* slot = free_slots_.back();
      free_slots_.pop_back();
      return slot;
    }
    if (chunks_.empty() || used_in_last_chunk_ == last_chunk_size_) {
      last_chunk_size_ = chunks_.empty() ? kFirstChunkSize : std::min(last_chunk_size_ * 2, kMaxChunkSize);
      chunks_.emplace_back(new Slot[last_chunk_size_]);
      used_in_last_chunk_ = 0;
    }
    return &chunks_.back()[used_in_last_chunk_++];
  }

  static constexpr std::size_t kFirstChunkSize = 16;
  static constexpr std::size_t kMaxChunkSize = 16384;

  std::vector<std::unique_ptr<Slot[]>> chunks_;
  std::size_t last_chunk_size_ = 0;
  std::size_t used_in_last_chunk_ = 0;
  std::vector<Slot*> free_slots_;
  std::size_t live_count_ = 0;
};

// Result of a structural self-check; tests assert on ok() and print summary().
struct InvariantReport {
  std::vector<std::string> errors;
  bool ok() const { return errors.empty(); }
  std::string summary() const;
};

class Graph {
 public:
  Graph() = default;
  Graph(const Graph&) = delete;
  Graph& operator=(const Graph&) = delete;
  ~Graph();

  // Creates an element of type T (a subclass of Element) owned by this graph.
  template <typename T, typename... Args>
  T& create(Args&&... args) {
    static_assert(std::is_base_of<Element, T>::value, "MGE elements derive from vrm_sim::mge::Element");
    Pool<T>& pool = poolFor<T>();
    T* element = pool.create(std::forward<Args>(args)...);
    registerElement(*element, pool);
    return *element;
  }

  // As create(), but with a given id instead of the next one: restoring a snapshot (a checkpoint) needs the elements'
  // ids back, since removal orders and id-keyed bookkeeping follow them. The caller guarantees that no live element
  // has that id; setNextId() then keeps later ids above it.
  template <typename T, typename... Args>
  T& createWithId(std::uint64_t id, Args&&... args) {
    static_assert(std::is_base_of<Element, T>::value, "MGE elements derive from vrm_sim::mge::Element");
    if (id == 0) throw std::invalid_argument("MGE element id 0 is not an id");
    Pool<T>& pool = poolFor<T>();
    T* element = pool.create(std::forward<Args>(args)...);
    registerElement(*element, pool, id);
    return *element;
  }
  // The id the next create() gives.
  std::uint64_t nextId() const { return next_id_; }
  // Throws std::invalid_argument unless `next_id` is above the id of every live element.
  void setNextId(std::uint64_t next_id);

  // Removes every edge of `element` (and the matching reference edges in its neighbours), then destroys it.
  // Cost O(Σ over its neighbours of their list length for the reference label) — small, except for hub elements.
  void destroy(Element& element);
  // Destroys all elements without edge maintenance.
  void clear();
  // Drops spare adjacency capacity of every element (after bulk construction) and packs all adjacency blocks into one
  // contiguous arena in element order.
  void shrinkToFit();

  // Inserts (from, to, label) at the end of Γ(from, label) and its reference edge (to, from, −label) at the end of
  // Γ(to, −label). Parallel edges are allowed (it is a multigraph); self loops too. Throws std::invalid_argument for
  // label 0 or an element that is not in this graph.
  void insertEdge(Element& from, Element& to, Label label);
  // As insertEdge, but `to` is placed at `position` in Γ(from, label) (0 = front; size() = end), keeping the order
  // the thesis needs for triangle vertices and scene-graph traversal. Throws std::out_of_range if position > size.
  void insertEdgeAt(Element& from, std::size_t position, Element& to, Label label);
  // Removes the first occurrence of (from, to, label) and one matching reference edge. False if there is none.
  bool removeEdge(Element& from, Element& to, Label label);

  bool contains(const Element& element) const {
    return element.graph_index_ < elements_.size() && elements_[element.graph_index_] == &element;
  }
  std::size_t size() const { return elements_.size(); }
  // All live elements (order unspecified: destruction moves the last entry into the hole).
  const std::vector<Element*>& elements() const { return elements_; }
  // Number of edges, each edge counted once together with its reference edge.
  std::size_t edgeCount() const;
  // Changes whenever an edge is inserted or removed (also by destroy() and clear()): views derived from the
  // adjacency (NeighbourSlots) compare it to know when to rebuild.
  std::uint64_t edgeVersion() const { return edge_version_; }

  // Checks: registry consistent; label ranges disjoint and inside each adjacency vector; no label 0; no dangling
  // neighbour pointers; every edge has its reference edge with the same multiplicity. O(E log E).
  InvariantReport checkInvariants() const;

 private:
  template <typename T>
  Pool<T>& poolFor() {
    std::unique_ptr<PoolBase>& pool = pools_[std::type_index(typeid(T))];
    if (!pool) pool = std::make_unique<Pool<T>>();
    return static_cast<Pool<T>&>(*pool);
  }

  // id 0: the next id.
  void registerElement(Element& element, PoolBase& pool, std::uint64_t id = 0);
  void requireMember(const Element& element) const;
  PoolBase& poolOf(const Element& element) const;

  // Declared before elements_ so that pools outlive the elements they hold during destruction.
  std::unordered_map<std::type_index, std::unique_ptr<PoolBase>> pools_;
  std::vector<Element*> elements_;
  std::uint64_t next_id_ = 1;
  std::uint64_t edge_version_ = 0;
  // Exact-size adjacency blocks of all elements, packed by shrinkToFit() in element order (see element.h). Elements
  // are destroyed (clear() in ~Graph) before it goes.
  std::unique_ptr<std::uint64_t[]> arena_;
};

}  // namespace mge
}  // namespace vrm_sim
