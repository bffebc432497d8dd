// The kd builder's stack of event lists (kd_events.hpp): room is handed out
// and given back like a stack, blocks never move, and every block is in the
// memory budget while the stack holds it.
#include <gtest/gtest.h>

#include <random>

#include "builders/kd_events.hpp"

namespace bsp {
namespace {

constexpr size_t kBlock = 4096;  // the smallest block the stack makes

TEST(EventStack, ReleaseHandsTheSameRoomOutAgain) {
    MemoryBudget budget(64);
    TaskCredit credit(budget);
    EventStack stack(kBlock);
    Event* a = stack.push(100, credit, 0);
    const EventStack::Mark m = stack.mark();
    Event* b = stack.push(50, credit, 1);
    EXPECT_EQ(b, a + 100);  // on top of the first push
    stack.release(m);
    EXPECT_EQ(stack.push(70, credit, 1), b);  // the released room, again
}

TEST(EventStack, ShrinkLastGivesBackTheUnusedEnd) {
    MemoryBudget budget(64);
    TaskCredit credit(budget);
    EventStack stack(kBlock);
    Event* a = stack.push(100, credit, 0);
    stack.shrink_last(a, 30);
    EXPECT_EQ(stack.push(10, credit, 0), a + 30);
}

TEST(EventStack, FullBlockStartsANewOneAndOldEventsStayPut) {
    MemoryBudget budget(64);
    TaskCredit credit(budget);
    EventStack stack(kBlock);
    Event* a = stack.push(kBlock - 10, credit, 0);
    a[0] = Event(1.5f, 7u);
    const EventStack::Mark m = stack.mark();
    Event* big = stack.push(3 * kBlock, credit, 1);  // more than a block: a block of its own
    big[3 * kBlock - 1] = Event(2.5f, 9u);
    EXPECT_EQ(a[0].pos, 1.5f);
    EXPECT_EQ(a[0].key, 7u);
    const uint64_t charged = budget.used();
    EXPECT_GE(charged, (kBlock + 3 * kBlock) * sizeof(Event));
    // Given back and asked for again: the same block, nothing new charged.
    stack.release(m);
    EXPECT_EQ(stack.push(2 * kBlock, credit, 1), big);
    EXPECT_EQ(budget.used(), charged);
}

TEST(EventStack, BlocksAreReleasedWithTheStack) {
    MemoryBudget budget(64);
    TaskCredit credit(budget);
    const uint64_t before = budget.used();
    {
        EventStack stack(kBlock);
        stack.push(10 * kBlock, credit, 0);
        EXPECT_GE(budget.used(), before + 10 * kBlock * sizeof(Event));
    }
    // What is left is the task credit's small reserve, under one chunk.
    EXPECT_LT(budget.used(), before + 2 * TaskCredit::kChunk);
}

TEST(EventStack, ABlockOverTheLimitStopsTheBuild) {
    MemoryBudget budget(1);  // 1 MB
    TaskCredit credit(budget);
    EventStack stack(kBlock);
    EXPECT_THROW(stack.push(1 << 20, credit, 3), MemoryLimitExceeded);  // 8 MB of events
}

TEST(Event, OrdersByPositionThenEndPlanarStart) {
    const Event end(1.0f, 5u << 2 | kEnd), planar(1.0f, 3u << 2 | kPlanar),
        start(1.0f, 1u << 2 | kStart), later(2.0f, 0u << 2 | kEnd);
    EXPECT_TRUE(end < planar);
    EXPECT_TRUE(planar < start);
    EXPECT_TRUE(start < later);
    EXPECT_FALSE(start < end);
    EXPECT_EQ(planar.tri(), 3u);
    EXPECT_EQ(planar.type(), uint32_t(kPlanar));
}

TEST(Event, RadixSortOrdersAsOperatorLessAndKeepsTiesInOrder) {
    std::mt19937 rng(5);
    std::uniform_int_distribution<int> pos(-20, 20), type(0, 2);
    std::vector<Event> events, tmp;
    for (uint32_t t = 0; t < 20000; ++t) {
        // Few distinct positions (many ties), both zeros, tiny and huge values.
        float p = float(pos(rng)) * 0.25f;
        if (t % 97 == 0) p = -0.0f;
        if (t % 89 == 0) p = 1e-38f * float(pos(rng));
        if (t % 83 == 0) p = 3e38f * float(pos(rng) % 2);
        events.emplace_back(p, t << 2 | uint32_t(type(rng)));
    }
    std::vector<Event> expected = events;
    std::stable_sort(expected.begin(), expected.end());
    radix_sort_events(events, tmp);
    ASSERT_EQ(events.size(), expected.size());
    for (size_t i = 0; i < events.size(); ++i) {
        // -0 and +0 are equal to operator<, so stable_sort leaves them
        // mixed as the radix sort does: compare the keys, not the bits.
        EXPECT_EQ(events[i].key, expected[i].key) << i;
        EXPECT_TRUE(events[i].pos == expected[i].pos) << i;
    }
}

}  // namespace
}  // namespace bsp
