// The BVH's single-ray kernel: the walk of the 8-wide nodes
// (bvh_wide_node.hpp) that builders/bvh_collapse.cpp makes of the binary
// tree. At each node one eight-lane slab test gives every child's range; the
// children entered are visited nearest first (the others pushed, farthest
// first), with early exit, the same walk start, the same triangle test, the
// same leaf acceptance and the same tie rule as the binary walk
// (bvh_single_ray.hpp) - whose hits it gives bit for bit.
//
// Why bit for bit: each lane's arithmetic is BvhPairTest's exactly - the
// near face's crossing (x - o) * r - e and the far face's (x - o) * r + e,
// where the pair test computes -((x - o) * r) - e = -((x - o) * r + e); MAXPS
// and MINPS return their second operand where the first is NaN (a ray in a
// face plane) and where both are zeros, as the pair test's accumulator does.
// The leaves are the binary tree's, so a leaf is entered with the same range
// and accepts the same hits; only the order of the visits differs, and the
// closest hit with its tie rule (of equal t the nearer in double, then the
// smallest triangle index)
// does not depend on the order.
//
// Every path walks it - hits only, packets, counting, trace_path - so that
// every path gives the same answer bit for bit. (Not quite order-free: a
// ray lying in a triangle's plane gets a meaningless plane distance, which
// a leaf accepts where its walk range meets the triangle's box, so for such
// rays a visit order can decide which of two leaves answers first. The
// binary walk, bvh_single_ray.hpp, is kept as the reference of the C++
// tests on rays off the triangles' planes, and for the layout benchmark.)
//
// Included by kernels/trace_kernels.cpp inside one instruction-set level's
// namespace, like single_ray.hpp.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>

#include <immintrin.h>

#include "bvh_wide_node.hpp"
#include "trace/kernels/bvh_single_ray.hpp"

#ifndef BSPLAB_ISA_NS
#error "bvh_wide_single_ray.hpp is compiled per instruction set: include it from trace_kernels.cpp"
#endif

namespace bsp::BSPLAB_ISA_NS {
namespace {

constexpr int kWidth = BvhWideNode::kWidth;
static_assert(kWidth == 8, "the lane vectors below hold eight floats");

// Up to kWidth - 1 children pushed per wide node, one wide node per binary
// level at most.
constexpr int kBvhWideStack = (kWidth - 1) * 64 + kWidth;

struct WideStackEntry {
    uint32_t child, count;  // a wide node (count = kInterior) or a leaf's refs[] slice
    float tmin, tmax;
    uint32_t lane;  // kWidth x its wide node + its lane: its binary node, for the counters
};

// One face of the eight children: one AVX register on the AVX2 and AVX-512
// levels, two SSE registers on the SSE level. Each operation is the same
// IEEE single operation lane by lane on every level (MAXPS and MINPS
// included, with their operand order), so every level's walk is the same.
#if defined(__AVX__)
struct LaneFloats {
    __m256 v;
    static LaneFloats load(const char* p) { return {_mm256_load_ps(reinterpret_cast<const float*>(p))}; }
    static LaneFloats all(float x) { return {_mm256_set1_ps(x)}; }
    friend LaneFloats operator-(LaneFloats a, LaneFloats b) { return {_mm256_sub_ps(a.v, b.v)}; }
    friend LaneFloats operator+(LaneFloats a, LaneFloats b) { return {_mm256_add_ps(a.v, b.v)}; }
    friend LaneFloats operator*(LaneFloats a, LaneFloats b) { return {_mm256_mul_ps(a.v, b.v)}; }
    // MAXPS / MINPS: b where a is NaN, and where both are zeros.
    friend LaneFloats max_of(LaneFloats a, LaneFloats b) { return {_mm256_max_ps(a.v, b.v)}; }
    friend LaneFloats min_of(LaneFloats a, LaneFloats b) { return {_mm256_min_ps(a.v, b.v)}; }
    friend int le_bits(LaneFloats a, LaneFloats b) {
        return _mm256_movemask_ps(_mm256_cmp_ps(a.v, b.v, _CMP_LE_OQ));
    }
    friend int gt_bits(LaneFloats a, LaneFloats b) {
        return _mm256_movemask_ps(_mm256_cmp_ps(a.v, b.v, _CMP_GT_OQ));
    }
    friend int eq_bits(LaneFloats a, LaneFloats b) {
        return _mm256_movemask_ps(_mm256_cmp_ps(a.v, b.v, _CMP_EQ_OQ));
    }
    void store(float* out) const { _mm256_store_ps(out, v); }
};
#else
struct LaneFloats {
    __m128 a, b;
    static LaneFloats load(const char* p) {
        const float* f = reinterpret_cast<const float*>(p);
        return {_mm_load_ps(f), _mm_load_ps(f + 4)};
    }
    static LaneFloats all(float x) { return {_mm_set1_ps(x), _mm_set1_ps(x)}; }
    friend LaneFloats operator-(LaneFloats x, LaneFloats y) { return {_mm_sub_ps(x.a, y.a), _mm_sub_ps(x.b, y.b)}; }
    friend LaneFloats operator+(LaneFloats x, LaneFloats y) { return {_mm_add_ps(x.a, y.a), _mm_add_ps(x.b, y.b)}; }
    friend LaneFloats operator*(LaneFloats x, LaneFloats y) { return {_mm_mul_ps(x.a, y.a), _mm_mul_ps(x.b, y.b)}; }
    friend LaneFloats max_of(LaneFloats x, LaneFloats y) { return {_mm_max_ps(x.a, y.a), _mm_max_ps(x.b, y.b)}; }
    friend LaneFloats min_of(LaneFloats x, LaneFloats y) { return {_mm_min_ps(x.a, y.a), _mm_min_ps(x.b, y.b)}; }
    friend int le_bits(LaneFloats x, LaneFloats y) {
        return _mm_movemask_ps(_mm_cmple_ps(x.a, y.a)) | (_mm_movemask_ps(_mm_cmple_ps(x.b, y.b)) << 4);
    }
    friend int gt_bits(LaneFloats x, LaneFloats y) {
        return _mm_movemask_ps(_mm_cmpgt_ps(x.a, y.a)) | (_mm_movemask_ps(_mm_cmpgt_ps(x.b, y.b)) << 4);
    }
    friend int eq_bits(LaneFloats x, LaneFloats y) {
        return _mm_movemask_ps(_mm_cmpeq_ps(x.a, y.a)) | (_mm_movemask_ps(_mm_cmpeq_ps(x.b, y.b)) << 4);
    }
    void store(float* out) const {
        _mm_store_ps(out, a);
        _mm_store_ps(out + 4, b);
    }
};
#endif

// A pushed item's first bytes - a wide node's four cache lines, or a leaf's
// first triangles - asked of memory when it is pushed, not when it is
// popped: on incoherent rays most nodes are not in cache, and a pushed item
// is usually popped a few nodes later, so its misses overlap the walk of
// the nearer subtree instead of stalling it.
inline void prefetch_item(const BvhWideNode* nodes, const BvhLeafTriangle* leaf_tris,
                          uint32_t child, uint32_t count) {
    const char* at = count == BvhWideNode::kInterior
                         ? reinterpret_cast<const char*>(nodes + child)
                         : reinterpret_cast<const char*>(leaf_tris + child);
    for (int line = 0; line < 4; ++line) _mm_prefetch(at + 64 * line, _MM_HINT_T0);
}

// The eight-lane slab test (see the file's comment).
struct BvhLaneTest {
    LaneFloats org[3], idir[3], err[3];
    // Byte offsets in a node of each axis's near and far faces: the high one
    // is near where d[k] < 0 (or -0). Chosen once per ray, so that the node
    // test loads the faces it needs and selects nothing.
    size_t near_at[3], far_at[3];

    explicit BvhLaneTest(const BvhRay& r) {
        for (int k = 0; k < 3; ++k) {
            org[k] = LaneFloats::all(r.org[k]);
            idir[k] = LaneFloats::all(r.idir[k]);
            err[k] = LaneFloats::all(r.err[k]);
            const size_t lo = offsetof(BvhWideNode, lo) + k * sizeof(float[kWidth]),
                         hi = offsetof(BvhWideNode, hi) + k * sizeof(float[kWidth]);
            near_at[k] = r.neg[k] ? hi : lo;
            far_at[k] = r.neg[k] ? lo : hi;
        }
    }

    // The lanes the ray enters within [s0, s1]; their ranges in enter/exit.
    int test(const BvhWideNode& n, float s0, float s1, float* enter, float* exit) const {
        LaneFloats en = LaneFloats::all(s0), ex = LaneFloats::all(s1);
        const char* base = reinterpret_cast<const char*>(&n);
        for (int k = 0; k < 3; ++k) {
            const LaneFloats nearf = LaneFloats::load(base + near_at[k]);
            const LaneFloats farf = LaneFloats::load(base + far_at[k]);
            en = max_of((nearf - org[k]) * idir[k] - err[k], en);
            ex = min_of((farf - org[k]) * idir[k] + err[k], ex);
        }
        en.store(enter);
        ex.store(exit);
        return le_bits(en, ex);
    }
};

// One ray through the wide BVH. The counters (bvh_single_ray.hpp's hooks)
// see the binary nodes the walk enters: the root, then every lane the walk
// takes, interior or leaf (so steps are the nodes visited, as on the
// binary walk, without the levels the wide nodes skip), and the box tests
// of the wide nodes visited, eight each, plus the root's box.
template <class Counters>
__attribute__((always_inline)) inline void bvh_wide_trace_one(const TreeView& tree, const Vec3& o,
                                                              const Vec3& d, float tmin,
                                                              float tmax, Closest& hit,
                                                              Counters& count_) {
    const BvhWalkStart w(tree, o, d, tmin, tmax, hit);
    count_.box_test(1);
    if (!w.in_box) return;
    const BvhLaneTest lanes(w.ray);
    const double t_e = w.rw.walk.t_e;
    const float *dir = w.rw.dir, *org = w.rw.walk.org;
    const float s_lo = w.rw.s_lo, s_hi = w.rw.s_hi, pad = w.pad;
    const ShearedRay& sray = w.sray;
    float t0 = w.t0, t1 = w.t1;
    const BvhLeafTriangle* leaf_tris = tree.bvh_leaf_tris;
    const BvhWideNode* nodes = tree.bvh_wide;
    const uint32_t* binary_of = tree.bvh_wide_binary;
    WideStackEntry stack[kBvhWideStack];
    int top = 0;
    // The current item: a wide node, or a leaf (count != kInterior).
    uint32_t child = 0, count = BvhWideNode::kInterior;
    if (tree.bvh_nodes[0].is_leaf()) {  // a tree of one leaf: the wide root's lane 0 is it
        child = nodes[0].first(0);
        count = nodes[0].leaf_count(0);
    }
    count_.step(0, t0, t1, t_e);
    // Makes a stack entry the current item.
    const auto enter = [&](const WideStackEntry& e) {
        child = e.child;
        count = e.count;
        t0 = e.tmin;
        t1 = e.tmax;
        count_.step(binary_of[e.lane], t0, t1, t_e);
    };
    for (;;) {
        if (count == BvhWideNode::kInterior) {
            const BvhWideNode& node = nodes[child];
            count_.box_test(BvhWideNode::kWidth);
            alignas(32) float en[kWidth], ex[kWidth];
            const int mask = lanes.test(node, s_lo, std::min(s_hi, hit.reach), en, ex);
            if (mask != 0) {
                // Lane l of this node as stack entry `slot`, its item fetched.
                const auto push_at = [&](int slot, int l) {
                    stack[slot] = {node.child[l], node.count[l], en[l], ex[l],
                                   BvhWideNode::kWidth * child + uint32_t(l)};
                    prefetch_item(nodes, leaf_tris, node.child[l], node.count[l]);
                };
                // The nearest entered lane is taken now; the others are
                // pushed farthest first, so that they pop nearest first
                // (ties: the higher lane is taken first). One and two lanes
                // - most nodes of incoherent rays - are decided apart.
                unsigned rest = unsigned(mask);
                const int l0 = __builtin_ctz(rest);
                rest &= rest - 1;
                int take = l0;
                if (rest != 0) {
                    const int l1 = __builtin_ctz(rest);
                    rest &= rest - 1;
                    if (rest == 0) {
                        const bool first_nearer = en[l0] < en[l1];
                        const int push = first_nearer ? l1 : l0;
                        take = first_nearer ? l0 : l1;
                        push_at(top++, push);
                    } else {
                        // Three lanes or more: each one's rank among them by
                        // entry, farthest first (ties: the lower lane first),
                        // from two lane compares, and each written to its
                        // place on the stack - no branch on the entries (an
                        // insertion sort's loops mispredicted about five times
                        // a ray, callgrind, sportscar, random rays). The
                        // nearest, on top, is taken.
                        const LaneFloats entries = LaneFloats::load(reinterpret_cast<const char*>(en));
                        const unsigned entered = unsigned(mask);
                        for (unsigned m = entered; m; m &= m - 1) {
                            const int l = __builtin_ctz(m);
                            const LaneFloats mine = LaneFloats::all(en[l]);
                            const unsigned before =
                                (unsigned(gt_bits(entries, mine)) |
                                 (unsigned(eq_bits(entries, mine)) & ((1u << l) - 1u))) &
                                entered;
                            push_at(top + __builtin_popcount(before), l);
                        }
                        top += __builtin_popcount(entered) - 1;
                        enter(stack[top]);
                        continue;
                    }
                }
                const uint32_t at = BvhWideNode::kWidth * child + uint32_t(take);
                child = node.child[take];
                count = node.count[take];
                t0 = en[take];
                t1 = ex[take];
                count_.step(binary_of[at], t0, t1, t_e);
                continue;
            }
        } else {
            for (uint32_t i = 0; i < count; ++i) {
                const BvhLeafTriangle& leaf = leaf_tris[child + i];
                const uint32_t p = leaf.prim;
                count_.test(p);
                TriangleHit th;
                const Triangle& tri = leaf.tri;
                if (intersect_triangle(sray, tri, tmin, hit.t, th, hit.td, int32_t(p) < hit.prim) &&
                    leaf_accepts(tri.bounds(), org, dir, t0, std::min(t1, hit.reach), th.t, t_e,
                                 pad)) {
                    count_.hit(th.t);
                    hit.take(th.t, th.td, p, th.u, th.v, t_e);
                } else {
                    count_.miss();
                }
            }
        }
        // The next entry the ray can still reach.
        for (;;) {
            if (top == 0) return;
            const WideStackEntry& e = stack[--top];
            if (!(hit.reach < e.tmin)) {
                enter(e);
                break;
            }
        }
    }
}

// The wide walk's rays (kernel_set.hpp), through trace_bvh_rays.
template <class Counters>
void bvh_wide_trace_rays(const TreeView& view, const RayBatch& rays, const HitBatch& hits,
                         size_t begin, size_t end) {
    trace_bvh_rays<Counters>(view, rays, hits, begin, end,
                             [](auto&&... a) { bvh_wide_trace_one(a...); });
}

}  // namespace
}  // namespace bsp::BSPLAB_ISA_NS
