// The sweep builder's direction helpers (builders/strategies/directions.hpp):
// draw()'s picks are the first m distinct draws of the node's generator,
// whichever look-up it uses, and node_directions() keeps the first of equal
// directions, the axes first for "+" methods.
#include <gtest/gtest.h>

#include <set>
#include <vector>

#include "builders/strategies/directions.hpp"
#include "builders/strategies/strategy.hpp"

namespace bsp {
namespace {

// What draw() promises, written the plain way: draw until m distinct.
std::vector<uint32_t> first_distinct(size_t n, size_t m, Rng rng) {
    std::vector<uint32_t> picked;
    if (m >= n) {
        for (size_t i = 0; i < n; ++i) picked.push_back(uint32_t(i));
        return picked;
    }
    std::set<uint32_t> seen;
    while (picked.size() < m) {
        const uint32_t i = uint32_t(rng.below(n));
        if (seen.insert(i).second) picked.push_back(i);
    }
    return picked;
}

TEST(Draw, PicksTheFirstDistinctDrawsOnBothLookUps) {
    // m up to 64 scans the picks, above it a hash set: the same picks.
    const size_t cases[][2] = {{10, 3}, {10, 9}, {5, 10}, {7, 7}, {100, 64}, {100, 65},
                               {70, 66}, {100000, 1024}, {2000, 1999}};
    for (const auto& c : cases) {
        for (uint64_t seed : {1ull, 2ull, 12345ull}) {
            Rng a(seed), b(seed);
            const std::vector<uint32_t> got = draw(c[0], c[1], a);
            EXPECT_EQ(got, first_distinct(c[0], c[1], b)) << c[0] << " " << c[1];
            EXPECT_EQ(got.size(), std::min(c[0], c[1]));
            EXPECT_EQ(std::set<uint32_t>(got.begin(), got.end()).size(), got.size());
            for (uint32_t i : got) EXPECT_LT(i, c[0]);
        }
    }
}

TEST(NodeDirections, KeepsTheFirstOfEqualDirectionsAxesFirst) {
    // Four triangles in two planes: z = 0 (an axis normal) and x = y
    // (twice each), so the normals strategy can only find two directions.
    const std::vector<Triangle> tris = {
        {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}},  {{{2, 0, 0}, {3, 0, 0}, {2, 1, 0}}},
        {{{0, 0, 0}, {1, 1, 0}, {0, 0, 1}}},  {{{2, 2, 0}, {3, 3, 0}, {2, 2, 1}}}};
    const uint32_t ids[] = {0, 1, 2, 3};
    BuildOptions opt;
    opt.strategy = "normals";
    opt.plus_axes = true;
    opt.k = 3 + 4;
    const auto strategy = make_strategy(opt);
    Rng rng(7);
    std::vector<Vec3> dirs = {{9, 9, 9}};  // whatever was there goes
    node_directions(*strategy, opt, tris, ids, 4, rng, dirs);
    ASSERT_EQ(dirs.size(), 4u);
    auto is = [](const Vec3& d, float x, float y, float z) {
        return d.x == x && d.y == y && d.z == z;
    };
    EXPECT_TRUE(is(dirs[0], 1, 0, 0));
    EXPECT_TRUE(is(dirs[1], 0, 1, 0));
    EXPECT_TRUE(is(dirs[2], 0, 0, 1));  // z = 0's normal is the axis, not kept twice
    EXPECT_NEAR(dirs[3].x, 0.70710678f, 1e-6f);
    EXPECT_NEAR(dirs[3].y, -0.70710678f, 1e-6f);
    EXPECT_EQ(dirs[3].z, 0.0f);
}

}  // namespace
}  // namespace bsp
