// The tree's local frame: a scene far from the origin (in its own sizes) is
// built and walked relative to a point near its centre, so that every
// rounding bound the builders and the walk use - the crossing slack and the
// triangle test's displacement (walk_start.hpp), the sweep builder's
// robust_epsilon, the leaves' box padding - follows the scene's size, not
// its distance from the origin. Those bounds are relative to the largest
// coordinate they meet: at 10^6 scene sizes from the origin they are 10^6
// times wider than the scene needs, and the walk visits both sides of most
// planes (docs/algorithms.md#far-scenes).
//
// The move is exact. On an axis where the scene lies at least
// kFrameMinCentre of its sizes from the origin, every coordinate has the
// sign and at least the binade of the nearest one, so all are multiples of
// that binade's float spacing g; the offset is the centre rounded to a
// multiple of g, and v - offset, a multiple of g below 2^24 g, is a float.
// choose_frame checks it on every coordinate anyway and keeps that axis at
// the origin where it is not. On the other axes (and for every scene near
// the origin: the trees, and their hashes, are then the same as without a
// frame) the offset is 0.
//
// A ray enters the frame as (o - offset) * scale, rounded to float once
// (to_frame). Where that is exact - an origin in the scene's binade, as
// every camera or bounce ray of the scene - the triangle test computes the
// same float differences v - o as without the frame, so the hits are the
// same bits (Embree's). Elsewhere the ray the tree traces is displaced by
// at most half a float spacing of the moved origin (2^-24 of its distance
// from the scene's centre): every path (single rays, packets, the BVH,
// trace_path, the instanced mesh trees) traces that same moved ray, and the
// walk's bounds hold for it, so the answer is watertight for it, a
// displacement far below the one Embree's own test makes at that distance
// (2^-24 of |v - o| per vertex, and more for the far test, kFarTestSizes).
#pragma once
#include <algorithm>
#include <cmath>
#include <vector>

#include "geometry.hpp"

namespace bsp {

// An axis gets an offset only where the scene's centre lies at least this
// many scene sizes (the box's longest side) from the origin along it.
// Nearer, the bounds are at most that many times the scene's own - a few
// ulps of 2^-20 of the scene, far below any cell - and the tree stays as it
// was built before the frame existed (the same bits, the same hashes).
constexpr double kFrameMinCentre = 16.0;

// Per axis, the offset to subtract from every coordinate (0: none).
struct Frame {
    double offset[3] = {0.0, 0.0, 0.0};
    bool moved() const { return offset[0] != 0.0 || offset[1] != 0.0 || offset[2] != 0.0; }
};

// The frame of `triangles` (every vertex, degenerate triangles included:
// the tree keeps them all, and gives them back exactly).
inline Frame choose_frame(const std::vector<Triangle>& triangles) {
    Frame f;
    if (triangles.empty()) return f;
    double lo[3], hi[3];
    for (int k = 0; k < 3; ++k) lo[k] = INFINITY, hi[k] = -INFINITY;
    for (const Triangle& t : triangles)
        for (const Vec3& v : t.v)
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], double(v[k]));
                hi[k] = std::max(hi[k], double(v[k]));
            }
    double size = 0.0;
    for (int k = 0; k < 3; ++k) size = std::max(size, hi[k] - lo[k]);
    if (!std::isfinite(size)) return f;  // the builders refuse such input
    for (int k = 0; k < 3; ++k) {
        const double centre = 0.5 * (lo[k] + hi[k]);
        if (lo[k] <= 0.0 && hi[k] >= 0.0) continue;
        if (!(std::fabs(centre) >= kFrameMinCentre * size)) continue;
        // Every coordinate is a multiple of the float spacing of the
        // nearest one's binade.
        const double nearest = std::min(std::fabs(lo[k]), std::fabs(hi[k]));
        const double g = std::ldexp(1.0, std::ilogb(nearest) - 23);
        const double offset = std::nearbyint(centre / g) * g;
        bool exact = true;
        for (const Triangle& t : triangles)
            for (const Vec3& v : t.v) {
                const double moved = double(v[k]) - offset;
                exact = exact && double(float(moved)) == moved;
            }
        if (exact) f.offset[k] = offset;
    }
    return f;
}

// Moves `triangles` into frame `f` (exact, see choose_frame).
inline void move_into(const Frame& f, std::vector<Triangle>& triangles) {
    if (!f.moved()) return;
    for (Triangle& t : triangles)
        for (Vec3& v : t.v)
            v = Vec3(float(double(v.x) - f.offset[0]), float(double(v.y) - f.offset[1]),
                     float(double(v.z) - f.offset[2]));
}

// A ray origin in the tree's space: moved into the frame and scaled, in
// double (exact for floats and a power of two) and rounded to float once.
inline Vec3 to_frame(const double offset[3], double scale, const float o[3]) {
    return Vec3(float((double(o[0]) - offset[0]) * scale),
                float((double(o[1]) - offset[1]) * scale),
                float((double(o[2]) - offset[2]) * scale));
}

// A coordinate of the tree's space along `axis` back in the input's units
// (the inspectors' geometry, the instanced top level's boxes), in double.
inline double to_world(double x, int axis, const double offset[3], double scale) {
    return x / scale + offset[axis];
}

}  // namespace bsp
