// Progress reporting and cooperative cancellation, shared between a worker
// (build, trace) and whoever watches it from another thread.
#pragma once
#include <atomic>
#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <thread>

namespace bsp {

struct Cancelled : std::runtime_error {
    Cancelled() : std::runtime_error("cancelled") {}
};

class Progress {
public:
    // Work is counted in fixed-point units of kScale so that workers can add
    // with one atomic integer add and the total stays exact.
    static constexpr uint64_t kScale = uint64_t(1) << 52;
    // How long a held check (hold_at_check) waits for cancel() before it
    // lets the work go on: only reached when no cancel comes, i.e. when the
    // test that held the work fails.
    static constexpr std::chrono::seconds kHoldLimit{60};

    // Ready for the next job: nothing done and no cancel pending (a hold,
    // below, stays as it was).
    void reset() {
        done_.store(0, std::memory_order_relaxed);
        cancelled_.store(false, std::memory_order_relaxed);
    }
    void add(uint64_t units) { done_.fetch_add(units, std::memory_order_relaxed); }
    double value() const {
        double v = double(done_.load(std::memory_order_relaxed)) / double(kScale);
        return v > 1.0 ? 1.0 : v;
    }
    void cancel() { cancelled_.store(true, std::memory_order_relaxed); }
    bool cancelled() const { return cancelled_.load(std::memory_order_relaxed); }
    void check() const {
        if (hold_.load(std::memory_order_relaxed) != 0) [[unlikely]] hold();
        if (cancelled()) throw Cancelled();
    }

    // For tests: the n-th check() from now (n >= 1; 0 disarms) waits there
    // until cancel(), then throws. A cancel from another thread thus meets
    // work that provably has not finished, however fast the machine; `held`
    // says the work has reached that check.
    void hold_at_check(uint64_t n) {
        held_.store(false, std::memory_order_relaxed);
        hold_.store(n, std::memory_order_relaxed);
    }
    bool held() const { return held_.load(std::memory_order_acquire); }

private:
    void hold() const {
        // The check that takes the count from 1 to 0 is the one that waits.
        uint64_t left = hold_.load(std::memory_order_relaxed);
        while (left != 0 && !hold_.compare_exchange_weak(left, left - 1,
                                                         std::memory_order_relaxed)) {
        }
        if (left != 1) return;
        held_.store(true, std::memory_order_release);
        const auto until = std::chrono::steady_clock::now() + kHoldLimit;
        while (!cancelled() && std::chrono::steady_clock::now() < until)
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }

    std::atomic<uint64_t> done_{0};
    std::atomic<bool> cancelled_{false};
    mutable std::atomic<uint64_t> hold_{0};
    mutable std::atomic<bool> held_{false};
};

}  // namespace bsp
