// A least-significant-digit radix sort of plain values by an integer key:
// stable, so values of equal keys keep their order. The kd builder sorts its
// events with it, the sweep builder its long projection lists
// (builders/projection_sort.hpp), the tracer its incoherent rays
// (trace/ray_order.cpp).
#pragma once
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <utility>
#include <vector>

namespace bsp {

// Sorts data[0, n) by key_of(value), a key of kPasses * kBits bits, in
// kPasses passes of kBits through tmp (room for n values). Returns where the
// sorted values are: data after an even number of passes, tmp after an odd.
template <int kBits, int kPasses, class T, class KeyOf>
T* radix_sort(T* data, T* tmp, size_t n, KeyOf key_of) {
    constexpr size_t kBuckets = size_t(1) << kBits;
    constexpr uint64_t kDigit = kBuckets - 1;
    // Every pass's counts in one read of the values.
    std::vector<size_t> count(static_cast<size_t>(kPasses) * kBuckets, 0);
    for (size_t i = 0; i < n; ++i) {
        const uint64_t key = key_of(data[i]);
        for (int p = 0; p < kPasses; ++p) ++count[p * kBuckets + ((key >> (p * kBits)) & kDigit)];
    }
    for (int p = 0; p < kPasses; ++p) {
        size_t* c = count.data() + p * kBuckets;
        size_t sum = 0;
        for (size_t b = 0; b < kBuckets; ++b) sum += std::exchange(c[b], sum);
        for (size_t i = 0; i < n; ++i) tmp[c[(key_of(data[i]) >> (p * kBits)) & kDigit]++] = data[i];
        std::swap(data, tmp);
    }
    return data;
}

// A float's bits made to order as the floats do (a key for radix_sort), -0
// taken as +0, which compares equal to it: negative floats have all their
// bits flipped, the others only their sign bit.
inline uint32_t float_order_bits(float x) {
    const float v = x == 0.0f ? 0.0f : x;
    uint32_t u;
    std::memcpy(&u, &v, sizeof u);
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

}  // namespace bsp
