// Where a ray's walk through the tree starts, and how far its plane crossings
// may be off: the conservative crossing rule of every traversal path
// (single_ray.hpp, packet.hpp, and through trace_one trace_path.cpp).
//
// The walk starts where the ray enters the scene box, computed in double
// (t_e), from the origin o + t_e d rounded to float: the walk's parameter is
// s = t - t_e. A ray from far away then crosses planes with the error of a
// point inside the box, not of |o| (a ray from 10^6 scene sizes away once
// walked both sides of most planes). The triangle test keeps the ray's own
// origin, so hits are the same bits whatever the walk does.
//
// Every crossing s of a plane is widened to [s - err, s + err], err bounding
// its float error, and a child is visited when its widened range touches the
// ray's (closed comparisons). So a cell's range always holds the exact range
// of the ray inside the cell, and a hit exactly on a cell's boundary - a ray
// through an edge lying in two split planes, whose crossings round either way
// - is found in the cell of its triangle (docs/algorithms.md#robustness).
//
// Included by single_ray.hpp and packet.hpp, inside one instruction-set
// level's namespace (see trace_kernels.cpp).
#pragma once
#include <algorithm>
#include <cmath>
#include <limits>

#include "geometry.hpp"
#include "trace/kernels/tree_view.hpp"

#ifndef BSPLAB_ISA_NS
#error "walk_start.hpp is compiled per instruction set: include it from the kernel headers"
#endif

namespace bsp::BSPLAB_ISA_NS {
namespace {

// The relative error of an axis crossing (split - o[a]) * (1 / d[a]): three
// roundings of 2^-24 (difference, reciprocal, product), with room to spare.
constexpr float kCrossRel = 1.0f / (1 << 21);
// The double precision rounding of o + t_e d, relative to |o| + |t_e d|.
constexpr double kOriginRel = 1.0 / double(1ull << 50);

// The t at which the ray o + t d enters box b, from the float crossings of
// its faces; 0 when it starts inside the box (the walk then starts at the
// ray's origin). It need not be exact: the walk origin is the ray's point at
// exactly this t (in double), and only that point's rounding to float
// enters the bounds. A ray that misses the box by a rounding (aimed at a
// wall in the box's face) still starts where it comes closest, the largest
// of its near crossings, and the widened float clip decides; falling back
// to the far origin made such rays walk the whole tree.
inline float box_entry(const Box& b, const float o[3], const float d[3], const float idir[3]) {
    float t0 = 0.0f;
    for (int k = 0; k < 3; ++k) {
        if (d[k] == 0.0f) continue;  // outside the slab: the clip rejects it
        t0 = std::max(t0, std::min((b.lo[k] - o[k]) * idir[k], (b.hi[k] - o[k]) * idir[k]));
    }
    return t0;
}

// A float below (above) the exact s of the ray's t, for the walk's range.
inline float walk_lower(float t, double t_e) {
    const float s = float(double(t) - t_e);
    return s - std::fabs(s) * kCrossRel;
}
inline float walk_upper(float t, double t_e) {
    const float s = float(double(t) - t_e);
    return s + std::fabs(s) * kCrossRel;
}

// The farthest walk parameter s at which a hit can still be as close as the
// closest hit's t: a hit in a cell that starts beyond it rounds to a t above
// hit_t (the early exit's test). Half an ulp of t above hit_t (its rounding;
// 2^-40 for the double plane distance), rounded up in s.
inline float walk_reach(float hit_t, double t_e) {
    const double t = double(hit_t) + std::fabs(double(hit_t)) * (0x1p-24 + 0x1p-40);
    const float s = float(t - t_e);
    return s + std::fabs(s) * 0x1p-22f + std::numeric_limits<float>::denorm_min();
}

// The same for a closest hit at the double distance hit_td (ray_distance):
// a hit that beats it (single_ray.hpp's Closest) is no farther in double,
// so its cell starts before hit_td, give or take the double distance's error
// (2^-40), rounded up in s. Without the float t's half ulp, which from far
// away is a good part of the scene (2^-24 of 10^7 scene sizes: 0.6 of one),
// where the walk went on past the hit through every cell in reach.
inline float walk_reach_exact(double hit_td, double t_e) {
    const double t = hit_td + std::fabs(hit_td) * 0x1p-40;
    const float s = float(t - t_e);
    return s + std::fabs(s) * 0x1p-22f + std::numeric_limits<float>::denorm_min();
}

// Rays from farther than this many scene box sizes also test triangles
// from the walk origin (ShearedRay::t_offset): from there a float test
// decides to a rounding of the scene's coordinates, from the ray's origin
// only to one of |o|, which at 10^6 scene sizes is a good part of the scene.
// Nearer rays test from their own origin, bit for bit as Embree's test does
// (the same edge of two triangles is decided the same way).
constexpr double kFarTestSizes = 1024.0;

// How far the triangle test's decision may sit from the exact ray: the
// watertight test shears the vertices relative to its origin in float
// (v - o, then x - s z), so it decides for a ray displaced by a few
// roundings of |v - o| <= |test origin| + the scene's largest coordinate
// (8 of 2^-24 with the shear's and the subtraction's; 2^-20 leaves room).
// A crossing's bound includes that displacement: where the float test hits
// a triangle the exact ray passes beside, the walk still visits the cell of
// that triangle. (Lost Empire: a ray 7.6e-6 from a voxel corner, x = 8,
// y = 0, crossed x = 8 at y = +4e-6, above the y = 0 plane; the float test
// hit the triangle below it, whose cell the exact ray never entered, and
// missed its neighbour, which the exact ray hits: a leak to a wall 2 %
// farther.)
constexpr float kTestRel = 1.0f / (1 << 20);

struct WalkStart {
    double t_e;
    float org[3];      // o + t_e d, rounded to float
    // Where the triangle test starts: the walk origin for a far ray, else
    // the ray's own origin (test_t = 0).
    float test_org[3];
    double test_t;
    float org_err[3];  // its error along each axis, in s: |delta o[a]| / |d[a]|
    // A general plane's crossing error terms (see trace_one), of the walk's
    // origin: the scene's coordinates and |org|_1, and |d|_1.
    float cross_a, cross_b;
    // The triangle test's displacement from the exact ray (kTestRel): in
    // every crossing's bound, and in the leaves' box padding (cull_pad +
    // slack, leaf_acceptance.hpp).
    float slack;

    WalkStart(const TreeView& tree, const float o[3], const float d[3], const float idir[3]) {
        const Box& bounds = tree.bounds;
        const float two_scene_scale = tree.two_scene_scale;
        // A general plane's crossing is off by a few roundings of the terms it
        // is computed from: the plane offset (at most a few scene
        // coordinates), n.org (at most |org|_1, n being unit) and s n.d (at
        // most |s| |d|_1); plus the rounding of org itself.
        constexpr float kCrossUlps = 1.0f / (1 << 20);  // 16 roundings of 2^-24
        // An origin strictly inside the box (most rays of a scene: random,
        // ambient occlusion, interior cameras) enters it at t_e = 0 without
        // box_entry's crossings: every face is then at a nonzero distance
        // of the origin's sign pattern (lo - o < 0 < hi - o), so one of each
        // axis's two crossings is <= 0 (-inf for a denormal d[k]'s infinite
        // 1 / d[k], never NaN) and box_entry would return +0 too. On a face
        // (a zero distance times an infinite 1 / d[k] is NaN) it decides.
        const bool inside = bounds.lo.x < o[0] && o[0] < bounds.hi.x && bounds.lo.y < o[1] &&
                            o[1] < bounds.hi.y && bounds.lo.z < o[2] && o[2] < bounds.hi.z;
        t_e = inside ? 0.0 : box_entry(bounds, o, d, idir);
        const float scene = 0.5f * two_scene_scale;
        if (t_e == 0.0) {  // inside the box: the ray's own origin, exactly
            slack = kTestRel * (scene + std::max({std::fabs(o[0]), std::fabs(o[1]),
                                                              std::fabs(o[2])}));
            // Parallel to an axis (idir = inf) the crossing is +-inf whatever
            // the bound: no displacement term there.
            for (int k = 0; k < 3; ++k)
                org[k] = test_org[k] = o[k],
                org_err[k] = d[k] == 0.0f ? 0.0f : slack * std::fabs(idir[k]);
            test_t = 0.0;
            cross_a = kCrossUlps * (two_scene_scale + std::fabs(o[0]) + std::fabs(o[1]) +
                                    std::fabs(o[2])) +
                      slack;
            cross_b = kCrossUlps * (std::fabs(d[0]) + std::fabs(d[1]) + std::fabs(d[2]));
            return;
        }
        double far = 0.0;
        for (int k = 0; k < 3; ++k) {
            const double moved = double(o[k]) + t_e * double(d[k]);
            org[k] = float(moved);
            // Parallel to the axis the origin does not move (t_e * 0 = 0).
            const double err = d[k] == 0.0
                                   ? 0.0
                                   : (kCrossRel * std::fabs(double(org[k])) +
                                      kOriginRel * (std::fabs(double(o[k])) +
                                                    std::fabs(t_e * double(d[k])))) *
                                         std::fabs(double(idir[k]));
            org_err[k] = float(err * (1.0 + 0x1p-20));
            far += kOriginRel * (std::fabs(double(o[k])) + std::fabs(t_e * double(d[k])));
        }
        double speed = 0.0;
        for (int k = 0; k < 3; ++k) speed = std::max(speed, std::fabs(double(d[k])));
        const bool far_test = t_e * speed > kFarTestSizes * tree.box_extent;
        test_t = far_test ? t_e : 0.0;
        for (int k = 0; k < 3; ++k) test_org[k] = far_test ? org[k] : o[k];
        slack =
            kTestRel * (scene + std::max({std::fabs(test_org[0]), std::fabs(test_org[1]),
                                          std::fabs(test_org[2])}));
        for (int k = 0; k < 3; ++k)
            if (d[k] != 0.0f) org_err[k] += slack * std::fabs(idir[k]);
        cross_a = kCrossUlps * (two_scene_scale + std::fabs(org[0]) + std::fabs(org[1]) +
                                std::fabs(org[2])) +
                  float(far) + slack;
        cross_b = kCrossUlps * (std::fabs(d[0]) + std::fabs(d[1]) + std::fabs(d[2]));
    }
};

// An axis crossing's error bound for every crossing the walk uses, once the
// ray's range in the box [s0, s1] is known: the origin's part, and the
// relative part at the largest |s| that matters (a crossing beyond the range
// is decided the same way with any smaller bound).
inline void axis_crossing_errors(const WalkStart& w, float s0, float s1, float err[3]) {
    const float rel = kCrossRel * std::max(std::fabs(s0), std::fabs(s1));
    for (int k = 0; k < 3; ++k) err[k] = w.org_err[k] + rel;
}

}  // namespace
}  // namespace bsp::BSPLAB_ISA_NS
