// Cells (cell.hpp): a cube cut by axis and oblique planes, checked against
// volumes, areas and vertex counts worked out by hand, and the area-by-offset
// profile of CellProjection against the cells Cell::split actually makes.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "builders/cell.hpp"

namespace bsp {
namespace {

// The cube [0, 2]^3: every coordinate and area below is exact in binary.
Cell cube() { return Cell::from_box({{0, 0, 0}, {2, 2, 2}}); }

// The volume of a closed convex cell by the divergence theorem: each face
// adds (n . p) A / 3 for any point p of it.
double volume(const Cell& c) {
    double v = 0;
    for (const Cell::Face& f : c.faces()) v += dot(f.normal, c.points()[f.first]) * f.area / 3.0;
    return v;
}

// Corners of the cell: the face points, each counted once (faces share them).
size_t vertex_count(const Cell& c) {
    std::vector<Vec3d> seen;
    for (const Vec3d& p : c.points()) {
        bool known = false;
        for (const Vec3d& q : seen) {
            const Vec3d d = p - q;
            known = known || dot(d, d) < 1e-20;
        }
        if (!known) seen.push_back(p);
    }
    return seen.size();
}

// The area of the face lying in the cut (outward normal n), or 0.
double face_area_along(const Cell& c, const Vec3d& n) {
    for (const Cell::Face& f : c.faces())
        if (dot(f.normal, n) > 1.0 - 1e-12) return f.area;
    return 0.0;
}

Vec3d unit(double x, double y, double z) {
    const double l = std::sqrt(x * x + y * y + z * z);
    return {x / l, y / l, z / l};
}

TEST(Cell, CubeFromBox) {
    const Cell c = cube();
    EXPECT_EQ(c.faces().size(), 6u);
    EXPECT_EQ(vertex_count(c), 8u);
    EXPECT_EQ(c.area(), 24.0);
    EXPECT_DOUBLE_EQ(volume(c), 8.0);  // the division by 3 rounds
    double lo, hi;
    c.extent(unit(1, 1, 1), lo, hi);
    EXPECT_NEAR(lo, 0.0, 1e-15);
    EXPECT_NEAR(hi, 6.0 / std::sqrt(3.0), 1e-14);
}

TEST(Cell, AxisCutMakesTwoBoxes) {
    Cell below, above;
    cube().split({1, 0, 0}, 0.5, below, above);
    // 0.5 x 2 x 2 and 1.5 x 2 x 2: exact in binary, and so are their areas.
    EXPECT_DOUBLE_EQ(volume(below), 2.0);
    EXPECT_DOUBLE_EQ(volume(above), 6.0);
    EXPECT_EQ(below.area(), 12.0);
    EXPECT_EQ(above.area(), 20.0);
    EXPECT_EQ(below.faces().size(), 6u);
    EXPECT_EQ(above.faces().size(), 6u);
    EXPECT_EQ(vertex_count(below), 8u);
    EXPECT_EQ(vertex_count(above), 8u);
    // The parts' surfaces are the whole's plus the 2 x 2 cut, once per side.
    EXPECT_EQ(face_area_along(below, {1, 0, 0}), 4.0);
    EXPECT_EQ(face_area_along(above, {-1, 0, 0}), 4.0);
}

TEST(Cell, AxisCutsPutTheNewFaceExactlyOnThePlane) {
    // Float planes cutting a float box, as the sweep builder makes them: the
    // new face must lie exactly at the plane's position, so the cell's extent
    // equals it bit for bit (an interpolated crossing is off by an ulp of a
    // double, and then the plane was a candidate inside the cell again).
    // (About one interpolated crossing in sixty was off: 20 boxes of 30 cuts.)
    std::mt19937 gen(5);
    std::uniform_real_distribution<float> share(0.01f, 0.99f);
    Cell c;
    for (int i = 0; i < 600; ++i) {
        if (i % 30 == 0) c = Cell::from_box({{0.1f, -0.3f, 0.7f}, {1.3f, 0.9f, 1.9f}});
        const int axis = i % 3;
        const Vec3d n(axis == 0, axis == 1, axis == 2);
        double lo, hi;
        c.extent(n, lo, hi);
        const double d = double(float(lo + double(share(gen)) * (hi - lo)));
        Cell below, above;
        c.split(n, d, below, above);
        // Every point of either part near the plane lies exactly in it.
        for (const Cell* part : {&below, &above}) {
            for (const Vec3d& p : part->points()) {
                const double x = dot(n, p);
                if (std::fabs(x - d) < 1e-9) {
                    ASSERT_EQ(x, d) << "cut " << i;
                }
            }
        }
        double blo, bhi, alo, ahi;
        below.extent(n, blo, bhi);
        above.extent(n, alo, ahi);
        EXPECT_EQ(bhi, d);
        EXPECT_EQ(alo, d);
        EXPECT_EQ(blo, lo);
        EXPECT_EQ(ahi, hi);
        c = i % 2 ? below : above;
    }
}

TEST(Cell, DiagonalCutThroughCentreMakesHexagon) {
    // x + y + z = 3 through the centre: two congruent halves whose cap is a
    // regular hexagon of side sqrt(2), area 3 sqrt(3). Each half keeps four
    // corners of the cube (coordinate sums 0, 2, 2, 2 or 4, 4, 4, 6) and all
    // six faces in part, plus the cap.
    const Vec3d n = unit(1, 1, 1);
    Cell below, above;
    cube().split(n, std::sqrt(3.0), below, above);
    const double cap = 3.0 * std::sqrt(3.0);
    for (const Cell* half : {&below, &above}) {
        EXPECT_NEAR(volume(*half), 4.0, 1e-12);
        EXPECT_NEAR(half->area(), 12.0 + cap, 1e-12);
        EXPECT_EQ(half->faces().size(), 7u);
        EXPECT_EQ(vertex_count(*half), 10u);
    }
    EXPECT_NEAR(face_area_along(below, n), cap, 1e-12);
    EXPECT_NEAR(face_area_along(above, n * -1.0), cap, 1e-12);
}

TEST(Cell, CornerCutMakesTetrahedron) {
    // x + y + z = 1 cuts off the corner at the origin: a right tetrahedron
    // with unit legs (volume 1/6, three right triangles of area 1/2 and an
    // equilateral cap of side sqrt(2), area sqrt(3)/2).
    Cell below, above;
    cube().split(unit(1, 1, 1), 1.0 / std::sqrt(3.0), below, above);
    EXPECT_NEAR(volume(below), 1.0 / 6.0, 1e-14);
    EXPECT_NEAR(below.area(), 1.5 + std::sqrt(3.0) / 2.0, 1e-14);
    EXPECT_EQ(below.faces().size(), 4u);
    EXPECT_EQ(vertex_count(below), 4u);
    EXPECT_NEAR(volume(above), 8.0 - 1.0 / 6.0, 1e-12);
    EXPECT_NEAR(above.area(), 24.0 - 1.5 + std::sqrt(3.0) / 2.0, 1e-12);
    EXPECT_EQ(above.faces().size(), 7u);
    EXPECT_EQ(vertex_count(above), 10u);  // 7 corners and the cut's 3
}

TEST(Cell, PlaneMissingTheCellLeavesItWhole) {
    Cell below, above;
    cube().split({0, 0, 1}, 5.0, below, above);
    EXPECT_TRUE(above.empty());
    EXPECT_EQ(below.area(), 24.0);
    EXPECT_DOUBLE_EQ(volume(below), 8.0);
}

TEST(Cell, RandomCutsConserveVolumeAndArea) {
    // Repeated oblique cuts, each of the larger part of the last: the parts'
    // volumes add up to the whole, and their areas to the whole plus the cap
    // on both sides. (Keeping the larger part keeps the cell's size near the
    // coordinates', whose rounding sets the error.)
    std::mt19937 gen(7);
    std::uniform_real_distribution<double> coord(-1.0, 1.0), share(0.25, 0.75);
    Cell c = cube();
    for (int i = 0; i < 20; ++i) {
        const Vec3d n = unit(coord(gen), coord(gen), coord(gen));
        double lo, hi;
        c.extent(n, lo, hi);
        const double d = lo + share(gen) * (hi - lo);
        Cell below, above;
        c.split(n, d, below, above);
        ASSERT_FALSE(below.empty());
        ASSERT_FALSE(above.empty());
        const double cap = face_area_along(below, n);
        EXPECT_GT(cap, 0.0);
        EXPECT_NEAR(face_area_along(above, n * -1.0), cap, 1e-12 * 24.0);
        EXPECT_NEAR(volume(below) + volume(above), volume(c), 1e-12 * 8.0);
        EXPECT_NEAR(below.area() + above.area(), c.area() + 2.0 * cap, 1e-12 * 24.0);
        // Every point of each part lies on its side of the plane.
        for (const Vec3d& p : below.points()) EXPECT_LE(dot(n, p), d + 1e-12);
        for (const Vec3d& p : above.points()) EXPECT_GE(dot(n, p), d - 1e-12);
        c = volume(below) > volume(above) ? below : above;
    }
}

// The profile the sweep prices planes with: the areas of the parts below and
// above u.x = t, caps included, without cutting the cell.
TEST(CellProjection, ProfileOfCubeAlongAxis) {
    const Cell c = cube();
    const CellProjection cp(c, {1, 0, 0});
    EXPECT_EQ(cp.lo(), 0.0);
    EXPECT_EQ(cp.hi(), 2.0);
    for (double t : {0.25, 0.5, 1.0, 1.5}) {
        double below, above;
        cp.areas_at(t, below, above);
        // A t x 2 x 2 box below, (2 - t) x 2 x 2 above.
        EXPECT_NEAR(below, 8.0 + 8.0 * t, 1e-13) << "t = " << t;
        EXPECT_NEAR(above, 8.0 + 8.0 * (2.0 - t), 1e-13) << "t = " << t;
    }
}

// The surface of the box [lo, hi] with its extent along `axis` ending at t.
double box_area_below(const Vec3d& lo, const Vec3d& hi, int axis, double t) {
    Vec3d d = hi - lo;
    (axis == 0 ? d.x : axis == 1 ? d.y : d.z) = t - (axis == 0 ? lo.x : axis == 1 ? lo.y : lo.z);
    return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
}

TEST(CellProjection, AreasOfABoxAreExactAlongEveryAxis) {
    // A box that is not a cube: along each axis, the parts below and above
    // every plane inside are boxes, directly (areas_at) and from the table
    // (eval).
    const Vec3d lo(-1.0, 0.0, 2.0), hi(3.0, 0.5, 4.0);
    const Cell c = Cell::from_box({{-1.0f, 0.0f, 2.0f}, {3.0f, 0.5f, 4.0f}});
    const double lows[3] = {lo.x, lo.y, lo.z}, highs[3] = {hi.x, hi.y, hi.z};
    for (int axis = 0; axis < 3; ++axis) {
        const Vec3d u(axis == 0, axis == 1, axis == 2);
        EXPECT_NEAR(c.area(), box_area_below(lo, hi, axis, highs[axis]), 1e-12);
        const CellProjection direct(c, u);
        CellProjection table(c, u);
        table.tabulate();
        for (int i = 1; i < 8; ++i) {
            const double t = lows[axis] + (highs[axis] - lows[axis]) * i / 8.0;
            double b, a, tb, ta;
            direct.areas_at(t, b, a);
            table.eval(t, tb, ta);
            const double below = box_area_below(lo, hi, axis, t);
            // The part above is the box mirrored: [t, hi] along the axis.
            const double above = box_area_below(lo, hi, axis, lows[axis] + highs[axis] - t);
            EXPECT_NEAR(b, below, 1e-12 * below) << "axis " << axis << ", t = " << t;
            EXPECT_NEAR(a, above, 1e-12 * above) << "axis " << axis << ", t = " << t;
            EXPECT_NEAR(tb, b, 1e-9 * b) << "axis " << axis << ", t = " << t;
            EXPECT_NEAR(ta, a, 1e-9 * a) << "axis " << axis << ", t = " << t;
        }
    }
}

TEST(CellProjection, TableEqualsDirectAreasInsideAndBeyondTheCell) {
    // Unit cubes cut four times by planes through their middle region (the
    // larger part kept each time), seen
    // along random directions at offsets inside the cell and beyond either
    // end: the table gives the direct areas, and the two parts together
    // cover the cell's surface (SA(below) + SA(above) >= SA(cell)) wherever
    // both are non-empty.
    std::mt19937 gen(3);
    std::normal_distribution<double> normal;
    std::uniform_real_distribution<double> middle(0.3, 0.7), offset(-0.5, 2.0);
    for (int i = 0; i < 20; ++i) {
        Cell c = Cell::from_box({{0, 0, 0}, {1, 1, 1}});
        for (int j = 0; j < 4; ++j) {
            const Vec3d n = unit(normal(gen), normal(gen), normal(gen));
            const Vec3d p(middle(gen), middle(gen), middle(gen));
            Cell below, above;
            c.split(n, dot(n, p), below, above);
            c = below.area() > above.area() ? below : above;  // never empty
        }
        const double total = c.area();
        ASSERT_GT(total, 0.0);
        ASSERT_LT(total, 6.0);
        const Vec3d u = unit(normal(gen), normal(gen), normal(gen));
        const CellProjection direct(c, u);
        CellProjection table(c, u);
        table.tabulate();
        for (int j = 0; j < 25; ++j) {
            const double t = offset(gen);
            double b, a, tb, ta;
            direct.areas_at(t, b, a);
            table.eval(t, tb, ta);
            EXPECT_NEAR(tb, b, 1e-7 * b + 1e-12) << "t = " << t;
            EXPECT_NEAR(ta, a, 1e-7 * a + 1e-12) << "t = " << t;
            if (b > 0 && a > 0) {
                EXPECT_GE(b + a, total * (1 - 1e-9)) << "t = " << t;
            }
        }
    }
}

TEST(CellProjection, PlaneInAFaceMakesAFlatCellOnThatSide) {
    // A plane at either end of the cell: the flat cell it cuts off (the face
    // and the cap, back to back) has twice the face's area, at the bottom as
    // at the top, and the other part is the whole cell - what split() makes.
    const Cell c = cube();
    const CellProjection cp(c, {0, 0, 1});
    double below, above;
    cp.areas_at(0.0, below, above);
    EXPECT_EQ(below, 8.0);
    EXPECT_EQ(above, 24.0);
    cp.areas_at(2.0, below, above);
    EXPECT_EQ(below, 24.0);
    EXPECT_EQ(above, 8.0);
    for (double t : {0.0, 2.0}) {
        Cell b, a;
        c.split({0, 0, 1}, t, b, a);
        cp.areas_at(t, below, above);
        EXPECT_EQ(below, b.area()) << "t = " << t;
        EXPECT_EQ(above, a.area()) << "t = " << t;
    }
}

TEST(CellProjection, CutsOnlyInsideBeyondTheRounding) {
    // Along an axis any position strictly inside cuts, however close to a
    // face; along an oblique direction a plane within the rounding of the
    // cell's vertices does not (it would cut off an empty sliver).
    const Cell c = cube();
    const CellProjection axis(c, {1, 0, 0});
    EXPECT_TRUE(axis.cuts(std::nextafter(0.0, 1.0)));
    EXPECT_TRUE(axis.cuts(std::nextafter(2.0, 0.0)));
    EXPECT_FALSE(axis.cuts(0.0));
    EXPECT_FALSE(axis.cuts(2.0));
    const CellProjection oblique(c, unit(1, 2, 3));
    EXPECT_FALSE(oblique.cuts(oblique.lo() + 1e-13));
    EXPECT_FALSE(oblique.cuts(oblique.hi() - 1e-13));
    EXPECT_TRUE(oblique.cuts(oblique.lo() + 1e-6));
    EXPECT_TRUE(oblique.cuts(oblique.hi() - 1e-6));
}

// A randomly cut cell (three oblique halvings of the cube).
Cell randomly_cut_cell(std::mt19937& gen) {
    std::uniform_real_distribution<double> coord(-1.0, 1.0);
    Cell c = cube();
    for (int i = 0; i < 3; ++i) {
        Cell below, above;
        const Vec3d n = unit(coord(gen), coord(gen), coord(gen));
        double lo, hi;
        c.extent(n, lo, hi);
        c.split(n, 0.5 * (lo + hi), below, above);
        c = below;
    }
    return c;
}

TEST(CellProjection, ProfileMatchesTheCutCells) {
    // Along random directions of a randomly cut cell, areas_at() gives the
    // areas of the parts split() makes, and the tabulated eval() the same.
    std::mt19937 gen(11);
    std::uniform_real_distribution<double> coord(-1.0, 1.0), share(0.02, 0.98);
    const Cell c = randomly_cut_cell(gen);
    for (int i = 0; i < 10; ++i) {
        const Vec3d u = unit(coord(gen), coord(gen), coord(gen));
        CellProjection cp(c, u);
        CellProjection table(c, u);
        table.tabulate();
        for (int j = 0; j < 20; ++j) {
            const double t = cp.lo() + share(gen) * (cp.hi() - cp.lo());
            Cell below, above;
            c.split(u, t, below, above);
            double b, a, tb, ta;
            cp.areas_at(t, b, a);
            table.eval(t, tb, ta);
            const double tol = 1e-9 * c.area();
            EXPECT_NEAR(b, below.area(), tol);
            EXPECT_NEAR(a, above.area(), tol);
            EXPECT_NEAR(tb, b, tol);
            EXPECT_NEAR(ta, a, tol);
        }
    }
}

TEST(CellProjection, ReprojectingEqualsAFreshProjection) {
    // The builder keeps one projection per thread and re-projects it: every
    // value must be the one a new projection gives, bit for bit, and the
    // previous direction's table must be gone (eval() then evaluates directly).
    std::mt19937 gen(5);
    std::uniform_real_distribution<double> coord(-1.0, 1.0), share(0.02, 0.98);
    const Cell c = randomly_cut_cell(gen);
    const Cell box = cube();
    CellProjection reused;
    for (int i = 0; i < 6; ++i) {
        const Vec3d u = unit(coord(gen), coord(gen), coord(gen));
        reused.project(box, unit(1, 0, 0));
        reused.tabulate();
        reused.project(c, u);
        const CellProjection fresh(c, u);
        EXPECT_EQ(reused.lo(), fresh.lo());
        EXPECT_EQ(reused.hi(), fresh.hi());
        for (int j = 0; j < 10; ++j) {
            const double t = fresh.lo() + share(gen) * (fresh.hi() - fresh.lo());
            EXPECT_EQ(reused.cuts(t), fresh.cuts(t));
            double rb, ra, fb, fa;
            reused.eval(t, rb, ra);
            fresh.areas_at(t, fb, fa);
            EXPECT_EQ(rb, fb);
            EXPECT_EQ(ra, fa);
        }
    }
}

TEST(CellProjection, AreaBelowNeverFallsAsThePlaneRises) {
    // The sweep skips candidates on this (may_win_beyond): the part of a
    // convex cell below a plane, and its surface, grow as the plane rises.
    std::mt19937 gen(7);
    std::uniform_real_distribution<double> coord(-1.0, 1.0);
    const Cell c = randomly_cut_cell(gen);
    for (int i = 0; i < 10; ++i) {
        const Vec3d u = unit(coord(gen), coord(gen), coord(gen));
        CellProjection cp(c, u), table(c, u);
        ASSERT_TRUE(cp.areas_monotone());
        table.tabulate();
        double last = 0, last_table = 0;
        for (int j = 0; j <= 200; ++j) {
            const double t = cp.lo() + (cp.hi() - cp.lo()) * j / 200.0;
            double b, a, tb, ta;
            cp.areas_at(t, b, a);
            table.eval(t, tb, ta);
            EXPECT_GE(b, last - 1e-12 * c.area()) << "t = " << t;
            EXPECT_GE(tb, last_table - 1e-12 * c.area()) << "t = " << t;
            last = b;
            last_table = tb;
        }
        EXPECT_GT(last, 0.0);
    }
}

}  // namespace
}  // namespace bsp
