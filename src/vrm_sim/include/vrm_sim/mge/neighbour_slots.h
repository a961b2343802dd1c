#pragma once
// NeighbourSlots<T>: the array slots of one element list and of each listed element's neighbours, as one contiguous
// offsets + slots array (CSR), derived from the graph through ListAccess and rebuilt when the topology or the slots
// change (issue 15).
//
// Why: a sweep over Γ(tissue, kNodeList) that reads each node's neighbours through ListAccess streams the node
// elements, their adjacency blocks (label table and neighbour pointers) and each neighbour's slot: at 10^6 nodes about
// three times the bytes of a CSR array, and memory bound. Solvers that visit the same neighbourhoods every step read
// this view instead and pay the graph walk once per topology change (cutting, refinement), not once per step. The MGE
// stays the one source of truth: elements can still be added and removed; refresh() notices it by
// Graph::edgeVersion() and ArrayManager::slotVersion().
//
// T (the listed elements) and N (their neighbours, T by default) are attributed element types with arrayConnector()
// (Node, Spring, Triangle); every listed element must be connected to the element manager passed to refresh(), every
// neighbour under the given labels to the neighbour manager (e.g. nodes and the springs at each node: a node → spring
// adjacency of the tissue, issue 40).
//
// Layout::kListOrder keeps the graph's orders: row k is the k-th listed element, its neighbours in list order.
// Layout::kSlotOrder is canonical: row i is the element in slot i (so the listed elements must be exactly the
// manager's slots 0..n−1) and each row's neighbour slots ascend, so the result depends on the slots alone and not on
// the order in which edges were inserted — what a solver needs whose results must not change when the same topology
// was reached by another history.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <stdexcept>
#include <utility>
#include <vector>

#include "vrm_sim/mge/element.h"
#include "vrm_sim/mge/graph.h"
#include "vrm_sim/mge/list_access.h"

namespace vrm_sim {
namespace mge {

template <typename T, typename N = T>
class NeighbourSlots {
 public:
  enum class Layout { kListOrder, kSlotOrder };

  // Contiguous slots of one element's neighbours.
  class Range {
   public:
    Range(const std::uint32_t* first, const std::uint32_t* last) : first_(first), last_(last) {}
    const std::uint32_t* begin() const { return first_; }
    const std::uint32_t* end() const { return last_; }
    std::size_t size() const { return static_cast<std::size_t>(last_ - first_); }

   private:
    const std::uint32_t* first_;
    const std::uint32_t* last_;
  };

  // The listed elements are Γ(owner, list_label); the neighbours of each are Γ(element, l) for each l in `labels`,
  // concatenated in that order (e.g. {l, −l} for an undirected relation stored once per pair).
  NeighbourSlots(Element& owner, Label list_label, std::vector<Label> labels, Layout layout = Layout::kListOrder)
      : owner_(&owner), list_label_(list_label), labels_(std::move(labels)), layout_(layout) {}

  // Rebuilds if `graph` changed its edges or `arrays` its slots since the last rebuild (or other ones are passed).
  // Returns true if it rebuilt. Throws std::invalid_argument if an element is not connected to `arrays`.
  template <typename Manager>
  bool refresh(const Graph& graph, const Manager& arrays) {
    return refresh(graph, arrays, arrays);
  }
  // The same with the listed elements in `element_arrays` and their neighbours in `neighbour_arrays`. kSlotOrder
  // also throws std::invalid_argument unless the listed elements occupy exactly the slots 0..size()−1.
  template <typename ElementManager, typename NeighbourManager>
  bool refresh(const Graph& graph, const ElementManager& element_arrays, const NeighbourManager& neighbour_arrays) {
    const Stamp stamp{&graph,
                      &element_arrays,
                      &neighbour_arrays,
                      graph.edgeVersion(),
                      element_arrays.slotVersion(),
                      neighbour_arrays.slotVersion()};
    if (built_ && stamp == stamp_) return false;
    built_ = false;  // a throwing rebuild leaves no half-built view behind a matching stamp
    if (layout_ == Layout::kSlotOrder) {
      rebuildBySlot(element_arrays, neighbour_arrays);
    } else {
      rebuild(element_arrays, neighbour_arrays);
    }
    stamp_ = stamp;
    built_ = true;
    return true;
  }

  // Number of listed elements.
  std::size_t size() const { return element_slots_.size(); }
  // Array slot of the k-th row's element (k itself with kSlotOrder).
  std::uint32_t slot(std::size_t k) const { return element_slots_[k]; }
  // Array slots of the k-th row's neighbours.
  Range neighbours(std::size_t k) const {
    return Range(neighbour_slots_.data() + offsets_[k], neighbour_slots_.data() + offsets_[k + 1]);
  }
  // The raw arrays, for kernels that want the CSR form itself: offsets() has size() + 1 entries.
  const std::uint32_t* elementSlots() const { return element_slots_.data(); }
  const std::uint32_t* offsets() const { return offsets_.data(); }
  const std::uint32_t* neighbourSlots() const { return neighbour_slots_.data(); }
  std::size_t neighbourCount() const { return neighbour_slots_.size(); }

 private:
  struct Stamp {
    const Graph* graph = nullptr;
    const void* element_arrays = nullptr;
    const void* neighbour_arrays = nullptr;
    std::uint64_t edge_version = 0;
    std::uint64_t element_slot_version = 0;
    std::uint64_t neighbour_slot_version = 0;
    bool operator==(const Stamp& other) const {
      return graph == other.graph && element_arrays == other.element_arrays &&
             neighbour_arrays == other.neighbour_arrays && edge_version == other.edge_version &&
             element_slot_version == other.element_slot_version &&
             neighbour_slot_version == other.neighbour_slot_version;
    }
  };

  template <typename Attributed, typename Manager>
  static std::uint32_t slotIn(const Manager& arrays, const Attributed& element) {
    const auto& connector = element.arrayConnector();
    if (connector.manager() != &arrays) throw std::invalid_argument("NeighbourSlots: element not in these arrays");
    return connector.slot();
  }

  template <typename ElementManager, typename NeighbourManager>
  void rebuild(const ElementManager& element_arrays, const NeighbourManager& neighbour_arrays) {
    const ListAccess<T> list(*owner_, list_label_);
    element_slots_.clear();
    offsets_.clear();
    neighbour_slots_.clear();
    element_slots_.reserve(list.size());
    offsets_.reserve(list.size() + 1);
    offsets_.push_back(0);
    for (T* element : list) {
      element_slots_.push_back(slotIn(element_arrays, *element));
      for (Label label : labels_) {
        for (N* neighbour : ListAccess<N>(*element, label)) {
          neighbour_slots_.push_back(slotIn(neighbour_arrays, *neighbour));
        }
      }
      if (neighbour_slots_.size() > 0xffffffffu) throw std::length_error("NeighbourSlots: too many neighbours");
      offsets_.push_back(static_cast<std::uint32_t>(neighbour_slots_.size()));
    }
  }

  // Two passes over the list: the row lengths by slot, then each row filled in place and sorted.
  template <typename ElementManager, typename NeighbourManager>
  void rebuildBySlot(const ElementManager& element_arrays, const NeighbourManager& neighbour_arrays) {
    const ListAccess<T> list(*owner_, list_label_);
    const std::size_t n = list.size();
    element_slots_.resize(n);
    std::iota(element_slots_.begin(), element_slots_.end(), 0u);
    offsets_.assign(n + 1, 0);
    std::size_t total = 0;
    for (T* element : list) {
      const std::uint32_t slot = slotIn(element_arrays, *element);
      if (slot >= n || offsets_[slot + 1] != 0) {
        throw std::invalid_argument("NeighbourSlots: the listed elements do not occupy the slots 0..n-1 once each");
      }
      std::size_t count = 0;
      for (Label label : labels_) count += ListAccess<N>(*element, label).size();
      // +1 marks the row as seen (an element without neighbours too); taken off again below.
      offsets_[slot + 1] = static_cast<std::uint32_t>(count + 1);
      total += count;
    }
    if (total > 0xffffffffu) throw std::length_error("NeighbourSlots: too many neighbours");
    for (std::size_t i = 0; i < n; ++i) offsets_[i + 1] = offsets_[i] + (offsets_[i + 1] - 1);
    neighbour_slots_.resize(total);
    for (T* element : list) {
      const std::uint32_t slot = element->arrayConnector().slot();
      std::uint32_t* row = neighbour_slots_.data() + offsets_[slot];
      std::uint32_t* fill = row;
      for (Label label : labels_) {
        for (N* neighbour : ListAccess<N>(*element, label)) *fill++ = slotIn(neighbour_arrays, *neighbour);
      }
      std::sort(row, fill);
    }
  }

  Element* owner_;
  Label list_label_;
  std::vector<Label> labels_;
  Layout layout_;
  bool built_ = false;
  Stamp stamp_;
  std::vector<std::uint32_t> element_slots_;
  std::vector<std::uint32_t> offsets_;
  std::vector<std::uint32_t> neighbour_slots_;
};

}  // namespace mge
}  // namespace vrm_sim
