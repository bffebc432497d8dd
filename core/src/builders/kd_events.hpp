// The kd builder's events and the stack of memory their lists live in.
#pragma once
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <utility>
#include <memory>
#include <vector>

#include "builders/memory.hpp"
#include "radix_sort.hpp"

namespace bsp {

enum EventType : uint32_t { kEnd = 0, kPlanar = 1, kStart = 2 };

// 8 bytes: position plus (triangle << 2 | type). Ends sort before planar
// before starts at equal positions, which the sweep relies on.
struct Event {
    float pos;
    uint32_t key;
    // Left uninitialised: lists are sized before they are written.
    Event() {}
    Event(float p, uint32_t k) : pos(p), key(k) {}
    uint32_t tri() const { return key >> 2; }
    uint32_t type() const { return key & 3u; }
    bool operator<(const Event& o) const {
        return pos < o.pos || (pos == o.pos && (key & 3u) < (o.key & 3u));
    }
};

// Sorts events into Event::operator<'s order (equal ones keep their order)
// by a least-significant-digit radix sort on (position, type): four passes
// of 9 bits over a 36-bit key, through `tmp` (as large as `events`). At the
// root, where 2N events per axis are sorted, it took a quarter of
// std::sort's time.
inline void radix_sort_events(std::vector<Event>& events, std::vector<Event>& tmp);

// The event's sort key: its position's bits made to order as the floats do
// (-0 taken as +0, which compares equal to it), then its type.
inline uint64_t event_sort_key(const Event& e) {
    return uint64_t(float_order_bits(e.pos)) << 2 | e.type();
}

inline void radix_sort_events(std::vector<Event>& events, std::vector<Event>& tmp) {
    tmp.resize(events.size());
    if (radix_sort<9, 4>(events.data(), tmp.data(), events.size(), event_sort_key) !=
        events.data())
        events.swap(tmp);
}

// A node's sorted events along one axis, inside an EventStack's block.
struct EventSpan {
    Event* data = nullptr;
    size_t size = 0;
    Event* begin() const { return data; }
    Event* end() const { return data + size; }
    const Event& operator[](size_t i) const { return data[i]; }
};

// A build task's event lists, allocated as on a stack. A node takes room for
// its right child's lists on top (its left child's lists overwrite its own
// in place) and gives everything above its mark back once both subtrees
// are built, so a depth-first build reuses the same memory from node to
// node instead of asking malloc for six lists at every split. Blocks never
// move, so spans stay valid while the stack grows, and a block, once
// allocated and charged to the memory budget, stays with the task.
class EventStack {
public:
    struct Mark {
        size_t block = 0, top = 0;
    };

    // A new block holds at least this many events, so that a small task's
    // lists share one block rather than each asking malloc for its own.
    static constexpr size_t kMinBlockEvents = 4096;

    // `block_events`: the size of a new block, unless a list needs more.
    explicit EventStack(size_t block_events)
        : block_events_(std::max(block_events, kMinBlockEvents)) {}

    Mark mark() const { return {current_, top_}; }
    void release(Mark m) {
        current_ = m.block;
        top_ = m.top;
    }

    // Room for n events on top of the stack.
    Event* push(size_t n, TaskCredit& credit, int depth) {
        while (blocks_.empty() || top_ + n > blocks_[current_].size) {
            if (!blocks_.empty() && current_ + 1 < blocks_.size() &&
                blocks_[current_ + 1].size >= n) {
                ++current_;  // a block left over from an earlier, deeper branch
            } else {
                add_block(n, credit, depth);
            }
            top_ = 0;
        }
        Event* p = blocks_[current_].data.get() + top_;
        top_ += n;
        return p;
    }

    // Gives back the last push's unused end: it used `used` of its n events.
    void shrink_last(Event* last, size_t used) {
        top_ = size_t(last - blocks_[current_].data.get()) + used;
    }

    EventStack(const EventStack&) = delete;
    EventStack& operator=(const EventStack&) = delete;
    ~EventStack() {
        if (credit_) credit_->release(charged_);
    }

private:
    struct Block {
        std::unique_ptr<Event[]> data;
        size_t size = 0;
    };
    size_t block_events_;
    std::vector<Block> blocks_;
    size_t current_ = 0, top_ = 0;
    TaskCredit* credit_ = nullptr;  // the task's, which outlives the stack
    uint64_t charged_ = 0;          // the blocks' bytes in the memory budget

    // A new block after the current one, for at least n events; blocks
    // above the current one (too small for n) are freed first.
    void add_block(size_t n, TaskCredit& credit, int depth) {
        credit_ = &credit;
        const size_t first = blocks_.empty() ? 0 : current_ + 1;
        for (size_t i = first; i < blocks_.size(); ++i) {
            credit.release(blocks_[i].size * sizeof(Event));
            charged_ -= blocks_[i].size * sizeof(Event);
        }
        blocks_.resize(first);
        const size_t size = std::max(n, block_events_);
        credit.charge(size * sizeof(Event), depth, "the children's event lists");
        charged_ += size * sizeof(Event);
        blocks_.push_back({std::unique_ptr<Event[]>(new Event[size]), size});
        current_ = first;
    }
};

}  // namespace bsp
