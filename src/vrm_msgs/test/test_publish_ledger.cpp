#include <gtest/gtest.h>

#include <boost/make_shared.hpp>

#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/publish.h"

TEST(PublishLedger, IsOffByDefault) { EXPECT_FALSE(vrm_msgs::PublishLedger::instance().enabled()); }

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

TEST(PublishLedger, RecordsPublishesOnlyWhileEnabled) {
  auto& ledger = vrm_msgs::PublishLedger::instance();
  ledger.setEnabled(false);
  auto unnoted = boost::make_shared<vrm_msgs::EyeState>();
  const std::size_t before = ledger.recorded();
  EXPECT_FALSE(ledger.recordIfEnabled(unnoted)) << "recording must be off by default / when disabled";
  EXPECT_EQ(ledger.recorded(), before);
  EXPECT_FALSE(ledger.contains(unnoted.get()));

  ledger.setEnabled(true);
  EXPECT_TRUE(ledger.enabled());
  auto noted = boost::make_shared<vrm_msgs::EyeState>();
  EXPECT_TRUE(ledger.recordIfEnabled(noted));
  EXPECT_EQ(ledger.recorded(), before + 1);
  EXPECT_TRUE(ledger.contains(noted.get()));
  EXPECT_FALSE(ledger.contains(unnoted.get()));
  ledger.setEnabled(false);
}
