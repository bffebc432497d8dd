// The build's memory budget (options.memory_limit_mb), enforced while the
// tree is being built: one atomic byte counter shared by the build tasks.
//
// The builders charge what they allocate, per node and never per triangle:
// build nodes, the leaves' reference arrays, the kd builder's event lists, the
// sweep builder's reference and clipped-polygon pools, and at the end the
// flat tree. Working lists are charged before they are allocated (where their
// size is known beforehand; the sweep builder's polygon pools right after)
// and released when they are freed. The counts are rounded up (an event list
// as if every triangle had two events on each axis), so the budget errs on
// the side of stopping early. The first charge that does not fit stops the
// build: every task throws MemoryLimitExceeded with the same message at its
// next node. Small charges go through a per-task credit (TaskCredit), so
// the shared counter costs next to nothing per node.
#pragma once
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>

namespace bsp {

// A std::bad_alloc (code that handles running out of memory handles this
// too) whose what() says which limit was hit and what the build needed.
// The Python bindings raise it as MemoryError with that message.
class MemoryLimitExceeded : public std::bad_alloc {
public:
    explicit MemoryLimitExceeded(const std::string& message) : message_(message) {}
    const char* what() const noexcept override { return message_.what(); }

private:
    std::runtime_error message_;  // its copies share the text and cannot throw
};

// "12.3 MB" with MB = 2^20 bytes, as memory_limit_mb counts ("45 KB" under 1 MB).
inline std::string format_mb(double bytes) {
    char buf[64];
    const double mb = bytes / (1024.0 * 1024.0);
    if (bytes < 1024) std::snprintf(buf, sizeof buf, "%.0f bytes", bytes);
    else if (mb < 1) std::snprintf(buf, sizeof buf, "%.0f KB", bytes / 1024.0);
    else std::snprintf(buf, sizeof buf, mb < 10 ? "%.2f MB" : "%.1f MB", mb);
    return buf;
}

class MemoryBudget {
public:
    explicit MemoryBudget(double limit_mb)
        : limit_mb_(limit_mb), limit_(limit_mb * 1024.0 * 1024.0) {}

    double limit_mb() const { return limit_mb_; }
    double limit_bytes() const { return limit_; }
    uint64_t used() const { return used_.load(std::memory_order_relaxed); }
    uint64_t peak() const { return peak_.load(std::memory_order_relaxed); }

    // Counts `bytes` more, or, when they do not fit under the limit, stops
    // the build: throws MemoryLimitExceeded naming what asked for them
    // (`what`, e.g. "the children's event lists") and the node's depth.
    void charge(uint64_t bytes, int depth, const char* what) {
        // The total that did not fit, not used() + bytes afterwards: another
        // task may release in between, and the message would then name less
        // than the limit it says was exceeded.
        uint64_t would_be = 0;
        if (!try_charge(bytes, &would_be)) fail(would_be, bytes, depth, what);
    }

    // Counts `bytes` more if they fit under the limit; otherwise stores the
    // total they would have made in *would_be.
    bool try_charge(uint64_t bytes, uint64_t* would_be = nullptr) {
        const uint64_t now = used_.fetch_add(bytes, std::memory_order_relaxed) + bytes;
        if (double(now) > limit_) {
            used_.fetch_sub(bytes, std::memory_order_relaxed);
            if (would_be) *would_be = now;
            return false;
        }
        uint64_t peak = peak_.load(std::memory_order_relaxed);
        while (now > peak && !peak_.compare_exchange_weak(peak, now, std::memory_order_relaxed)) {
        }
        return true;
    }

    void release(uint64_t bytes) { used_.fetch_sub(bytes, std::memory_order_relaxed); }

    // Called at every node: once any task has run over the limit, the others
    // stop too, with the first one's message.
    void check() const {
        if (failed_.load(std::memory_order_relaxed)) throw_stored();
    }

    // Stops the build with `message` (the finished tree's size check).
    [[noreturn]] void fail(const std::string& message) {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            if (message_.empty()) message_ = message;
            failed_.store(true, std::memory_order_relaxed);
        }
        throw_stored();
    }

    // "build needs more than 100 MB (memory_limit_mb=100): " - the start of
    // every message, so the finished-tree check reads like the others.
    std::string headline() const {
        char buf[128];
        std::snprintf(buf, sizeof buf, "build needs more than %g MB (memory_limit_mb=%g): ",
                      limit_mb_, limit_mb_);
        return buf;
    }

private:
    double limit_mb_;
    double limit_;
    std::atomic<uint64_t> used_{0};
    std::atomic<uint64_t> peak_{0};
    std::atomic<bool> failed_{false};
    mutable std::mutex mutex_;
    std::string message_;

    [[noreturn]] void fail(uint64_t needed, uint64_t asked, int depth, const char* what) {
        std::string m = headline() + "it needed at least " + format_mb(double(needed));
        if (depth >= 0) m += " when it stopped at depth " + std::to_string(depth);
        m += std::string(" (") + what + ": " + format_mb(double(asked)) +
             " more); raise memory_limit_mb, or lower max_duplication or max_depth";
        fail(m);
    }

    [[noreturn]] void throw_stored() const {
        std::lock_guard<std::mutex> lock(mutex_);
        throw MemoryLimitExceeded(message_);
    }
};

// One build task's way into the budget (used by that task's thread only).
// Charges under kChunk - nearly all: a node's, a small leaf's - come out of
// a credit drawn from the shared counter kChunk at a time, and releases
// under kChunk go back into it (beyond two chunks, to the counter), so the
// shared atomic counter is touched about once per 64 KB rather than at
// every node. The credit counts as used: the counter errs on the high side,
// by less than two chunks per task. Near the limit a charge takes exactly
// what it misses, so a build stops only when its count does not fit.
class TaskCredit {
public:
    static constexpr uint64_t kChunk = 64 * 1024;

    explicit TaskCredit(MemoryBudget& budget) : budget_(budget) {}
    ~TaskCredit() {
        if (left_) budget_.release(left_);
    }
    TaskCredit(const TaskCredit&) = delete;
    TaskCredit& operator=(const TaskCredit&) = delete;

    MemoryBudget& budget() const { return budget_; }

    void charge(uint64_t bytes, int depth, const char* what) {
        if (bytes >= kChunk) return budget_.charge(bytes, depth, what);
        if (left_ < bytes) {
            if (budget_.try_charge(kChunk)) {
                left_ += kChunk;
            } else {
                budget_.charge(bytes - left_, depth, what);
                left_ = bytes;
            }
        }
        left_ -= bytes;
    }

    void release(uint64_t bytes) {
        if (bytes >= kChunk) return budget_.release(bytes);
        left_ += bytes;
        if (left_ > 2 * kChunk) {
            budget_.release(left_ - kChunk);
            left_ = kChunk;
        }
    }

private:
    MemoryBudget& budget_;
    uint64_t left_ = 0;  // counted as used, not handed out yet
};

// Bytes charged to a task's credit and given back when the charge is
// destroyed or reset (RAII), so working lists are released with their owner.
// A charge can hand parts of itself to other owners (take) or become
// permanent (keep). A charge moved to another task must be handed to that
// task's credit (move_to) before anything else happens there.
class Charge {
public:
    Charge() = default;
    Charge(TaskCredit& credit, uint64_t bytes, int depth, const char* what) : credit_(&credit) {
        credit.charge(bytes, depth, what);
        bytes_ = bytes;
    }
    Charge(Charge&& o) noexcept : credit_(o.credit_), bytes_(std::exchange(o.bytes_, 0)) {}
    Charge& operator=(Charge&& o) noexcept {
        if (this != &o) {
            reset();
            credit_ = o.credit_;
            bytes_ = std::exchange(o.bytes_, 0);
        }
        return *this;
    }
    Charge(const Charge&) = delete;
    Charge& operator=(const Charge&) = delete;
    ~Charge() { reset(); }

    uint64_t bytes() const { return bytes_; }
    void reset() {
        if (credit_ && bytes_) credit_->release(bytes_);
        bytes_ = 0;
    }
    // From now on released into `credit` (this charge moved to its task).
    void move_to(TaskCredit& credit) { credit_ = &credit; }
    // Moves `bytes` of this charge (at most all of it) into a new charge.
    Charge take(uint64_t bytes) {
        Charge c;
        c.credit_ = credit_;
        c.bytes_ = bytes < bytes_ ? bytes : bytes_;
        bytes_ -= c.bytes_;
        return c;
    }
    // Adds another charge's bytes (of the same task) to this one.
    void absorb(Charge&& o) {
        if (!credit_) credit_ = o.credit_;
        bytes_ += std::exchange(o.bytes_, 0);
    }
    // The bytes stay counted until the build ends (build nodes, leaves).
    void keep() { bytes_ = 0; }

private:
    TaskCredit* credit_ = nullptr;
    uint64_t bytes_ = 0;
};

// What one pointer-tree node is charged: more than the object takes in the
// node arena (build_tree.hpp asserts it), which also covers a block's slack.
constexpr uint64_t kBuildNodeBytes = 128;

}  // namespace bsp
