// The watertight ray-triangle test (triangle.hpp) on cases whose answers are
// exact, and on rays across an edge two triangles share.
#include <gtest/gtest.h>

#include <random>

#include "trace/triangle.hpp"

namespace bsp {
namespace {

const Triangle kUnit{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};

bool hit(const Triangle& tri, const Vec3& o, const Vec3& d, TriangleHit& h,
         float tmax = kInf) {
    return intersect_triangle(ShearedRay(o, d), tri, 0.0f, tmax, h);
}

TEST(Triangle, ExactHitAndBarycentrics) {
    TriangleHit h{};
    ASSERT_TRUE(hit(kUnit, {0.25f, 0.5f, 2.0f}, {0, 0, -1}, h));
    EXPECT_EQ(h.t, 2.0f);
    EXPECT_EQ(h.u, 0.25f);  // p = (1 - u - v) v0 + u v1 + v v2, as in Embree
    EXPECT_EQ(h.v, 0.5f);
}

TEST(Triangle, BothSidesHit) {
    TriangleHit h{};
    ASSERT_TRUE(hit(kUnit, {0.25f, 0.25f, -4.0f}, {0, 0, 1}, h));
    EXPECT_EQ(h.t, 4.0f);
    EXPECT_EQ(h.u, 0.25f);
    EXPECT_EQ(h.v, 0.25f);
}

TEST(Triangle, MissesOutsideAndAlongThePlane) {
    TriangleHit h{};
    EXPECT_FALSE(hit(kUnit, {0.75f, 0.75f, 1.0f}, {0, 0, -1}, h));  // beyond the hypotenuse
    EXPECT_FALSE(hit(kUnit, {-0.25f, 0.5f, 1.0f}, {0, 0, -1}, h));
    EXPECT_FALSE(hit(kUnit, {-1.0f, 0.25f, 0.0f}, {1, 0, 0}, h));   // in the plane
}

TEST(Triangle, DistanceRangeIsOpen) {
    // tmin < t < tmax: a hit exactly at tmax is not taken, nor one behind.
    TriangleHit h{};
    EXPECT_FALSE(hit(kUnit, {0.25f, 0.25f, 1.0f}, {0, 0, -1}, h, 1.0f));
    EXPECT_TRUE(hit(kUnit, {0.25f, 0.25f, 1.0f}, {0, 0, -1}, h, 1.5f));
    EXPECT_FALSE(hit(kUnit, {0.25f, 0.25f, -1.0f}, {0, 0, -1}, h));
}

TEST(Triangle, VertexAndEdgeAreInside) {
    TriangleHit h{};
    EXPECT_TRUE(hit(kUnit, {0.0f, 0.0f, 1.0f}, {0, 0, -1}, h));  // on v0
    EXPECT_TRUE(hit(kUnit, {0.5f, 0.0f, 1.0f}, {0, 0, -1}, h));  // on edge v0 v1
    EXPECT_EQ(h.u, 0.5f);
    EXPECT_EQ(h.v, 0.0f);
}

TEST(Triangle, SharedEdgeIsWatertight) {
    // Two triangles split a tilted square (z = x/2 + y/4, exact) along its
    // diagonal. Oblique rays aimed at points near the diagonal, all from the
    // same side, must hit at least one of them: the shared edge's edge
    // functions agree bit for bit with opposite signs.
    const Vec3 a(0, 0, 0), b(1, 0, 0.5f), c(1, 1, 0.75f), d(0, 1, 0.25f);
    const Triangle t1{{a, b, c}}, t2{{a, c, d}};
    std::mt19937 gen(9);
    std::uniform_real_distribution<float> along(0.01f, 0.99f), off(-1e-6f, 1e-6f),
        dir(-0.5f, 0.5f);
    int rays = 0;
    for (int i = 0; i < 20000; ++i) {
        const float s = along(gen);
        const Vec3 target = a + (c - a) * s + Vec3(off(gen), off(gen), off(gen));
        const Vec3 direction(dir(gen), dir(gen), -1.0f);
        const Vec3 origin = target - direction * 3.0f;
        TriangleHit h1{}, h2{};
        const bool any = hit(t1, origin, direction, h1) || hit(t2, origin, direction, h2);
        EXPECT_TRUE(any) << "ray " << i << " slipped through the shared edge";
        ++rays;
    }
    EXPECT_EQ(rays, 20000);
}

}  // namespace
}  // namespace bsp
