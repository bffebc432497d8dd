// Progress reporting and cooperative cancellation, shared between a worker
// (build, trace) and whoever watches it from another thread.
#pragma once
#include <atomic>
#include <cstdint>
#include <stdexcept>

namespace bsp {

struct Cancelled : std::runtime_error {
    Cancelled() : std::runtime_error("cancelled") {}
};

class Progress {
public:
    // Work is counted in fixed-point units of kScale so that workers can add
    // with one atomic integer add and the total stays exact.
    static constexpr uint64_t kScale = uint64_t(1) << 52;

    // Ready for the next job: nothing done and no cancel pending.
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
        if (cancelled()) throw Cancelled();
    }

private:
    std::atomic<uint64_t> done_{0};
    std::atomic<bool> cancelled_{false};
};

}  // namespace bsp
