#pragma once
// Compact attribute storage, thesis §3.3.2 (Fig. 3.4–3.6): the attributes of many MGEs live in contiguous arrays so
// that sequential sweeps use the cache well and can be uploaded as one block (renderer, §6). An attributed element
// holds an ArrayConnector (its slot index in the arrays); removal moves the last entry into the hole (order in the
// array is irrelevant, all entries have the same size) and fixes the moved element's slot, so removal is O(1).
//
// Generalisation: ArrayManager<A, B, ...> keeps one array per attribute type (structure of arrays) with ONE shared
// slot per element, so e.g. positions[i], velocities[i] and masses[i] of a node agree without bookkeeping.
// ArrayManager<Attr> is the thesis' single-attribute case.
//
// Storage modes (§3.3.2, last paragraph):
//   kArray: the array is the only copy; ArrayConnector::get() reads/writes the array (the thesis' bent pointer).
//   kDual:  each connector has its own copy (kept by the manager per slot at a stable address), get() works on it,
//           and sync() copies all copies into the arrays on demand (e.g. random-access simulation on the instances,
//           then one bulk copy for the renderer); syncFromArray() copies back after a bulk algorithm wrote the arrays.

#include <algorithm>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

namespace vrm_sim {
namespace mge {

class Element;

enum class StorageMode { kArray, kDual };

template <typename... Attrs>
class ArrayConnector;

template <typename... Attrs>
class ArrayManager {
  static_assert(sizeof...(Attrs) >= 1, "ArrayManager needs at least one attribute type");

 public:
  using Connector = ArrayConnector<Attrs...>;
  using Values = std::tuple<Attrs...>;
  template <std::size_t I>
  using Attr = std::tuple_element_t<I, Values>;
  // Called after a removal moved the last entry into `slot` (so ownerAt(slot) / connectorAt(slot) is the moved
  // element). Structures that store slot indices of this manager (e.g. spring → node index pairs) fix them here.
  using RelocationListener = std::function<void(std::size_t slot)>;

  explicit ArrayManager(StorageMode mode = StorageMode::kArray) : mode_(mode) {}
  ArrayManager(const ArrayManager&) = delete;
  ArrayManager& operator=(const ArrayManager&) = delete;
  // Connectors may outlive the manager (e.g. elements destroyed later): they are left disconnected.
  ~ArrayManager() {
    for (Connector* connector : connectors_) connector->manager_ = nullptr;
  }

  StorageMode mode() const { return mode_; }
  std::size_t size() const { return connectors_.size(); }
  bool empty() const { return connectors_.empty(); }
  void reserve(std::size_t count) {
    forEachColumn([count](auto& column) { column.reserve(count); });
    connectors_.reserve(count);
    owners_.reserve(count);
    if (mode_ == StorageMode::kDual) locals_.reserve(count);
  }

  // Contiguous column I (size() entries). In kDual mode it holds the values of the last sync().
  template <std::size_t I = 0>
  Attr<I>* data() {
    return std::get<I>(columns_).data();
  }
  template <std::size_t I = 0>
  const Attr<I>* data() const {
    return std::get<I>(columns_).data();
  }
  template <std::size_t I = 0>
  Attr<I>& at(std::size_t slot) {
    assert(slot < size());
    return std::get<I>(columns_)[slot];
  }
  template <std::size_t I = 0>
  const Attr<I>& at(std::size_t slot) const {
    assert(slot < size());
    return std::get<I>(columns_)[slot];
  }

  Connector& connectorAt(std::size_t slot) const { return *connectors_[slot]; }
  Element* ownerAt(std::size_t slot) const { return owners_[slot]; }

  void setRelocationListener(RelocationListener listener) { on_relocated_ = std::move(listener); }
  // Changes whenever a slot is taken or freed (a removal moves the last entry): views that cache slot indices
  // (NeighbourSlots) compare it to know when to rebuild.
  std::uint64_t slotVersion() const { return slot_version_; }

  // kDual: instance copies → arrays. No-op in kArray mode (the array is the only copy).
  void sync() {
    if (mode_ != StorageMode::kDual) return;
    for (std::size_t slot = 0; slot < connectors_.size(); ++slot) {
      copyToArray(slot, *locals_[slot], std::index_sequence_for<Attrs...>{});
    }
  }
  // kDual: arrays → instance copies. No-op in kArray mode.
  void syncFromArray() {
    if (mode_ != StorageMode::kDual) return;
    for (std::size_t slot = 0; slot < connectors_.size(); ++slot) {
      copyFromArray(slot, *locals_[slot], std::index_sequence_for<Attrs...>{});
    }
  }

 private:
  friend Connector;

  template <typename Function>
  void forEachColumn(Function&& function) {
    std::apply([&function](auto&... column) { (function(column), ...); }, columns_);
  }

  // The thesis' FetchNewDataPtr: a new slot at the end of every column.
  std::uint32_t acquire(Connector& connector, Element* owner, const Attrs&... initial) {
    if (connectors_.size() >= std::numeric_limits<std::uint32_t>::max()) throw std::length_error("ArrayManager full");
    const std::size_t slot = connectors_.size();
    std::unique_ptr<Values> local;
    if (mode_ == StorageMode::kDual) local = std::make_unique<Values>(initial...);
    try {
      connectors_.push_back(&connector);
      owners_.push_back(owner);
      if (mode_ == StorageMode::kDual) locals_.push_back(std::move(local));
      appendValues(std::index_sequence_for<Attrs...>{}, initial...);
    } catch (...) {
      // Roll back the vectors that did grow, so all of them keep size() entries.
      forEachColumn([slot](auto& column) { column.resize(std::min(column.size(), slot)); });
      connectors_.resize(std::min(connectors_.size(), slot));
      owners_.resize(std::min(owners_.size(), slot));
      locals_.resize(std::min(locals_.size(), slot));
      throw;
    }
    ++slot_version_;
    return static_cast<std::uint32_t>(slot);
  }

  template <std::size_t... I>
  void appendValues(std::index_sequence<I...>, const Attrs&... initial) {
    (std::get<I>(columns_).push_back(initial), ...);
  }

  // Fig. 3.6: the last entry fills the hole; only the moved element's slot changes.
  void release(std::size_t slot) {
    assert(slot < size());
    const std::size_t last = connectors_.size() - 1;
    if (slot != last) {
      forEachColumn([slot, last](auto& column) { column[slot] = std::move(column[last]); });
      connectors_[slot] = connectors_[last];
      connectors_[slot]->slot_ = static_cast<std::uint32_t>(slot);
      owners_[slot] = owners_[last];
      if (!locals_.empty()) locals_[slot] = std::move(locals_[last]);
    }
    forEachColumn([](auto& column) { column.pop_back(); });
    connectors_.pop_back();
    owners_.pop_back();
    if (!locals_.empty()) locals_.pop_back();
    ++slot_version_;
    if (slot != last && on_relocated_) on_relocated_(slot);
  }

  template <std::size_t... I>
  void copyToArray(std::size_t slot, const Values& values, std::index_sequence<I...>) {
    ((std::get<I>(columns_)[slot] = std::get<I>(values)), ...);
  }
  template <std::size_t... I>
  void copyFromArray(std::size_t slot, Values& values, std::index_sequence<I...>) const {
    ((std::get<I>(values) = std::get<I>(columns_)[slot]), ...);
  }

  StorageMode mode_;
  std::tuple<std::vector<Attrs>...> columns_;
  std::vector<Connector*> connectors_;  // slot → connector, to fix the slot of a moved entry
  std::vector<Element*> owners_;        // slot → owning element (kept here, not in the connector: smaller elements)
  std::vector<std::unique_ptr<Values>> locals_;  // slot → instance copy (kDual mode only; stable addresses)
  RelocationListener on_relocated_;
  std::uint64_t slot_version_ = 0;
};

// Member of an attributed element; its link to one ArrayManager (thesis Fig. 3.4/3.5). Not copyable or movable:
// the manager points at it. Disconnects (frees the slot) on destruction.
template <typename... Attrs>
class ArrayConnector {
 public:
  using Manager = ArrayManager<Attrs...>;
  template <std::size_t I>
  using Attr = typename Manager::template Attr<I>;

  ArrayConnector() = default;
  ArrayConnector(const ArrayConnector&) = delete;
  ArrayConnector& operator=(const ArrayConnector&) = delete;
  ~ArrayConnector() { disconnect(); }

  // The thesis' ConnectToArray: takes a slot and stores the initial values there (and in the instance copy in
  // kDual mode). `owner` is reported by ArrayManager::ownerAt(); it may be null.
  void connect(Manager& manager, Element* owner, const Attrs&... initial) {
    if (manager_ != nullptr) throw std::logic_error("ArrayConnector is already connected");
    slot_ = manager.acquire(*this, owner, initial...);
    dual_ = manager.mode() == StorageMode::kDual;
    manager_ = &manager;
  }
  void connect(Manager& manager, Element* owner) { connect(manager, owner, Attrs{}...); }

  void disconnect() {
    if (manager_ == nullptr) return;
    Manager* manager = manager_;
    manager_ = nullptr;
    manager->release(slot_);
  }

  bool connected() const { return manager_ != nullptr; }
  // Index of this element's entry in every column of the manager; changes when another element is removed.
  std::uint32_t slot() const {
    assert(connected());
    return slot_;
  }
  // The owner given to connect(); null while disconnected.
  Element* owner() const { return manager_ == nullptr ? nullptr : manager_->owners_[slot_]; }
  Manager* manager() const { return manager_; }

  template <std::size_t I = 0>
  Attr<I>& get() {
    assert(connected());
    return dual_ ? std::get<I>(*manager_->locals_[slot_]) : manager_->template at<I>(slot_);
  }
  template <std::size_t I = 0>
  const Attr<I>& get() const {
    assert(connected());
    return dual_ ? std::get<I>(*manager_->locals_[slot_]) : manager_->template at<I>(slot_);
  }

 private:
  friend Manager;

  // 16 bytes: owner and kDual instance copy live in the manager (indexed by slot), so attributed elements stay small.
  std::uint32_t slot_ = 0;  // first: the field navigation reads most
  bool dual_ = false;       // kDual: get() works on the manager's instance copy of this slot
  Manager* manager_ = nullptr;
};

}  // namespace mge
}  // namespace vrm_sim
