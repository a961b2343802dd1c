#include "vrm_sim/mge/graph.h"

#include <algorithm>
#include <cassert>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <typeinfo>
#include <unordered_set>

namespace vrm_sim {
namespace mge {

// ---------------------------------------------------------------------------------------------------------------------
// Element

std::size_t Element::neighbourCount(Label label) const {
  const std::uint32_t index = findRange(label);
  return index == kNoRange ? 0 : range(index).count;
}

Element* Element::neighbour(Label label, std::size_t index) const {
  const std::uint32_t r = findRange(label);
  if (r == kNoRange || index >= range(r).count) throw std::out_of_range("MGE neighbour index out of range");
  return rangeData(r)[index];
}

std::vector<Element*> Element::neighbours(Label label) const {
  const std::uint32_t r = findRange(label);
  if (r == kNoRange) return {};
  Element* const* first = rangeData(r);
  return std::vector<Element*>(first, first + range(r).count);
}

std::vector<Label> Element::labels() const {
  std::vector<Label> result;
  for (std::uint32_t r = 0; r < rangeCount(); ++r) {
    if (range(r).count > 0) result.push_back(range(r).label);
  }
  return result;
}

std::size_t Element::degree() const {
  std::size_t total = 0;
  for (std::uint32_t r = 0; r < rangeCount(); ++r) total += range(r).count;
  return total;
}

void Element::adoptBlock(Block* block, bool in_arena) {
  releaseBlock();
  block_ = block;
  block_in_arena_ = in_arena ? 1 : 0;
  holes_ = 0;
}

void Element::reallocateBlock(std::uint32_t range_capacity, std::uint32_t capacity) {
  const std::uint32_t range_count = rangeCount();
  const std::uint32_t size = block_ == nullptr ? 0 : block_->size;
  assert(range_capacity >= range_count && capacity >= size);
  Block* block = static_cast<Block*>(::operator new(Block::bytes(range_capacity, capacity)));
  block->range_count = range_count;
  block->range_capacity = range_capacity;
  block->size = size;
  block->capacity = capacity;
  if (block_ != nullptr) {
    std::copy_n(block_->ranges(), range_count, block->ranges());
    std::copy_n(block_->neighbours(), size, block->neighbours());
  }
  const std::uint32_t holes = holes_;
  adoptBlock(block, /*in_arena=*/false);
  holes_ = holes;
}

std::uint32_t Element::findOrAddRange(Label label) {
  const std::uint32_t existing = findRange(label);
  if (existing != kNoRange) return existing;
  if (block_ == nullptr || block_->range_count == block_->range_capacity) {
    const std::uint32_t range_count = rangeCount();
    if (range_count == kNoRange - 1) throw std::length_error("MGE element has too many labels");
    reallocateBlock(range_count == 0 ? 2 : range_count + std::max<std::uint32_t>(range_count / 2, 1),
                    block_ == nullptr ? 0 : block_->capacity);
  }
  block_->ranges()[block_->range_count] = LabelRange{label, block_->size, 0, 0};
  return block_->range_count++;
}

void Element::growRange(std::uint32_t range_index) {
  LabelRange current = range(range_index);
  if (current.capacity >= 0x7fffffffu) throw std::length_error("MGE adjacency list too long");
  const std::uint32_t new_capacity = std::max<std::uint32_t>(2, current.capacity * 2);
  const bool last = current.begin + current.capacity == block_->size;
  const std::uint64_t needed =
      last ? std::uint64_t{current.begin} + new_capacity : std::uint64_t{block_->size} + new_capacity;
  if (needed > 0xffffffffu) throw std::length_error("MGE adjacency too large");
  if (needed > block_->capacity || block_in_arena_) {
    // Geometric growth of the whole block (arena blocks are exact-size: they always move back to the heap).
    const std::uint64_t grown = std::max<std::uint64_t>(needed, std::uint64_t{block_->capacity} * 2);
    reallocateBlock(block_->range_capacity, static_cast<std::uint32_t>(std::min<std::uint64_t>(grown, 0xffffffffu)));
  }
  Element** neighbours = block_->neighbours();
  LabelRange& range = block_->ranges()[range_index];
  if (last) {
    std::fill(neighbours + block_->size, neighbours + range.begin + new_capacity, nullptr);
    block_->size = range.begin + new_capacity;
  } else {
    // Move the range behind everything else instead of shifting all later ranges: O(count), amortised O(1).
    const std::uint32_t new_begin = block_->size;
    std::copy_n(neighbours + range.begin, range.count, neighbours + new_begin);
    std::fill(neighbours + new_begin + range.count, neighbours + new_begin + new_capacity, nullptr);
    std::fill_n(neighbours + range.begin, range.capacity, nullptr);
    holes_ += range.capacity;
    block_->size = new_begin + new_capacity;
    range.begin = new_begin;
  }
  range.capacity = new_capacity;
  if (holes_ > block_->size / 2) compactRanges();
}

std::size_t Element::tightBlockBytes() const {
  if (block_ == nullptr) return 0;
  return Block::bytes(block_->range_count, degree());
}

void Element::compactRanges() {
  const std::uint32_t range_count = block_->range_count;
  std::uint64_t total = 0;
  for (std::uint32_t r = 0; r < range_count; ++r) total += range(r).capacity;
  const std::uint32_t range_capacity = block_->range_capacity;
  Block* block = static_cast<Block*>(::operator new(Block::bytes(range_capacity, total)));
  block->range_count = range_count;
  block->range_capacity = range_capacity;
  block->capacity = static_cast<std::uint32_t>(total);
  Element** packed = block->neighbours();
  std::uint32_t size = 0;
  for (std::uint32_t r = 0; r < range_count; ++r) {
    LabelRange entry = range(r);
    std::copy_n(rangeData(r), entry.count, packed + size);
    std::fill(packed + size + entry.count, packed + size + entry.capacity, nullptr);
    entry.begin = size;
    size += entry.capacity;
    block->ranges()[r] = entry;
  }
  block->size = size;
  adoptBlock(block, /*in_arena=*/false);
}

void Element::moveBlockToArena(void* memory) {
  Block* block = static_cast<Block*>(memory);
  const std::uint32_t range_count = block_->range_count;
  block->range_count = range_count;
  block->range_capacity = range_count;
  Element** packed = block->neighbours();
  std::uint32_t size = 0;
  for (std::uint32_t r = 0; r < range_count; ++r) {
    LabelRange entry = range(r);
    std::copy_n(rangeData(r), entry.count, packed + size);
    entry.begin = size;
    entry.capacity = entry.count;
    size += entry.count;
    block->ranges()[r] = entry;
  }
  block->size = size;
  block->capacity = size;
  adoptBlock(block, /*in_arena=*/true);
}

void Element::insertNeighbour(std::uint32_t range_index, std::size_t position, Element* neighbour) {
  if (range(range_index).count == range(range_index).capacity) growRange(range_index);
  LabelRange& entry = block_->ranges()[range_index];
  Element** first = block_->neighbours() + entry.begin;
  std::move_backward(first + position, first + entry.count, first + entry.count + 1);
  first[position] = neighbour;
  ++entry.count;
}

bool Element::removeNeighbour(std::uint32_t range_index, Element* neighbour) {
  LabelRange& entry = block_->ranges()[range_index];
  Element** first = block_->neighbours() + entry.begin;
  Element** last = first + entry.count;
  Element** found = std::find(first, last, neighbour);
  if (found == last) return false;
  std::move(found + 1, last, found);
  *(last - 1) = nullptr;
  --entry.count;
  return true;
}

// ---------------------------------------------------------------------------------------------------------------------
// Graph

std::string InvariantReport::summary() const {
  if (errors.empty()) return "ok";
  std::ostringstream out;
  out << errors.size() << " MGE invariant violation(s):";
  const std::size_t shown = std::min<std::size_t>(errors.size(), 20);
  for (std::size_t i = 0; i < shown; ++i) out << "\n  " << errors[i];
  if (shown < errors.size()) out << "\n  ...";
  return out.str();
}

Graph::~Graph() { clear(); }

void Graph::clear() {
  ++edge_version_;
  for (Element* element : elements_) poolOf(*element).destroy(element);
  elements_.clear();
  arena_.reset();  // only the elements just destroyed had blocks in it
}

PoolBase& Graph::poolOf(const Element& element) const {
  // The pool of an element is the pool of its dynamic type (create<T> makes exactly a T).
  const auto found = pools_.find(std::type_index(typeid(element)));
  assert(found != pools_.end() && found->second);
  return *found->second;
}

void Graph::registerElement(Element& element, PoolBase& pool, std::uint64_t id) {
  element.id_ = id != 0 ? id : next_id_++;
  element.graph_index_ = static_cast<std::uint32_t>(elements_.size());
  try {
    elements_.push_back(&element);
  } catch (...) {
    pool.destroy(&element);
    throw;
  }
}

void Graph::setNextId(std::uint64_t next_id) {
  for (const Element* element : elements_) {
    if (element->id_ >= next_id) {
      throw std::invalid_argument("MGE next id " + std::to_string(next_id) + " is not above the live element id " +
                                  std::to_string(element->id_));
    }
  }
  next_id_ = next_id;
}

void Graph::requireMember(const Element& element) const {
  if (!contains(element)) throw std::invalid_argument("MGE element does not belong to this graph");
}

void Graph::destroy(Element& element) {
  requireMember(element);
  ++edge_version_;
  // Remove the reference edges in the neighbours; the element's own lists die with it.
  for (std::uint32_t r = 0; r < element.rangeCount(); ++r) {
    const Element::LabelRange& range = element.range(r);
    const Label reference = referenceLabel(range.label);
    for (std::uint32_t i = 0; i < range.count; ++i) {
      Element* neighbour = element.rangeData(r)[i];
      if (neighbour == &element) continue;  // self loop: both directions are in the dying element
      const std::uint32_t reference_range = neighbour->findRange(reference);
      const bool removed =
          reference_range != Element::kNoRange && neighbour->removeNeighbour(reference_range, &element);
      assert(removed && "missing MGE reference edge");
      (void)removed;
    }
  }
  const std::uint32_t index = element.graph_index_;
  elements_[index] = elements_.back();
  elements_[index]->graph_index_ = index;
  elements_.pop_back();
  poolOf(element).destroy(&element);
}

void Graph::insertEdge(Element& from, Element& to, Label label) {
  requireMember(from);
  insertEdgeAt(from, from.neighbourCount(label), to, label);
}

void Graph::insertEdgeAt(Element& from, std::size_t position, Element& to, Label label) {
  if (label == 0) throw std::invalid_argument("MGE label 0 is not allowed (labels are Z\\{0}, thesis Def. 3.2)");
  requireMember(from);
  requireMember(to);
  const std::uint32_t from_range = from.findOrAddRange(label);
  if (position > from.range(from_range).count) throw std::out_of_range("MGE edge insert position out of range");
  const std::uint32_t to_range = to.findOrAddRange(referenceLabel(label));
  // Reference edge first: if the second insertion throws (bad_alloc) we undo the first, keeping Def. 3.2 intact.
  to.insertNeighbour(to_range, to.range(to_range).count, &from);
  try {
    from.insertNeighbour(from_range, position, &to);
  } catch (...) {
    to.removeNeighbour(to_range, &from);
    throw;
  }
  ++edge_version_;
}

bool Graph::removeEdge(Element& from, Element& to, Label label) {
  if (label == 0) throw std::invalid_argument("MGE label 0 is not allowed (labels are Z\\{0}, thesis Def. 3.2)");
  requireMember(from);
  requireMember(to);
  const std::uint32_t from_range = from.findRange(label);
  if (from_range == Element::kNoRange || !from.removeNeighbour(from_range, &to)) return false;
  const bool removed = to.removeNeighbour(to.findRange(referenceLabel(label)), &from);
  assert(removed && "missing MGE reference edge");
  (void)removed;
  ++edge_version_;
  return true;
}

void Graph::shrinkToFit() {
  // One arena with every element's exact-size block, in element order (creation order unless elements were
  // destroyed): navigation over the elements then reads adjacency sequentially, like a CSR array. Blocks that were in
  // the previous arena move too, so that arena (and the dead blocks of destroyed or grown elements) can go.
  constexpr std::size_t kWord = sizeof(std::uint64_t);
  std::size_t words = 0;
  for (const Element* element : elements_) words += (element->tightBlockBytes() + kWord - 1) / kWord;
  std::unique_ptr<std::uint64_t[]> arena(words == 0 ? nullptr : new std::uint64_t[words]);
  std::size_t used = 0;
  for (Element* element : elements_) {
    const std::size_t bytes = element->tightBlockBytes();
    if (bytes == 0) continue;
    element->moveBlockToArena(arena.get() + used);
    used += (bytes + kWord - 1) / kWord;
  }
  arena_ = std::move(arena);
  elements_.shrink_to_fit();
}

std::size_t Graph::edgeCount() const {
  std::size_t directed = 0;
  for (const Element* element : elements_) directed += element->degree();
  return directed / 2;
}

InvariantReport Graph::checkInvariants() const {
  InvariantReport report;
  auto fail = [&report](const Element& element, const std::string& what) {
    std::ostringstream out;
    out << "element id " << element.id() << ": " << what;
    report.errors.push_back(out.str());
  };

  std::unordered_set<const Element*> members;
  members.reserve(elements_.size());
  std::unordered_set<std::uint64_t> ids;
  for (std::size_t i = 0; i < elements_.size(); ++i) {
    const Element* element = elements_[i];
    if (element->graph_index_ != i) fail(*element, "registry index mismatch");
    const auto pool = pools_.find(std::type_index(typeid(*element)));
    if (pool == pools_.end() || !pool->second) fail(*element, "no owning pool");
    if (!ids.insert(element->id()).second) fail(*element, "duplicate id");
    members.insert(element);
  }

  // (from id, to id, label) of every directed edge, and the reference edge each one demands.
  using EdgeKey = std::tuple<std::uint64_t, std::uint64_t, Label>;
  std::vector<EdgeKey> edges;
  std::vector<EdgeKey> demanded_references;
  for (const Element* element : elements_) {
    std::unordered_set<Label> seen_labels;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> extents;  // (begin, capacity) of every range
    std::size_t owned = 0;
    bool layout_ok = true;
    const Element::Block* block = element->block_;
    if (block != nullptr && (block->range_count > block->range_capacity || block->size > block->capacity)) {
      fail(*element, "adjacency block header inconsistent");
      continue;
    }
    for (std::uint32_t r = 0; r < element->rangeCount(); ++r) {
      const Element::LabelRange& range = element->range(r);
      if (range.label == 0) fail(*element, "label 0");
      if (!seen_labels.insert(range.label).second) fail(*element, "label listed twice");
      if (range.count > range.capacity) {
        fail(*element, "label range count exceeds capacity");
        layout_ok = false;
      }
      if (std::size_t{range.begin} + range.capacity > block->size) {
        fail(*element, "label range outside the adjacency array");
        layout_ok = false;
      }
      if (range.capacity > 0) extents.emplace_back(range.begin, range.capacity);  // empty ranges own no entries
      owned += range.capacity;
    }
    std::sort(extents.begin(), extents.end());
    for (std::size_t r = 1; r < extents.size(); ++r) {
      if (extents[r - 1].first + extents[r - 1].second > extents[r].first) {
        fail(*element, "label ranges overlap");
        layout_ok = false;
      }
    }
    if (owned + element->holes_ != (block == nullptr ? 0 : block->size)) {
      fail(*element, "adjacency hole bookkeeping wrong");
    }
    if (!layout_ok) continue;
    for (std::uint32_t r = 0; r < element->rangeCount(); ++r) {
      const Element::LabelRange& range = element->range(r);
      for (std::uint32_t i = 0; i < range.count; ++i) {
        const Element* neighbour = element->rangeData(r)[i];
        if (members.count(neighbour) == 0) {
          fail(*element, "dangling neighbour (label " + std::to_string(range.label) + ")");
          continue;
        }
        edges.emplace_back(element->id(), neighbour->id(), range.label);
        demanded_references.emplace_back(neighbour->id(), element->id(), referenceLabel(range.label));
      }
    }
  }
  std::sort(edges.begin(), edges.end());
  std::sort(demanded_references.begin(), demanded_references.end());
  if (edges != demanded_references) {
    std::vector<EdgeKey> missing;
    std::set_difference(demanded_references.begin(), demanded_references.end(), edges.begin(), edges.end(),
                        std::back_inserter(missing));
    std::ostringstream out;
    out << "reference edges missing or with wrong multiplicity (" << missing.size() << " missing)";
    if (!missing.empty()) {
      out << ", e.g. (" << std::get<0>(missing[0]) << ", " << std::get<1>(missing[0]) << ", " << std::get<2>(missing[0])
          << ")";
    }
    report.errors.push_back(out.str());
  }
  return report;
}

}  // namespace mge
}  // namespace vrm_sim
