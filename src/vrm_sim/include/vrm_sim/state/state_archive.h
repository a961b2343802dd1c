#pragma once
// StateArchive: one function per class moves its mutable state both ways (issue 39 §1, checkpoints). A class with
// state writes
//     void transferState(StateArchive& archive) { archive(a_)(b_)(c_); }
// and the same call saves (archive.saving()) or loads (archive.loading()) — so a member cannot be saved without being
// loaded, or in another order. Values go as their bytes (doubles bit for bit: a restored World must hash like the
// original), containers with their length. The format is for checkpoints of this build on this machine (the journal
// beside it is the portable record), not for exchange: no endianness or padding conversion, only a version check.
//
// Loading checks every length against what is left and every section tag, and throws StateError naming the section
// where the bytes stopped making sense — a truncated or foreign checkpoint is refused, never half applied by a caller
// that loads into a fresh object first.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <cstring>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace vrm_sim {

class StateError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class StateArchive;

namespace state_detail {
template <typename T, typename = void>
struct HasTransfer : std::false_type {};
template <typename T>
struct HasTransfer<T, std::void_t<decltype(std::declval<T&>().transferState(std::declval<StateArchive&>()))>>
    : std::true_type {};
// Values whose bytes are the value (a vector of them moves as one block).
template <typename T>
struct Plain : std::bool_constant<std::is_arithmetic_v<T> || std::is_enum_v<T>> {};
template <typename Scalar, int Rows, int Cols, int Options, int MaxRows, int MaxCols>
struct Plain<Eigen::Matrix<Scalar, Rows, Cols, Options, MaxRows, MaxCols>>
    : std::bool_constant<(Rows > 0 && Cols > 0 && std::is_arithmetic_v<Scalar>)> {};
template <typename T, std::size_t N>
struct Plain<std::array<T, N>> : Plain<T> {};
}  // namespace state_detail

class StateArchive {
 public:
  // An archive that saves into bytes(); `expected_bytes` (e.g. the last checkpoint's size) is reserved at once, so a
  // periodic checkpoint does not grow its buffer step by step (each growth a copy and, at this size, fresh pages).
  static StateArchive saver(std::size_t expected_bytes = 0) {
    StateArchive archive(nullptr, 0);
    archive.output_.reserve(expected_bytes);
    return archive;
  }
  // An archive that saves into `buffer`'s memory (emptied, its capacity kept): a periodic checkpoint that hands its
  // last buffer back touches no fresh pages (in a VM each first touch of a page is a fault of several µs).
  static StateArchive saverInto(std::string&& buffer) {
    StateArchive archive(nullptr, 0);
    archive.output_ = std::move(buffer);
    archive.output_.clear();
    return archive;
  }
  // An archive that loads from `data` (not copied: it must outlive the archive).
  static StateArchive loader(const std::string& data) { return StateArchive(data.data(), data.size()); }

  bool loading() const { return input_ != nullptr; }
  bool saving() const { return !loading(); }
  const std::string& bytes() const { return output_; }
  std::string takeBytes() { return std::move(output_); }
  std::size_t remaining() const { return size_ - position_; }
  bool atEnd() const { return position_ == size_; }

  // A named mark: saved as its text, checked when loading, so an error names where the stream went wrong.
  StateArchive& section(const char* name) {
    const std::size_t length = std::strlen(name);
    if (saving()) {
      put(name, length);
    } else {
      std::string found(length, '\0');
      get(found.data(), length, name);
      if (found != name) fail("section '" + std::string(name) + "' expected, found '" + printable(found) + "'");
      section_ = name;
    }
    return *this;
  }

  // Any value: arithmetic and enums as bytes, Eigen matrices and transforms as their coefficients, the standard
  // containers element by element, a class with transferState() through it.
  template <typename T>
  StateArchive& operator()(T& value) {
    transfer(value);
    return *this;
  }
  // Saving only (a const member of a const object), e.g. a check value: loading a const is a programming error.
  template <typename T>
  StateArchive& save(const T& value) {
    if (loading()) fail("save() while loading");
    T copy = value;
    transfer(copy);
    return *this;
  }
  // A value whose loaded copy must equal the live one (a configuration the state depends on, e.g. a size).
  template <typename T>
  StateArchive& expect(const T& value, const char* what) {
    T copy = value;
    transfer(copy);
    if (loading() && !(copy == value)) fail(std::string(what) + " differs from the checkpoint's");
    return *this;
  }

  [[noreturn]] void fail(const std::string& what) const {
    throw StateError("checkpoint" + (section_.empty() ? std::string() : " (in " + section_ + ")") + ": " + what);
  }

 private:
  StateArchive(const char* input, std::size_t size) : input_(input), size_(size) {}

  static std::string printable(const std::string& text) {
    std::string out;
    for (char c : text) out += (c >= 32 && c < 127) ? c : '?';
    return out;
  }

  void put(const void* data, std::size_t size) { output_.append(static_cast<const char*>(data), size); }
  void get(void* data, std::size_t size, const char* what) {
    if (size > remaining()) {
      fail(std::string("ends inside ") + what + " (" + std::to_string(remaining()) + " bytes left, " +
           std::to_string(size) + " needed)");
    }
    std::memcpy(data, input_ + position_, size);
    position_ += size;
  }
  template <typename T>
  void raw(T& value) {
    if (saving()) {
      put(&value, sizeof(T));
    } else {
      get(&value, sizeof(T), "a value");
    }
  }
  // A container length, checked against the bytes left (each element takes at least `min_element_bytes`).
  std::size_t length(std::size_t value, std::size_t min_element_bytes) {
    std::uint64_t count = value;
    raw(count);
    if (loading() && min_element_bytes > 0 && count > remaining() / min_element_bytes) {
      fail("a length of " + std::to_string(count) + " beyond the " + std::to_string(remaining()) + " bytes left");
    }
    return static_cast<std::size_t>(count);
  }

  template <typename T>
  void transfer(T& value) {
    if constexpr (state_detail::HasTransfer<T>::value) {
      value.transferState(*this);
    } else if constexpr (std::is_arithmetic_v<T> || std::is_enum_v<T>) {
      raw(value);
    } else {
      transferCompound(value);
    }
  }

  template <typename Scalar, int Rows, int Cols, int Options, int MaxRows, int MaxCols>
  void transferCompound(Eigen::Matrix<Scalar, Rows, Cols, Options, MaxRows, MaxCols>& value) {
    static_assert(Rows > 0 && Cols > 0, "fixed-size Eigen matrices only");
    for (Eigen::Index i = 0; i < value.size(); ++i) raw(value.data()[i]);
  }
  template <typename Scalar, int Dim, int Mode, int Options>
  void transferCompound(Eigen::Transform<Scalar, Dim, Mode, Options>& value) {
    transferCompound(value.matrix());
  }
  template <typename Scalar, int Options>
  void transferCompound(Eigen::Quaternion<Scalar, Options>& value) {
    transferCompound(value.coeffs());
  }
  void transferCompound(std::string& value) {
    const std::size_t count = length(value.size(), 1);
    if (loading()) value.resize(count);
    if (saving()) {
      put(value.data(), count);
    } else {
      get(value.data(), count, "a string");
    }
  }
  template <typename T, typename A>
  void transferCompound(std::vector<T, A>& value) {
    const std::size_t count = length(value.size(), 1);
    if (loading()) value.resize(count);
    if constexpr (state_detail::Plain<T>::value && !std::is_same_v<T, bool>) {
      static_assert(sizeof(T) % alignof(T) == 0, "no padding between elements");
      if (saving()) {
        put(value.data(), count * sizeof(T));
      } else {
        get(value.data(), count * sizeof(T), "a vector");
      }
    } else if constexpr (std::is_same_v<T, bool>) {
      for (std::size_t i = 0; i < count; ++i) {
        bool element = saving() ? static_cast<bool>(value[i]) : false;
        raw(element);
        if (loading()) value[i] = element;
      }
    } else {
      for (auto& element : value) transfer(element);
    }
  }
  template <typename T>
  void transferCompound(std::deque<T>& value) {
    const std::size_t count = length(value.size(), 1);
    if (loading()) value.resize(count);
    for (auto& element : value) transfer(element);
  }
  template <typename T, std::size_t N>
  void transferCompound(std::array<T, N>& value) {
    for (auto& element : value) transfer(element);
  }
  template <typename A, typename B>
  void transferCompound(std::pair<A, B>& value) {
    transfer(value.first);
    transfer(value.second);
  }
  template <typename T>
  void transferCompound(std::optional<T>& value) {
    bool present = value.has_value();
    raw(present);
    if (loading()) {
      if (present) {
        value.emplace();
      } else {
        value.reset();
      }
    }
    if (present) transfer(*value);
  }
  template <typename K, typename V, typename C, typename A>
  void transferCompound(std::map<K, V, C, A>& value) {
    const std::size_t count = length(value.size(), 1);
    if (saving()) {
      for (auto& [key, mapped] : value) {
        K key_copy = key;
        transfer(key_copy);
        transfer(mapped);
      }
      return;
    }
    value.clear();
    for (std::size_t i = 0; i < count; ++i) {
      K key{};
      transfer(key);
      transfer(value[key]);
    }
  }
  template <typename K, typename C, typename A>
  void transferCompound(std::set<K, C, A>& value) {
    const std::size_t count = length(value.size(), 1);
    if (saving()) {
      for (const K& key : value) {
        K key_copy = key;
        transfer(key_copy);
      }
      return;
    }
    value.clear();
    for (std::size_t i = 0; i < count; ++i) {
      K key{};
      transfer(key);
      value.insert(std::move(key));
    }
  }
  template <typename T>
  void transferCompound(std::unique_ptr<T>& value) {
    // The object exists on both sides (built from the same scene); its presence is part of the state.
    bool present = value != nullptr;
    raw(present);
    if (loading() && present != (value != nullptr)) fail("an object present on one side only");
    if (present) transfer(*value);
  }

  const char* input_ = nullptr;
  std::size_t size_ = 0;
  std::size_t position_ = 0;
  std::string output_;
  std::string section_;
};

}  // namespace vrm_sim
