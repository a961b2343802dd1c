#pragma once
// Zero-copy publishing for nodelets (the project's rule: allocate Msg::Ptr, fill, publish the pointer, never touch it).
// While the process-wide ledger is enabled, every message published through publishShared() is noted in it, so a
// graph test loaded in the same nodelet manager (vrm_graph/zero_copy_probe) can prove that a subscriber received the
// very object that was published. Recording is opt-in and off by default: production publishes then cost one
// relaxed atomic load, no mutex.

#include <ros/publisher.h>

#include <atomic>
#include <boost/shared_ptr.hpp>
#include <boost/weak_ptr.hpp>
#include <cstddef>
#include <deque>
#include <mutex>

namespace vrm_msgs {

class PublishLedger {
 public:
  static PublishLedger& instance();

  // Whoever needs the ledger (the zero-copy probe, tests) switches it on; messages published before are not noted.
  void setEnabled(bool enabled) { enabled_.store(enabled, std::memory_order_release); }
  bool enabled() const { return enabled_.load(std::memory_order_acquire); }

  // Notes the message regardless of enabled() (tests call it directly).
  void record(const boost::shared_ptr<const void>& message);
  // Notes the message only while enabled(); returns whether it did. What publishShared() does before publishing.
  bool recordIfEnabled(const boost::shared_ptr<const void>& message) {
    if (!enabled_.load(std::memory_order_relaxed)) return false;
    record(message);
    return true;
  }
  // True while the message at this address is alive and was noted. Expired entries never match, so a reused
  // address cannot give a false positive.
  bool contains(const void* message) const;
  std::size_t recorded() const;

 private:
  static constexpr std::size_t kCapacity = 4096;
  std::atomic<bool> enabled_{false};
  mutable std::mutex mutex_;
  std::deque<boost::weak_ptr<const void>> recent_;
  std::size_t recorded_ = 0;
};

template <class M>
void publishShared(const ros::Publisher& publisher, boost::shared_ptr<M> message) {
  boost::shared_ptr<const M> frozen(std::move(message));
  PublishLedger::instance().recordIfEnabled(frozen);
  publisher.publish(frozen);
}

}  // namespace vrm_msgs
