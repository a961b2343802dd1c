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
// T is an attributed element type with arrayConnector() (Node, Spring, Triangle); every listed element and every
// neighbour under the given labels must be connected to the manager passed to refresh().

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <utility>
#include <vector>

#include "vrm_sim/mge/element.h"
#include "vrm_sim/mge/graph.h"
#include "vrm_sim/mge/list_access.h"

namespace vrm_sim {
namespace mge {

template <typename T>
class NeighbourSlots {
 public:
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

  // The listed elements are Γ(owner, list_label) in list order; the neighbours of each are Γ(element, l) for each l in
  // `labels`, concatenated in that order (e.g. {l, −l} for an undirected relation stored once per pair).
  NeighbourSlots(Element& owner, Label list_label, std::vector<Label> labels)
      : owner_(&owner), list_label_(list_label), labels_(std::move(labels)) {}

  // Rebuilds if `graph` changed its edges or `arrays` its slots since the last rebuild (or other ones are passed).
  // Returns true if it rebuilt. Throws std::invalid_argument if an element is not connected to `arrays`.
  template <typename Manager>
  bool refresh(const Graph& graph, const Manager& arrays) {
    const Stamp stamp{&graph, &arrays, graph.edgeVersion(), arrays.slotVersion()};
    if (built_ && stamp == stamp_) return false;
    rebuild(arrays);
    stamp_ = stamp;
    built_ = true;
    return true;
  }

  // Number of listed elements.
  std::size_t size() const { return element_slots_.size(); }
  // Array slot of the k-th listed element.
  std::uint32_t slot(std::size_t k) const { return element_slots_[k]; }
  // Array slots of the k-th listed element's neighbours.
  Range neighbours(std::size_t k) const {
    return Range(neighbour_slots_.data() + offsets_[k], neighbour_slots_.data() + offsets_[k + 1]);
  }
  // The raw arrays, for kernels that want the CSR form itself: offsets() has size() + 1 entries.
  const std::uint32_t* elementSlots() const { return element_slots_.data(); }
  const std::uint32_t* offsets() const { return offsets_.data(); }
  const std::uint32_t* neighbourSlots() const { return neighbour_slots_.data(); }

 private:
  struct Stamp {
    const Graph* graph = nullptr;
    const void* arrays = nullptr;
    std::uint64_t edge_version = 0;
    std::uint64_t slot_version = 0;
    bool operator==(const Stamp& other) const {
      return graph == other.graph && arrays == other.arrays && edge_version == other.edge_version &&
             slot_version == other.slot_version;
    }
  };

  template <typename Manager>
  static std::uint32_t slotIn(const Manager& arrays, const T& element) {
    const auto& connector = element.arrayConnector();
    if (connector.manager() != &arrays) throw std::invalid_argument("NeighbourSlots: element not in these arrays");
    return connector.slot();
  }

  template <typename Manager>
  void rebuild(const Manager& arrays) {
    const ListAccess<T> list(*owner_, list_label_);
    element_slots_.clear();
    offsets_.clear();
    neighbour_slots_.clear();
    element_slots_.reserve(list.size());
    offsets_.reserve(list.size() + 1);
    offsets_.push_back(0);
    for (T* element : list) {
      element_slots_.push_back(slotIn(arrays, *element));
      for (Label label : labels_) {
        for (T* neighbour : ListAccess<T>(*element, label)) neighbour_slots_.push_back(slotIn(arrays, *neighbour));
      }
      if (neighbour_slots_.size() > 0xffffffffu) throw std::length_error("NeighbourSlots: too many neighbours");
      offsets_.push_back(static_cast<std::uint32_t>(neighbour_slots_.size()));
    }
  }

  Element* owner_;
  Label list_label_;
  std::vector<Label> labels_;
  bool built_ = false;
  Stamp stamp_;
  std::vector<std::uint32_t> element_slots_;
  std::vector<std::uint32_t> offsets_;
  std::vector<std::uint32_t> neighbour_slots_;
};

}  // namespace mge
}  // namespace vrm_sim
