// The BVH's single-ray kernel (trees of Structure::Bvh): ordered traversal
// of the binary box hierarchy - at an interior node both children's boxes
// are tested, the nearer entered first, the other pushed with its entry
// distance - with early exit, the same walk start, the same watertight
// triangle test and the same tie rule as the kd/BSP kernel (single_ray.hpp),
// so that its hits are the kd tree's bit for bit wherever both are right.
//
// The box test is the slab test of the walk's crossings (walk_start.hpp):
// every face's crossing widened by the axis crossing error of the ray's
// range in the scene box, the origin's error and the triangle test's
// displacement included, the comparisons closed. So a box's range holds the
// exact ray's range in it - a ray along a box face, or through an edge a
// box shares with its sibling, enters it - and no hit is lost at a box face
// (the role of Ize's 1 + 2 gamma padding, "Robust BVH Ray Traversal", 2013).
// A ray parallel to a slab (1 / d = inf) in its face plane gives NaN there,
// which the max/min below ignore: the closed slab holds it.
//
// Leaf culling does not apply: a BVH leaf's box is already the tight box of
// its triangles, so cull=True is the same traversal (the same answers). A
// leaf accepts a hit as the kd tree's leaves do with triangle boxes
// (leaf_acceptance.hpp): only where its walk parameter lies near the
// triangle's own box, which rejects the far-off distances of rays lying in
// a triangle's plane exactly as the kd tree rejects them.
//
// Included by kernels/trace_kernels.cpp (and trace_path.cpp) inside one
// instruction-set level's namespace, like single_ray.hpp.
#pragma once
#include <algorithm>
#include <cmath>
#include <utility>

#include <xmmintrin.h>

#include "trace/kernels/single_ray.hpp"

#ifndef BSPLAB_ISA_NS
#error "bvh_single_ray.hpp is compiled per instruction set: include it from trace_kernels.cpp"
#endif

namespace bsp::BSPLAB_ISA_NS {
namespace {

// The BVH's counters (the hooks of single_ray.hpp's CountEvery, plus box
// tests): steps are the nodes visited, box_tests the ray-box tests (two per
// interior node visited, one for the root), tests the triangle tests.
struct BvhCountEvery {
    uint32_t steps = 0, tests = 0, box_tests = 0;
    void step(uint32_t /*node*/, float /*s0*/, float /*s1*/, double /*t_e*/) { ++steps; }
    void box_test(uint32_t n) { box_tests += n; }
    void test(uint32_t /*prim*/) { ++tests; }
    void hit(float /*t*/) {}
    void miss() {}
    void store(const HitBatch& hits, size_t i) const {
        hits.steps[i] = steps;
        hits.general_steps[i] = 0;
        hits.tests[i] = tests;
        hits.culled[i] = 0;
        hits.box_tests[i] = box_tests;
    }
};

struct BvhCountNothing {
    void step(uint32_t, float, float, double) {}
    void box_test(uint32_t) {}
    void test(uint32_t) {}
    void hit(float) {}
    void miss() {}
    void store(const HitBatch&, size_t) const {}
};

// What the box test needs of a ray: the walk origin, 1 / d, each axis's
// crossing error, and which corner each axis enters by.
struct BvhRay {
    float org[3], idir[3], err[3];
    bool neg[3];  // d[k] < 0 (or -0): enters by the high face

    // The ray's range [enter, exit] in box `n` within [s0, s1]; false when
    // it misses. std::max(s, t) keeps s where t is NaN (a ray in a face
    // plane, parallel to it), std::min likewise.
    bool clip(const BvhNode& n, float s0, float s1, float& enter, float& exit) const {
        const float nx = neg[0] ? n.hi.x : n.lo.x, fx = neg[0] ? n.lo.x : n.hi.x;
        const float ny = neg[1] ? n.hi.y : n.lo.y, fy = neg[1] ? n.lo.y : n.hi.y;
        const float nz = neg[2] ? n.hi.z : n.lo.z, fz = neg[2] ? n.lo.z : n.hi.z;
        const float tnx = (nx - org[0]) * idir[0] - err[0], tfx = (fx - org[0]) * idir[0] + err[0];
        const float tny = (ny - org[1]) * idir[1] - err[1], tfy = (fy - org[1]) * idir[1] + err[1];
        const float tnz = (nz - org[2]) * idir[2] - err[2], tfz = (fz - org[2]) * idir[2] + err[2];
        enter = std::max(std::max(std::max(s0, tnx), tny), tnz);
        exit = std::min(std::min(std::min(s1, tfx), tfy), tfz);
        return enter <= exit;
    }

    // The ray of walk `w` (single_ray.hpp's RayWalk), clipped to the root's
    // box: its range there [t0, t1], and the crossing errors of that range.
    // False when it misses the box.
    bool start(const TreeView& tree, const RayWalk& w, float& t0, float& t1) {
        t0 = w.s_lo;
        t1 = w.s_hi;
        if (!clip_to_box(tree.bvh_nodes[0].box(), w.walk.org, w.idir, w.dir, w.walk.org_err, t0,
                         t1))
            return false;
        axis_crossing_errors(w.walk, t0, t1, err);
        for (int k = 0; k < 3; ++k) {
            org[k] = w.walk.org[k];
            idir[k] = w.idir[k];
            neg[k] = std::signbit(w.dir[k]);
        }
        return true;
    }
};

// What both BVH walks (this file's, bvh_wide_single_ray.hpp's) start from:
// the ray's walk (RayWalk), its box test's ray clipped to the root's box
// over [t0, t1] (in_box false when it misses), the triangle test's ray and
// the leaves' box padding (the builders' and the test's displacement).
struct BvhWalkStart {
    RayWalk rw;
    BvhRay ray;
    float t0 = 0, t1 = 0;
    bool in_box;
    ShearedRay sray;
    float pad;

    BvhWalkStart(const TreeView& tree, const Vec3& o, const Vec3& d, float tmin, float tmax,
                 Closest& hit)
        : rw(tree, o, d, tmin, tmax, hit),
          in_box(ray.start(tree, rw, t0, t1)),
          sray(rw.test_ray()),
          pad(tree.cull_pad + rw.walk.slack) {}
};

// Entries of the traversal stack: one per level of the tree at most
// (kBvhMaxDepth, builders/bvh_build.hpp, which the builder enforces).
constexpr int kBvhStack = 64;

// Both children of an interior node at once, in SSE (every level has it):
// the four corners' crossings of one axis - lanes (A near, B near, A far,
// B far) - in one vector, the far lanes negated, so that one max per axis
// gives both entries and both (negated) exits. Each lane's arithmetic is
// BvhRay::clip's exactly ((x - o) * -r is -((x - o) * r), and -a - e is
// -(a + e)), and MAXPS returns its second operand where the first is NaN,
// as std::max(s, t) keeps s: the same answers, the same counts.
struct BvhPairTest {
    __m128 org[3], sidir[3], err[3];
    __m128 swap[3];  // all ones where d[k] < 0: the near corner is the high one

    explicit BvhPairTest(const BvhRay& r) {
        for (int k = 0; k < 3; ++k) {
            org[k] = _mm_set1_ps(r.org[k]);
            sidir[k] = _mm_setr_ps(r.idir[k], r.idir[k], -r.idir[k], -r.idir[k]);
            err[k] = _mm_set1_ps(r.err[k]);
            swap[k] = _mm_castsi128_ps(_mm_set1_epi32(r.neg[k] ? -1 : 0));
        }
    }

    // Lanes 0, 1: entries of A and B; lanes 2, 3: their exits, negated.
    void test(const BvhNode* pair, float s0, float s1, float out[4]) const {
        const float* f = reinterpret_cast<const float*>(pair);
        __m128 x = _mm_load_ps(f), y = _mm_load_ps(f + 8);      // A.lo, B.lo
        __m128 z = _mm_load_ps(f + 4), w = _mm_load_ps(f + 12);  // A.hi, B.hi
        _MM_TRANSPOSE4_PS(x, y, z, w);  // x = (A.lo.x, B.lo.x, A.hi.x, B.hi.x), ...
        __m128 acc = _mm_setr_ps(s0, s0, -s1, -s1);
        const __m128 axes[3] = {x, y, z};
        for (int k = 0; k < 3; ++k) {
            const __m128 v = axes[k];
            const __m128 swapped = _mm_shuffle_ps(v, v, _MM_SHUFFLE(1, 0, 3, 2));
            const __m128 c = _mm_or_ps(_mm_and_ps(swap[k], swapped), _mm_andnot_ps(swap[k], v));
            const __m128 t = _mm_sub_ps(_mm_mul_ps(_mm_sub_ps(c, org[k]), sidir[k]), err[k]);
            acc = _mm_max_ps(t, acc);
        }
        _mm_storeu_ps(out, acc);
    }
};

// One ray through the BVH (see the file's comment); the walk and the hit
// bookkeeping are single_ray.hpp's.
template <class Counters>
void bvh_trace_one(const TreeView& tree, const Vec3& o, const Vec3& d, float tmin, float tmax,
                   Closest& hit, Counters& count) {
    const BvhWalkStart w(tree, o, d, tmin, tmax, hit);
    count.box_test(1);
    if (!w.in_box) return;
    const double t_e = w.rw.walk.t_e;
    const float *dir = w.rw.dir, *org = w.rw.walk.org;
    const float s_lo = w.rw.s_lo, s_hi = w.rw.s_hi, pad = w.pad;
    const ShearedRay& sray = w.sray;
    float t0 = w.t0, t1 = w.t1;
    const BvhNode* nodes = tree.bvh_nodes;
    const BvhPairTest pair(w.ray);
    const uint32_t* refs = tree.refs;
    const Triangle* tris = tree.tris;
    StackEntry stack[kBvhStack];
    int top = 0;
    uint32_t index = 0;
    for (;;) {
        const BvhNode& node = nodes[index];
        count.step(index, t0, t1, t_e);
        if (!node.is_leaf()) {
            const uint32_t left = node.left();
            const float limit = std::min(s_hi, hit.reach);
            float lanes[4];
            pair.test(nodes + left, s_lo, limit, lanes);
            const float a0 = lanes[0], b0 = lanes[1], a1 = -lanes[2], b1 = -lanes[3];
            const bool ha = a0 <= a1, hb = b0 <= b1;
            count.box_test(2);
            if (ha && hb) {
                // The nearer first; the other later, unless a hit ends the ray first.
                if (b0 < a0) {
                    stack[top++] = {left, a0, a1};
                    index = left + 1;
                    t0 = b0;
                    t1 = b1;
                } else {
                    stack[top++] = {left + 1, b0, b1};
                    index = left;
                    t0 = a0;
                    t1 = a1;
                }
                continue;
            }
            if (ha || hb) {
                index = ha ? left : left + 1;
                t0 = ha ? a0 : b0;
                t1 = ha ? a1 : b1;
                continue;
            }
        } else {
            const uint32_t n = node.count();
            for (uint32_t i = 0; i < n; ++i) {
                const uint32_t p = refs[node.first + i];
                count.test(p);
                TriangleHit th;
                const Triangle& tri = tris[p];
                if (intersect_triangle(sray, tri, tmin, hit.t, th, hit.td, int32_t(p) < hit.prim) &&
                    leaf_accepts(tri.bounds(), org, dir, t0, std::min(t1, hit.reach), th.t, t_e,
                                 pad)) {
                    count.hit(th.t);
                    hit.take(th.t, th.td, p, th.u, th.v, t_e);
                } else {
                    count.miss();
                }
            }
        }
        if (!pop_cell(stack, top, hit.reach, index, t0, t1)) break;
    }
}

// Rays [begin, end) one by one through `trace_one` (a BVH walk: the binary
// one below, the wide one of bvh_wide_single_ray.hpp), in and out of the
// tree's scaled space as single_ray.hpp's trace_rays does.
template <class Counters, class TraceOne>
void trace_bvh_rays(const TreeView& view, const RayBatch& rays, const HitBatch& hits,
                    size_t begin, size_t end, TraceOne trace_one) {
    const double scale = view.scale, inv_scale = 1.0 / view.scale;
    for (size_t i = begin; i < end; ++i) {
        const float* o = rays.origins + 3 * i;
        const float* d = rays.directions + 3 * i;
        Closest c;
        Counters count;
        const float tmin = rays.tmin[i * rays.tmin_stride];
        const float tmax = rays.tmax[i * rays.tmax_stride];
        if (scale == 1.0 && !view.moved) {
            trace_one(view, Vec3(o[0], o[1], o[2]), Vec3(d[0], d[1], d[2]), tmin, tmax, c, count);
        } else {
            const Vec3 so = to_tree_space(view, o);
            trace_one(view, so, Vec3(d[0], d[1], d[2]), float(tmin * scale), float(tmax * scale),
                      c, count);
            c.t = float(c.t * inv_scale);
            if (!(c.t < tmax)) c.prim = -1;
        }
        const bool is_hit = c.prim >= 0;
        hits.t[i] = is_hit ? c.t : kInf;
        hits.prim[i] = c.prim;
        hits.u[i] = is_hit ? c.u : 0.0f;
        hits.v[i] = is_hit ? c.v : 0.0f;
        count.store(hits, i);
    }
}

// The binary walk's rays (kernel_set.hpp).
template <class Counters>
void bvh_trace_rays(const TreeView& view, const RayBatch& rays, const HitBatch& hits,
                    size_t begin, size_t end) {
    // A lambda, not a function pointer: a call the compiler always inlines.
    trace_bvh_rays<Counters>(view, rays, hits, begin, end,
                             [](auto&&... a) { bvh_trace_one(a...); });
}

}  // namespace
}  // namespace bsp::BSPLAB_ISA_NS
