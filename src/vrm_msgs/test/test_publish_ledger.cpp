#include <gtest/gtest.h>

#include <boost/make_shared.hpp>

#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/publish.h"

TEST(PublishLedger, KnowsLiveMessagesOnly) {
  auto& ledger = vrm_msgs::PublishLedger::instance();
  auto message = boost::make_shared<vrm_msgs::EyeState>();
  const void* address = message.get();
  EXPECT_FALSE(ledger.contains(address));
  ledger.record(message);
  EXPECT_TRUE(ledger.contains(address));

  vrm_msgs::EyeState copy = *message;
  EXPECT_FALSE(ledger.contains(&copy));

  message.reset();
  EXPECT_FALSE(ledger.contains(address)) << "an expired message must not match a reused address";
}

TEST(PublishLedger, ForgetsBeyondCapacity) {
  auto& ledger = vrm_msgs::PublishLedger::instance();
  auto first = boost::make_shared<vrm_msgs::EyeState>();
  ledger.record(first);
  std::vector<boost::shared_ptr<vrm_msgs::EyeState>> keep;
  for (int i = 0; i < 5000; ++i) {
    keep.push_back(boost::make_shared<vrm_msgs::EyeState>());
    ledger.record(keep.back());
  }
  EXPECT_FALSE(ledger.contains(first.get()));
  EXPECT_TRUE(ledger.contains(keep.back().get()));
}
