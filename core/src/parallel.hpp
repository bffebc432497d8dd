// A minimal parallel-for over index chunks. Work is handed out through an
// atomic counter, so results never depend on which thread ran which chunk.
#pragma once
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace bsp {

inline int resolve_threads(int requested) {
    if (requested > 0) return requested;
    unsigned hw = std::thread::hardware_concurrency();
    return hw == 0 ? 1 : int(hw);
}

// Calls body(begin, end) for consecutive chunks of [0, n). The first exception
// thrown by any chunk stops the hand-out and is rethrown on the caller.
template <class Body>
void parallel_for(size_t n, size_t chunk, int threads, Body&& body) {
    threads = std::max(1, std::min<int>(threads, int((n + chunk - 1) / chunk)));
    std::atomic<size_t> next{0};
    std::atomic<bool> failed{false};
    std::exception_ptr error;
    std::mutex error_mutex;
    auto worker = [&] {
        for (;;) {
            if (failed.load(std::memory_order_relaxed)) return;
            size_t begin = next.fetch_add(chunk);
            if (begin >= n) return;
            try {
                body(begin, std::min(n, begin + chunk));
            } catch (...) {
                std::lock_guard<std::mutex> lock(error_mutex);
                if (!error) error = std::current_exception();
                failed = true;
            }
        }
    };
    std::vector<std::thread> pool;
    for (int i = 1; i < threads; ++i) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();
    if (error) std::rethrow_exception(error);
}

}  // namespace bsp
