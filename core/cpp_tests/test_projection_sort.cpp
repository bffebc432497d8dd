// The sweep builder's sort of its projections (projection_sort.hpp): either
// side of kRadixMinProjections it gives std::sort's floats in std::sort's
// order, which is what keeps the sweep's trees the same.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "builders/projection_sort.hpp"

namespace bsp {
namespace {

uint32_t bits(float x) {
    uint32_t u;
    std::memcpy(&u, &x, sizeof u);
    return u;
}

// Values with many ties, tiny and huge magnitudes, and (if asked) zeros of
// both signs.
std::vector<float> projections(size_t n, unsigned seed, bool zeros) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> pos(-40, 40);
    std::vector<float> v;
    for (size_t i = 0; i < n; ++i) {
        float p = float(pos(rng)) * 0.125f + (i % 3 == 0 ? 1e-3f * float(pos(rng)) : 0.0f);
        if (i % 89 == 0) p = 1e-38f * float(pos(rng));
        if (i % 83 == 0) p = 3e38f * float(pos(rng) % 2);
        if (p == 0.0f) p = !zeros ? 1.0f : (i % 2 ? -0.0f : 0.0f);
        v.push_back(p);
    }
    return v;
}

TEST(ProjectionSort, GivesStdSortsFloatsInItsOrder) {
    std::vector<float> tmp;
    for (size_t n : {size_t(0), size_t(1), size_t(2), size_t(17), kRadixMinProjections - 1,
                     kRadixMinProjections, kRadixMinProjections + 1, size_t(5000)}) {
        std::vector<float> v = projections(n, unsigned(n) + 1, false), expected = v;
        std::sort(expected.begin(), expected.end());
        sort_projections(v, tmp);
        ASSERT_EQ(v.size(), expected.size());
        // Without zeros of both signs the sorted sequence is unique, bit for bit.
        for (size_t i = 0; i < v.size(); ++i) EXPECT_EQ(bits(v[i]), bits(expected[i])) << n << " " << i;
    }
}

TEST(ProjectionSort, KeepsZerosOfBothSignsInTheirOrder) {
    std::vector<float> tmp;
    for (size_t n : {kRadixMinProjections, size_t(3000)}) {
        std::vector<float> v = projections(n, 7, true);
        std::vector<uint32_t> zero_bits;  // the zeros' signs, in input order
        for (float x : v)
            if (x == 0.0f) zero_bits.push_back(bits(x));
        // Both zeros are there, mixed.
        ASSERT_NE(std::count(zero_bits.begin(), zero_bits.end(), bits(0.0f)), 0);
        ASSERT_NE(std::count(zero_bits.begin(), zero_bits.end(), bits(-0.0f)), 0);
        std::vector<float> expected = v;
        std::sort(expected.begin(), expected.end());
        sort_projections(v, tmp);
        std::vector<uint32_t> sorted_zero_bits;
        for (size_t i = 0; i < v.size(); ++i) {
            EXPECT_TRUE(v[i] == expected[i]) << i;  // -0 == +0: the same values
            if (v[i] == 0.0f) sorted_zero_bits.push_back(bits(v[i]));
        }
        EXPECT_EQ(sorted_zero_bits, zero_bits);
    }
}

}  // namespace
}  // namespace bsp
