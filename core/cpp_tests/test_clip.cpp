// Bounds of a triangle clipped to a box (clip.hpp, the kd builder's "perfect
// splits"): exact where nothing is interpolated, and never smaller than the
// true clipped part.
#include <gtest/gtest.h>

#include <random>

#include "clip.hpp"

namespace bsp {
namespace {

bool inside(const Box& b, double x, double y, double z, double pad = 0.0) {
    return x >= b.lo.x - pad && x <= b.hi.x + pad && y >= b.lo.y - pad && y <= b.hi.y + pad &&
           z >= b.lo.z - pad && z <= b.hi.z + pad;
}

TEST(Clip, AxisAlignedCutsAreExact) {
    // The square [1, 2]^2 lies wholly under the hypotenuse x + y = 4.
    const Triangle t{{{0, 0, 0}, {4, 0, 0}, {0, 4, 0}}};
    const Box b = clipped_bounds(t, {{1, 1, -1}, {2, 2, 1}});
    EXPECT_EQ(b.lo.x, 1.0f);
    EXPECT_EQ(b.lo.y, 1.0f);
    EXPECT_EQ(b.hi.x, 2.0f);
    EXPECT_EQ(b.hi.y, 2.0f);
    EXPECT_EQ(b.lo.z, 0.0f);
    EXPECT_EQ(b.hi.z, 0.0f);
}

TEST(Clip, MissingBoxGivesEmptyBounds) {
    const Triangle t{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    EXPECT_TRUE(clipped_bounds(t, {{0.8f, 0.8f, -1}, {2, 2, 1}}).empty());
}

TEST(Clip, BoundsContainTheClippedTriangle) {
    // Random triangles and boxes: every point of the triangle (in double)
    // inside the box lies in the clipped bounds, and on its side of a split.
    std::mt19937 gen(13);
    std::uniform_real_distribution<float> x(-2.0f, 2.0f);
    std::uniform_real_distribution<double> w(0.0, 1.0);
    for (int i = 0; i < 300; ++i) {
        const Triangle t{{{x(gen), x(gen), x(gen)}, {x(gen), x(gen), x(gen)},
                          {x(gen), x(gen), x(gen)}}};
        Box box;
        box.extend(Vec3(x(gen), x(gen), x(gen)));
        box.extend(Vec3(x(gen), x(gen), x(gen)));
        const int axis = i % 3;
        const float pos = 0.5f * (box.lo[axis] + box.hi[axis]);
        const Box whole = clipped_bounds(t, box);
        Box below, above;
        split_clipped_bounds(t, box, axis, pos, below, above);
        EXPECT_FALSE(below.hi[axis] > pos);
        EXPECT_FALSE(above.lo[axis] < pos);
        for (int j = 0; j < 200; ++j) {
            double a = w(gen), b = w(gen);
            if (a + b > 1.0) a = 1.0 - a, b = 1.0 - b;
            double p[3];
            for (int k = 0; k < 3; ++k)
                p[k] = t.v[0][k] + a * (double(t.v[1][k]) - t.v[0][k]) +
                       b * (double(t.v[2][k]) - t.v[0][k]);
            if (!inside(box, p[0], p[1], p[2])) continue;
            // The sample itself rounds a little: allow that, not more.
            const double pad = 1e-6;
            EXPECT_TRUE(inside(whole, p[0], p[1], p[2], pad)) << "triangle " << i;
            const Box& side = p[axis] <= pos ? below : above;
            EXPECT_TRUE(inside(side, p[0], p[1], p[2], pad)) << "triangle " << i;
        }
    }
}

}  // namespace
}  // namespace bsp
