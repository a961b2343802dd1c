#include "vrm_sim/mge/graph.h"

#include <algorithm>
#include <cassert>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <unordered_set>

namespace vrm_sim {
namespace mge {

// ---------------------------------------------------------------------------------------------------------------------
// Element

std::size_t Element::neighbourCount(Label label) const {
  const std::uint32_t range = findRange(label);
  return range == kNoRange ? 0 : ranges_[range].count;
}

Element* Element::neighbour(Label label, std::size_t index) const {
  const std::uint32_t range = findRange(label);
  if (range == kNoRange || index >= ranges_[range].count) throw std::out_of_range("MGE neighbour index out of range");
  return neighbours_[ranges_[range].begin + index];
}

std::vector<Element*> Element::neighbours(Label label) const {
  const std::uint32_t range = findRange(label);
  if (range == kNoRange) return {};
  const auto first = neighbours_.begin() + ranges_[range].begin;
  return std::vector<Element*>(first, first + ranges_[range].count);
}

std::vector<Label> Element::labels() const {
  std::vector<Label> result;
  for (const LabelRange& range : ranges_) {
    if (range.count > 0) result.push_back(range.label);
  }
  return result;
}

std::size_t Element::degree() const {
  std::size_t total = 0;
  for (const LabelRange& range : ranges_) total += range.count;
  return total;
}

void Element::shrinkAdjacency() {
  // Fresh, exact-size allocations for both blocks, made back to back: after a bulk build they then lie next to each
  // other (and next to the neighbouring elements' blocks) on the heap.
  std::vector<LabelRange>(ranges_.begin(), ranges_.end()).swap(ranges_);
  compactRanges(/*tight=*/true);
}

std::uint32_t Element::findOrAddRange(Label label) {
  const std::uint32_t existing = findRange(label);
  if (existing != kNoRange) return existing;
  ranges_.push_back(LabelRange{label, static_cast<std::uint32_t>(neighbours_.size()), 0, 0});
  return static_cast<std::uint32_t>(ranges_.size() - 1);
}

void Element::growRange(std::uint32_t range_index) {
  LabelRange& range = ranges_[range_index];
  const std::uint32_t new_capacity = std::max<std::uint32_t>(2, range.capacity * 2);
  if (range.begin + range.capacity == neighbours_.size()) {
    neighbours_.resize(range.begin + new_capacity, nullptr);
  } else {
    // Move the range behind everything else instead of shifting all later ranges: O(count), amortised O(1).
    const std::size_t new_begin = neighbours_.size();
    neighbours_.resize(new_begin + new_capacity, nullptr);
    std::copy_n(neighbours_.begin() + range.begin, range.count, neighbours_.begin() + new_begin);
    std::fill_n(neighbours_.begin() + range.begin, range.capacity, nullptr);
    holes_ += range.capacity;
    range.begin = static_cast<std::uint32_t>(new_begin);
  }
  range.capacity = new_capacity;
  if (holes_ > neighbours_.size() / 2) compactRanges(/*tight=*/false);
}

void Element::compactRanges(bool tight) {
  std::vector<Element*> packed;
  std::size_t total = 0;
  for (const LabelRange& range : ranges_) total += tight ? range.count : range.capacity;
  packed.reserve(total);
  for (LabelRange& range : ranges_) {
    const auto first = neighbours_.begin() + range.begin;
    const std::uint32_t new_begin = static_cast<std::uint32_t>(packed.size());
    packed.insert(packed.end(), first, first + range.count);
    if (!tight) packed.resize(packed.size() + (range.capacity - range.count), nullptr);
    range.begin = new_begin;
    if (tight) range.capacity = range.count;
  }
  neighbours_.swap(packed);
  holes_ = 0;
}

void Element::insertNeighbour(std::uint32_t range_index, std::size_t position, Element* neighbour) {
  if (ranges_[range_index].count == ranges_[range_index].capacity) growRange(range_index);
  LabelRange& range = ranges_[range_index];
  const auto first = neighbours_.begin() + range.begin;
  std::move_backward(first + position, first + range.count, first + range.count + 1);
  first[position] = neighbour;
  ++range.count;
}

bool Element::removeNeighbour(std::uint32_t range_index, Element* neighbour) {
  LabelRange& range = ranges_[range_index];
  const auto first = neighbours_.begin() + range.begin;
  const auto last = first + range.count;
  const auto found = std::find(first, last, neighbour);
  if (found == last) return false;
  std::move(found + 1, last, found);
  *(last - 1) = nullptr;
  --range.count;
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
  for (Element* element : elements_) element->pool_->destroy(element);
  elements_.clear();
}

void Graph::registerElement(Element& element, PoolBase& pool) {
  element.id_ = next_id_++;
  element.pool_ = &pool;
  element.graph_index_ = static_cast<std::uint32_t>(elements_.size());
  try {
    elements_.push_back(&element);
  } catch (...) {
    pool.destroy(&element);
    throw;
  }
}

void Graph::requireMember(const Element& element) const {
  if (!contains(element)) throw std::invalid_argument("MGE element does not belong to this graph");
}

void Graph::destroy(Element& element) {
  requireMember(element);
  // Remove the reference edges in the neighbours; the element's own lists die with it.
  for (const Element::LabelRange& range : element.ranges_) {
    const Label reference = referenceLabel(range.label);
    for (std::uint32_t i = 0; i < range.count; ++i) {
      Element* neighbour = element.neighbours_[range.begin + i];
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
  element.pool_->destroy(&element);
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
  if (position > from.ranges_[from_range].count) throw std::out_of_range("MGE edge insert position out of range");
  const std::uint32_t to_range = to.findOrAddRange(referenceLabel(label));
  // Reference edge first: if the second insertion throws (bad_alloc) we undo the first, keeping Def. 3.2 intact.
  to.insertNeighbour(to_range, to.ranges_[to_range].count, &from);
  try {
    from.insertNeighbour(from_range, position, &to);
  } catch (...) {
    to.removeNeighbour(to_range, &from);
    throw;
  }
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
  return true;
}

void Graph::shrinkToFit() {
  for (Element* element : elements_) element->shrinkAdjacency();
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
    if (element->pool_ == nullptr) fail(*element, "no owning pool");
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
    for (const Element::LabelRange& range : element->ranges_) {
      if (range.label == 0) fail(*element, "label 0");
      if (!seen_labels.insert(range.label).second) fail(*element, "label listed twice");
      if (range.count > range.capacity) {
        fail(*element, "label range count exceeds capacity");
        layout_ok = false;
      }
      if (std::size_t{range.begin} + range.capacity > element->neighbours_.size()) {
        fail(*element, "label range outside the adjacency vector");
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
    if (owned + element->holes_ != element->neighbours_.size()) fail(*element, "adjacency hole bookkeeping wrong");
    if (!layout_ok) continue;
    for (const Element::LabelRange& range : element->ranges_) {
      for (std::uint32_t i = 0; i < range.count; ++i) {
        const Element* neighbour = element->neighbours_[range.begin + i];
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
