// Which triangle hits a leaf accepts: the one condition of every traversal
// path (single_ray.hpp's scalar and SIMD leaves, packet.hpp, trace_path.cpp
// through trace_one; culling on or off), so that culling can never change an
// answer.
//
// The triangle test's edge functions decide hit or miss, its distance comes
// from the triangle's plane (triangle.hpp). For a ray lying (nearly) in the
// triangle's plane the two disagree: the edge functions of the flattened
// projection pass, and the plane's distance is anywhere on the ray - on a
// tilted fan with rays along its spokes, hit points up to 5.9e6 units off
// the triangle. Culling skipped such a triangle wherever the leaf's segment
// box missed the triangle's box, and the unculled test took its far-off hit:
// 291 of 2,000 spoke rays answered differently with and without culling.
//
// So a leaf accepts a hit only where culling would have let the triangle be
// tested: the hit's walk parameter (give or take its rounding), clamped to
// the leaf's segment [s0, s1] (s1 = min(cell end, reach), as the cull box),
// gives a piece of the segment whose box - SegmentBox's, with the same
// padding - meets the triangle's culling box. That box lies inside the
// segment's box (rounding is monotone, and its padding is at most the
// segment's), so a culled triangle would
// have been rejected anyway: the accepted hits, in the same order, are the
// same whether or not culling skipped anything. A real hit passes: its point
// lies on the triangle, inside its box. Trees without boxes (leaf_boxes
// "none") cannot cull, and accept what the triangle test accepts.
//
// The condition depends on the leaf, so a triangle it rejects is not marked
// in the mailbox: a later leaf may accept it.
//
// Included by single_ray.hpp and packet.hpp, inside one instruction-set
// level's namespace (see trace_kernels.cpp).
#pragma once
#include <algorithm>
#include <cmath>

#include "geometry.hpp"
#include "trace/kernels/tree_view.hpp"

#ifndef BSPLAB_ISA_NS
#error "leaf_acceptance.hpp is compiled per instruction set: include it from the kernel headers"
#endif

namespace bsp::BSPLAB_ISA_NS {
namespace {

// The box of the ray's segment o + [t0, t1] d, padded so that no float error
// of the end points (or of the traversal's plane crossings, which the
// builders' fattening already bounds by tree.cull_pad / 2) can cull a hit.
// An end point's error is relative to the terms it is summed from, |o| and
// |t d|, not to the point itself: a ray from far away has |o| >> |o + t d|.
struct SegmentBox {
    float lo[3], hi[3];
    void set(const float* org, const float* dir, float t0, float t1, float pad) {
        const float tmag = std::max(std::fabs(t0), std::fabs(t1));
        for (int k = 0; k < 3; ++k) {
            const float a = org[k] + t0 * dir[k], b = org[k] + t1 * dir[k];
            const float p =
                pad + (std::fabs(org[k]) + tmag * std::fabs(dir[k])) * (1.0f / (1 << 20));
            lo[k] = std::min(a, b) - p;
            hi[k] = std::max(a, b) + p;
        }
    }
    bool misses(const Box& b) const {
        return b.lo.x > hi[0] || b.hi.x < lo[0] || b.lo.y > hi[1] || b.hi.y < lo[1] ||
               b.lo.z > hi[2] || b.hi.z < lo[2];
    }
};

// The culling box of reference `slot` of a leaf whose references start at
// refs[first] (LeafBoxes::Clipped) or of triangle `prim` (LeafBoxes::Triangle).
inline const Box& culling_box(const TreeView& tree, uint32_t prim, uint32_t slot) {
    return tree.boxes[tree.box_kind == LeafBoxes::Triangle ? prim : slot];
}

// True when the leaf accepts a hit at ray distance t (walk parameter
// t - t_e) of a triangle with culling box `box`, the leaf's segment being
// [s0, min(s1, reach)] of the walk origin `org`, its box padded by `pad`
// (cull_pad + WalkStart::slack, as the cull box; see the comment above).
//
// The hit's t is a float: its walk parameter s is known to an ulp of t (and
// of s), which for a ray from far away (|d| large, t near 1) is a good
// length along the ray - 1.2e-3 for a ray from 10^3 scene sizes of the fan
// scene. So the "point" is the segment [s - e, s + e], both ends clamped.
inline bool leaf_accepts(const Box& box, const float org[3], const float dir[3], float s0,
                         float s1, float t, double t_e, float pad) {
    const float s = float(double(t) - t_e);
    const float e = (std::fabs(t) + std::fabs(s)) * 0x1p-23f;
    const float a = std::min(std::max(s - e, s0), s1), b = std::min(std::max(s + e, s0), s1);
    // The cheap case first, taken by nearly every real hit: the piece's
    // near end, computed exactly as SegmentBox::set computes it, lies in the
    // culling box. The piece's box holds that point (its padding is >= 0,
    // and rounding is monotone), so it meets the culling box: the answer of
    // the full test below, without the far end and the padding.
    const float near[3] = {org[0] + a * dir[0], org[1] + a * dir[1], org[2] + a * dir[2]};
    if (box.lo.x <= near[0] && near[0] <= box.hi.x && box.lo.y <= near[1] &&
        near[1] <= box.hi.y && box.lo.z <= near[2] && near[2] <= box.hi.z)
        return true;
    SegmentBox around;
    around.set(org, dir, a, b, pad);
    return !around.misses(box);
}

}  // namespace
}  // namespace bsp::BSPLAB_ISA_NS
