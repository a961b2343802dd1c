#include "vrm_msgs/publish.h"

namespace vrm_msgs {

PublishLedger& PublishLedger::instance() {
  static PublishLedger ledger;
  return ledger;
}

void PublishLedger::record(const boost::shared_ptr<const void>& message) {
  std::lock_guard<std::mutex> lock(mutex_);
  recent_.emplace_back(message);
  if (recent_.size() > kCapacity) recent_.pop_front();
  ++recorded_;
}

bool PublishLedger::contains(const void* message) const {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = recent_.rbegin(); it != recent_.rend(); ++it) {
    const boost::shared_ptr<const void> alive = it->lock();
    if (alive && alive.get() == message) return true;
  }
  return false;
}

std::size_t PublishLedger::recorded() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return recorded_;
}

}  // namespace vrm_msgs
