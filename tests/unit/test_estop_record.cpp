// comm::EstopRecord: how the latch and each EDP follow the operators' commands and the latch's
// announcements without trusting any sender's clock (docs/operating.md "Emergency stop").
#include <gtest/gtest.h>

#include "mrroc/comm/estop_record.hpp"

using mrroc::EstopCommandRef;
using mrroc::comm::EstopRecord;

namespace {
const EstopCommandRef kOperatorStop{"ui#10", 100};
const EstopCommandRef kOperatorRelease{"ui#10", 101};
const EstopCommandRef kForged{"ui#66", INT64_MAX};
}  // namespace

TEST(EstopRecord, AnEngageHoldsUntilAnOperatorsReleaseAndItsCopiesCountOnce) {
  EstopRecord r;
  EXPECT_FALSE(r.holding());
  EXPECT_TRUE(r.engage(kOperatorStop));
  EXPECT_FALSE(r.engage(kOperatorStop));  // a copy
  EXPECT_TRUE(r.holding());
  const auto ended = r.release(kOperatorRelease);
  ASSERT_TRUE(ended.has_value());
  ASSERT_EQ(ended->size(), 1u);
  EXPECT_EQ(ended->front(), kOperatorStop);
  EXPECT_FALSE(r.holding());
  // A late copy of the ENGAGE released stops nothing; a copy of the RELEASE is not obeyed twice.
  EXPECT_FALSE(r.engage(kOperatorStop));
  EXPECT_FALSE(r.holding());
  EXPECT_FALSE(r.release(kOperatorRelease).has_value());
  // A new ENGAGE holds again, and a new RELEASE ends it.
  EXPECT_TRUE(r.engage({"ui#10", 102}));
  EXPECT_TRUE(r.holding());
  EXPECT_TRUE(r.release({"ui#10", 103}).has_value());
  EXPECT_FALSE(r.holding());
}

TEST(EstopRecord, AReleasedAnnouncementEndsOnlyTheEngagesItNames) {
  // The latch heard a forged ENGAGE and the operator's RELEASE; the EDP obeyed an ENGAGE the latch
  // never heard. The latch's RELEASED names only the forged one: the EDP stays stopped.
  EstopRecord latch;
  EstopRecord edp;
  EXPECT_TRUE(latch.engage(kForged));
  EXPECT_TRUE(edp.engage(kForged));
  const auto ended = latch.release(kOperatorRelease);
  ASSERT_TRUE(ended.has_value());
  EXPECT_TRUE(edp.release(kOperatorRelease).has_value());
  EXPECT_TRUE(edp.engage(kOperatorStop));  // the latch never hears this one
  EXPECT_FALSE(edp.latched_released(*ended));
  EXPECT_TRUE(edp.holding());
  EXPECT_EQ(edp.held().front(), kOperatorStop);
  // An announcement naming it (the latch heard it and a RELEASE) ends it.
  EXPECT_TRUE(edp.latched_released({kOperatorStop}));
  EXPECT_FALSE(edp.holding());
}

TEST(EstopRecord, AStopHeldForSeveralEngagesEndsWhenEveryOneIsNamed) {
  EstopRecord edp;
  EXPECT_TRUE(edp.engage({"ui#1", 5}));
  EXPECT_TRUE(edp.engage({"ui#2", 9}));
  EXPECT_FALSE(edp.latched_released({{"ui#1", 5}}));
  EXPECT_TRUE(edp.holding());
  EXPECT_TRUE(edp.latched_released({{"ui#2", 9}}));
  EXPECT_FALSE(edp.holding());
  // Nothing held: an announcement changes nothing (and says it did not empty anything).
  EXPECT_FALSE(edp.latched_released({{"ui#2", 9}}));
}

TEST(EstopRecord, EngagedAnnouncementsHoldWhatIsNotReleasedAndOnlyThat) {
  EstopRecord edp;
  EXPECT_TRUE(edp.engage(kOperatorStop));
  ASSERT_TRUE(edp.release(kOperatorRelease).has_value());
  // The latch has not heard the RELEASE yet: its ENGAGED names the stop released here.
  EXPECT_FALSE(edp.latched_engaged({kOperatorStop}, "launch#4"));
  EXPECT_FALSE(edp.holding());
  // An ENGAGE this EDP missed: held, and released by the announcement that names it.
  EXPECT_TRUE(edp.latched_engaged({kOperatorStop, {"ui#11", 7}}, "launch#4"));
  ASSERT_EQ(edp.held().size(), 1u);
  EXPECT_EQ(edp.held().front(), (EstopCommandRef{"ui#11", 7}));
  EXPECT_TRUE(edp.latched_released({{"ui#11", 7}}));
  // An ENGAGED naming nothing holds as the announcer's: no announcement can name that one.
  EXPECT_TRUE(edp.latched_engaged({}, "launch#4"));
  EXPECT_FALSE(edp.latched_released({{"launch#4", 0}}));
  EXPECT_TRUE(edp.holding());
  ASSERT_TRUE(edp.release({"ui#10", 104}).has_value());
  EXPECT_FALSE(edp.holding());
}

TEST(EstopRecord, CommandsWithoutNumbersAreNeverTakenAsCopiesOfReleasedOnes) {
  EstopRecord r;
  EXPECT_TRUE(r.engage({"old-tool", 0}));
  ASSERT_TRUE(r.release({"old-tool", 0}).has_value());
  EXPECT_TRUE(r.engage({"old-tool", 0}));  // the same name again: a new stop, taken
  EXPECT_TRUE(r.holding());
  EXPECT_FALSE(r.latched_released({{"old-tool", 0}}));  // cannot be named: still held
  ASSERT_TRUE(r.release({"old-tool", 0}).has_value());
  EXPECT_FALSE(r.holding());
}

TEST(EstopRecord, AFloodOfEngagesHoldsUntilAnOperatorsRelease) {
  EstopRecord r;
  for (std::int64_t i = 1; i <= 40; ++i) r.engage({"flood", i});
  EXPECT_TRUE(r.overflowed());
  EXPECT_EQ(r.held().size(), EstopRecord::kMaxHeld);
  std::vector<EstopCommandRef> all(r.held().begin(), r.held().end());
  EXPECT_FALSE(r.latched_released(all));  // the ones pushed out are not named
  EXPECT_TRUE(r.holding());
  ASSERT_TRUE(r.release(kOperatorRelease).has_value());
  EXPECT_FALSE(r.holding());
}
