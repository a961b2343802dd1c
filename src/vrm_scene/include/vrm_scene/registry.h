#pragma once
// One table per variation point (integrators, collision detectors, tissue models, scenarios, instruments): the
// names a scene file may use, the factory that builds each, and a one-line summary. The scene schema check, the
// factories, `--list` outputs and the docs all read the same table, so a name cannot be known in one place and
// unknown in another.
//
// Tables are built explicitly by the layer that owns the implementations (not self-registering: a static library
// drops object files nothing references, and the order of static initialisation across libraries is unspecified).

#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace vrm_sim {

// Levenshtein distance (insertions, deletions, substitutions).
inline std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> previous(b.size() + 1), current(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) previous[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    current[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      current[j] = std::min({previous[j] + 1, current[j - 1] + 1, previous[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    }
    std::swap(previous, current);
  }
  return previous[b.size()];
}

// " (did you mean 'x'?)" for the nearest candidate within two edits, else "": only near misses are typos worth
// pointing at. A word that names a candidate without its unit suffix ("roll" for "roll_deg", "cut_rate" for
// "cut_rate_hz") is pointed at it too: the value is then meant in that unit.
inline std::string typoSuggestion(const std::string& word, const std::vector<std::string>& candidates) {
  for (const char* unit : {"deg", "hz", "ms", "mm", "um"}) {
    const std::string with_unit = word + "_" + unit;
    for (const auto& candidate : candidates) {
      if (candidate == with_unit) return " (did you mean '" + candidate + "', in " + unit + "?)";
    }
  }
  std::string best;
  std::size_t best_distance = 3;
  for (const auto& candidate : candidates) {
    const std::size_t distance = editDistance(word, candidate);
    if (distance < best_distance) {
      best_distance = distance;
      best = candidate;
    }
  }
  return best.empty() ? "" : " (did you mean '" + best + "'?)";
}

template <class Factory>
class Registry {
 public:
  struct Entry {
    std::string name;
    Factory make;
    std::string summary;  // one line, for listings and error messages
  };

  // `what` names the variation point in messages ("integrator", "collision detector", ...).
  Registry(std::string what, std::vector<Entry> entries) : what_(std::move(what)), entries_(std::move(entries)) {
    for (std::size_t i = 0; i < entries_.size(); ++i) {
      for (std::size_t j = 0; j < i; ++j) {
        if (entries_[i].name == entries_[j].name) throw std::logic_error(what_ + " '" + entries_[i].name + "' twice");
      }
    }
  }

  const std::string& what() const { return what_; }
  const std::vector<Entry>& entries() const { return entries_; }

  // nullptr for an unknown name.
  const Entry* find(const std::string& name) const {
    for (const Entry& entry : entries_) {
      if (entry.name == name) return &entry;
    }
    return nullptr;
  }
  bool contains(const std::string& name) const { return find(name) != nullptr; }

  // The entry for `name`; std::invalid_argument naming the known ones otherwise.
  const Entry& at(const std::string& name) const {
    if (const Entry* entry = find(name)) return *entry;
    throw std::invalid_argument(unknownMessage(name));
  }

  // "unknown <what> 'name' (did you mean ...?) (known: ...)".
  std::string unknownMessage(const std::string& name) const {
    return "unknown " + what_ + " '" + name + "'" + typoSuggestion(name, names()) + " (known: " + namesJoined() + ")";
  }

  // In table order (the first is the default where a variation point has one).
  std::vector<std::string> names() const {
    std::vector<std::string> result;
    result.reserve(entries_.size());
    for (const Entry& entry : entries_) result.push_back(entry.name);
    return result;
  }

  std::string namesJoined(const char* separator = ", ") const {
    std::string joined;
    for (const Entry& entry : entries_) joined += (joined.empty() ? "" : separator) + entry.name;
    return joined;
  }

 private:
  std::string what_;
  std::vector<Entry> entries_;
};

}  // namespace vrm_sim
