#pragma once
// Zero-copy publishing for nodelets (DEVELOPERS.md: allocate Msg::Ptr, fill, publish the pointer, never touch it).
// Every message published through publishShared() is noted in a process-wide ledger, so a graph test loaded in
// the same nodelet manager can prove that a subscriber received the very object that was published.

#include <ros/publisher.h>

#include <boost/shared_ptr.hpp>
#include <boost/weak_ptr.hpp>
#include <cstddef>
#include <deque>
#include <mutex>

namespace vrm_msgs {

class PublishLedger {
 public:
  static PublishLedger& instance();

  void record(const boost::shared_ptr<const void>& message);
  // True while the message at this address is alive and was published through publishShared(). Expired entries
  // never match, so a reused address cannot give a false positive.
  bool contains(const void* message) const;
  std::size_t recorded() const;

 private:
  static constexpr std::size_t kCapacity = 4096;
  mutable std::mutex mutex_;
  std::deque<boost::weak_ptr<const void>> recent_;
  std::size_t recorded_ = 0;
};

template <class M>
void publishShared(const ros::Publisher& publisher, boost::shared_ptr<M> message) {
  boost::shared_ptr<const M> frozen(std::move(message));
  PublishLedger::instance().record(frozen);
  publisher.publish(frozen);
}

}  // namespace vrm_msgs
