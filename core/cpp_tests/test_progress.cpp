// Progress's test hold (hold_at_check): the n-th check waits for a cancel
// from another thread, then throws; the checks before it pass, and nothing
// waits once the hold is spent or disarmed.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "progress.hpp"

namespace bsp {
namespace {

TEST(Progress, HeldCheckWaitsForTheCancelThenThrows) {
    Progress p;
    p.hold_at_check(3);
    EXPECT_FALSE(p.held());
    int passed = 0;
    bool threw = false;
    std::atomic<bool> ended{false};  // a broken hold: the worker ends, nothing hangs
    std::thread work([&] {
        try {
            for (int i = 0; i < 100; ++i) {
                p.check();
                ++passed;
            }
        } catch (const Cancelled&) {
            threw = true;
        }
        ended = true;
    });
    // The worker cannot get past its third check before this cancel, so it
    // has passed exactly two whatever the scheduling.
    while (!p.held() && !ended) std::this_thread::yield();
    EXPECT_TRUE(p.held());
    p.cancel();
    work.join();
    EXPECT_TRUE(threw);
    EXPECT_EQ(passed, 2);
}

TEST(Progress, ASpentOrDisarmedHoldWaitsNoMore) {
    Progress p;
    p.hold_at_check(1);
    p.cancel();  // already cancelled: the held check returns at once and throws
    EXPECT_THROW(p.check(), Cancelled);
    EXPECT_TRUE(p.held());
    p.reset();   // the hold was spent by that check
    for (int i = 0; i < 1000; ++i) p.check();
    p.hold_at_check(2);
    p.hold_at_check(0);  // disarmed
    EXPECT_FALSE(p.held());
    for (int i = 0; i < 1000; ++i) p.check();
}

}  // namespace
}  // namespace bsp
