// Bounds of a triangle clipped to a box (clip.hpp, the kd builder's "perfect
// splits"): exact where nothing is interpolated, never smaller than the true
// clipped part, and no wider than its bounds rounded outwards to float.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "builders/clip.hpp"

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

TEST(Clip, CutPointsAreExactWhereTheyAreFloats) {
    // The cut x = 0.5 crosses the edge (0.25, 0.75)-(1.25, 1.75) at y = 1, a
    // float, and that is the clipped part's top: the bound is 1 itself, not
    // padded above it (a pad would make a neighbour touching y = 1 from
    // above straddle a split there).
    const Triangle t{{{0.25f, 0.75f, 0}, {1.25f, 1.75f, 0}, {1.25f, 0.75f, 0}}};
    const Box b = clipped_bounds(t, {{-1, -1, -1}, {0.5f, 4, 1}});
    EXPECT_EQ(b.hi.y, 1.0f);
    EXPECT_EQ(b.lo.y, 0.75f);
}

TEST(Clip, AnEdgeCutsTheSameBothWays) {
    // Two triangles sharing an edge list it in opposite directions; the cut
    // point must not depend on the direction, or the neighbours' bounds
    // would disagree by an ulp where they touch.
    std::mt19937 gen(5);
    std::uniform_real_distribution<float> x(-2.0f, 2.0f);
    for (int i = 0; i < 300; ++i) {
        const Vec3 p{x(gen), x(gen), x(gen)}, q{x(gen), x(gen), x(gen)}, r{x(gen), x(gen), x(gen)};
        Box box;
        box.extend(Vec3(x(gen), x(gen), x(gen)));
        box.extend(Vec3(x(gen), x(gen), x(gen)));
        const Box one = clipped_bounds(Triangle{{p, q, r}}, box);
        const Box other = clipped_bounds(Triangle{{q, p, r}}, box);
        for (int k = 0; k < 3; ++k) {
            EXPECT_EQ(one.lo[k], other.lo[k]) << "triangle " << i;
            EXPECT_EQ(one.hi[k], other.hi[k]) << "triangle " << i;
        }
    }
}

TEST(Clip, RandomBoundsAreTheTrueBoundsRoundedOutwards) {
    // A clipped triangle's extreme lies at a vertex of the clipped polygon;
    // computed in long double from the same polygon, the float bounds must
    // hold it and lie within one float ulp of it.
    std::mt19937 gen(7);
    std::uniform_real_distribution<float> x(-2.0f, 2.0f);
    for (int i = 0; i < 300; ++i) {
        const Triangle t{{{x(gen), x(gen), x(gen)}, {x(gen), x(gen), x(gen)},
                          {x(gen), x(gen), x(gen)}}};
        const float cut = x(gen);
        const Box box{{-3, -3, -3}, {cut, 3, 3}};
        const Box b = clipped_bounds(t, box);
        // One plane, x <= cut: the polygon's vertices are the triangle's
        // vertices with x <= cut and the crossings of its edges.
        for (int k = 1; k < 3; ++k) {
            long double lo = 1e30L, hi = -1e30L;
            for (int e = 0; e < 3; ++e) {
                const Vec3 a = t.v[e], c = t.v[(e + 1) % 3];
                if (a.x <= cut) lo = std::min<long double>(lo, a[k]), hi = std::max<long double>(hi, a[k]);
                if ((a.x < cut) != (c.x < cut) && a.x != cut && c.x != cut) {
                    const long double s = ((long double)cut - a.x) / ((long double)c.x - a.x);
                    const long double y = a[k] + ((long double)c[k] - a[k]) * s;
                    lo = std::min(lo, y), hi = std::max(hi, y);
                }
            }
            if (lo > hi) continue;
            EXPECT_LE((long double)b.lo[k], lo) << "triangle " << i;
            EXPECT_GE((long double)b.hi[k], hi) << "triangle " << i;
            EXPECT_GE((long double)std::nextafter(b.lo[k], 9.0f), lo) << "triangle " << i;
            EXPECT_LE((long double)std::nextafter(b.hi[k], -9.0f), hi) << "triangle " << i;
        }
    }
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
