// The single-ray kernel: front-to-back traversal of kd and general nodes
// with early exit (pbrt-v3 / Havran style), a small per-ray mailbox, and the
// watertight triangle test. Included by kernels/trace_kernels.cpp only, inside
// the namespace of one instruction-set level (BSPLAB_ISA_NS), with internal
// linkage: every level gets its own copy, and none leaks into another.
#pragma once
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <type_traits>

#include "trace/kernel_inlining.hpp"
#include "trace/traverse.hpp"
#include "trace/triangle.hpp"
#include "trace/kernels/in_plane.hpp"
#include "trace/kernels/leaf_acceptance.hpp"
#include "trace/kernels/leaf_simd.hpp"
#include "trace/kernels/tree_view.hpp"
#include "trace/kernels/walk_start.hpp"
#include "trace/ray_coherence.hpp"

#ifndef BSPLAB_ISA_NS
#error "single_ray.hpp is compiled per instruction set: include it from trace_kernels.cpp"
#endif

namespace bsp::BSPLAB_ISA_NS {
namespace {

// A triangle referenced by several leaves is tested once per ray: a small
// direct-mapped table of the last triangles tested. A collision only costs a
// repeated test, never a wrong answer, because the closest hit is kept
// whichever leaf found it.
struct Mailbox {
    static constexpr uint32_t kSize = 16;
    uint32_t slot[kSize];
    Mailbox() { std::fill(slot, slot + kSize, 0xFFFFFFFFu); }
    bool seen(uint32_t prim) {
        uint32_t& s = slot[prim & (kSize - 1)];
        if (s == prim) return true;
        s = prim;
        return false;
    }
    // Unmarks `prim`: a leaf rejected its hit (leaf_acceptance.hpp), and a
    // later leaf may accept it.
    void forget(uint32_t prim) {
        uint32_t& s = slot[prim & (kSize - 1)];
        if (s == prim) s = 0xFFFFFFFFu;
    }
};

// The closest hit so far. Of equally close hits (the same float t) the
// nearer in double (td, ray_distance) wins, and of those the smallest
// triangle index, on every path (counting or not, culling or not, SIMD
// leaves, packets, any thread count), so which leaf finds a hit first never
// changes the answer: two triangles sharing an edge the ray meets exactly,
// or coinciding, give one answer everywhere. (By the float t alone the
// early exit had to go on through every cell a hit could round to the same
// float in: from 10^7 scene sizes away, half the scene; walk_reach_exact.)
struct Closest {
    float t;
    int32_t prim = -1;
    float u = 0, v = 0;
    double td = -INFINITY;  // no hit yet: nothing ties with tmax
    // The walk parameter beyond which no cell can hold a hit as close
    // (walk_reach, walk_reach_exact): the early exit's and the cull box's end.
    float reach;

    bool beaten_by(float t_new, double td_new, uint32_t p) const {
        return t_new < t || (t_new == t && (td_new < td || (td_new == td && int32_t(p) < prim)));
    }
    void take(float t_new, double td_new, uint32_t p, float u_new, float v_new, double t_e) {
        t = t_new;
        td = td_new;
        prim = int32_t(p);
        u = u_new;
        v = v_new;
        reach = walk_reach_exact(td_new, t_e);
    }
};

// What every walk of one ray (trace_one here, the BVH's walks) starts from:
// the ray as plain arrays (the axis is a run-time index in the hot loops),
// its walk start (walk_start.hpp), the walk's range [s_lo, s_hi] for the
// ray's [tmin, tmax], and the closest hit reset to tmax.
struct RayWalk {
    float dir[3], idir[3];
    WalkStart walk;
    float s_lo, s_hi;

    RayWalk(const TreeView& tree, const Vec3& o, const Vec3& d, float tmin, float tmax,
            Closest& hit)
        : dir{d.x, d.y, d.z},
          idir{1.0f / d.x, 1.0f / d.y, 1.0f / d.z},
          walk(tree, std::array<float, 3>{o.x, o.y, o.z}.data(), dir, idir),
          s_lo(walk_lower(tmin, walk.t_e)),
          s_hi(walk_upper(tmax, walk.t_e)) {
        hit.t = tmax;
        hit.reach = walk_reach(tmax, walk.t_e);
    }

    // The triangle test's ray: from the walk origin for a far ray
    // (ShearedRay::t_offset, kFarTestSizes), with the precision of a point
    // inside the box; else from the ray's own origin.
    ShearedRay test_ray() const {
        return ShearedRay(Vec3(walk.test_org[0], walk.test_org[1], walk.test_org[2]),
                          Vec3(dir[0], dir[1], dir[2]), walk.test_t);
    }
};

// Clips the walk's range [s0, s1] to the box, every face's crossing widened
// by its error bound (walk_start.hpp); false when the ray misses the box.
bool clip_to_box(const Box& b, const float o[3], const float inv[3], const float d[3],
                 const float org_err[3], float& s0, float& s1) {
    for (int k = 0; k < 3; ++k) {
        if (d[k] == 0.0f) {
            if (o[k] < b.lo[k] || o[k] > b.hi[k]) return false;
            continue;
        }
        float tn = (b.lo[k] - o[k]) * inv[k];
        float tf = (b.hi[k] - o[k]) * inv[k];
        if (tn > tf) std::swap(tn, tf);
        tn -= org_err[k] + std::fabs(tn) * kCrossRel;
        tf += org_err[k] + std::fabs(tf) * kCrossRel;
        s0 = std::max(s0, tn);
        s1 = std::min(s1, tf);
        if (s0 > s1) return false;
    }
    return true;
}

// A leaf without triangles: its whole 8 bytes' `bits` are the leaf tag
// (count 0), so one compare of the child's bits tells it.
constexpr uint32_t kEmptyLeafBits = Node::kLeafTag;
inline bool is_empty_leaf(const Node& n) { return n.bits == kEmptyLeafBits; }

struct StackEntry {
    uint32_t node;
    float tmin, tmax;
};

// The in-plane walk's stack entry: also the sides of the remembered planes
// its cell lies on (in_plane.hpp).
struct InPlaneStackEntry : StackEntry {
    InPlaneWalk::Sides sides;
};

// The counters are a compile-time policy of the traversal: CountEvery keeps
// the heatmaps' and the statistics' counts of one ray, CountNothing is the
// hits-only path, whose empty hooks leave no counting code behind. The hooks
// say what the traversal does (a node visited over the walk's [s0, s1],
// t = t_e + s, walk_start.hpp; a triangle
// culled, skipped by the mailbox, tested, hit or missed), so that a policy
// can also record the whole walk: trace_path.cpp's PathRecord does, for the
// ray inspector, with this very loop.
struct CountEvery {
    uint32_t steps = 0, general_steps = 0, tests = 0, culled = 0;
    // The walk starts again, in the in-plane walk (trace_ray): what the
    // ordinary walk counted until then is not part of the ray's walk.
    void restart() { *this = CountEvery(); }
    void step(uint32_t /*node*/, float /*s0*/, float /*s1*/, double /*t_e*/) { ++steps; }
    void general_step() { ++general_steps; }
    void cull(uint32_t /*prim*/) { ++culled; }
    void seen(uint32_t /*prim*/) {}
    void test(uint32_t /*prim*/) { ++tests; }
    void hit(float /*t*/) {}
    void miss() {}
    void store(const HitBatch& hits, size_t i) const {
        hits.steps[i] = steps;
        hits.general_steps[i] = general_steps;
        hits.tests[i] = tests;
        hits.culled[i] = culled;
    }
};

struct CountNothing {
    void restart() {}
    void step(uint32_t, float, float, double) {}
    void general_step() {}
    void cull(uint32_t) {}
    void seen(uint32_t) {}
    void test(uint32_t) {}
    void hit(float) {}
    void miss() {}
    void store(const HitBatch&, size_t) const {}
};

// Leaves of this many triangles or more take the SIMD blocks on the
// hits-only path. Smaller leaves - nearly all of a SAH tree's - stay scalar:
// blocks for them ran fewer instructions (-4 % to -13 % of the trace,
// callgrind) but took more time against Embree in paired rounds (primary
// rays on sponza and sibenik -8 to -10 % with blocks from 2 triangles up,
// -4 % from 5 up); from 8 up the shared scenes' kd trees time as before and
// trees with big leaves (intersect_cost 0.3) trace random rays 10-19 %
// faster (docs/performance.md has the figures).
constexpr uint32_t kSimdLeafMin = 8;
// Even where no leaf takes the blocks, their code in the traversal loop cost
// the default kd trees (3 references per non-empty leaf) 1-4 % of their
// speed; so only trees whose leaves are big on average get the
// instantiation with blocks (trace_single_rays).
constexpr float kSimdLeafMean = 6.0f;

// The hits-only path's leaf: the edge functions of up to `L` triangles at
// a time in SIMD (leaf_simd.hpp), then, for the lanes that pass, in leaf
// order, the cull box, the plane distance and u, v as in intersect_triangle.
// Every lane's arithmetic is the scalar test's, and the passing lanes meet
// the running hit.t (strict <) and the shrinking segment box in the same
// order as the scalar loop's triangles, so the closest hit, and which of
// equally close triangles is kept (the first), are the scalar path's.
//
// No mailbox here. Re-testing a triangle that an earlier leaf of this ray
// tested (and did not cull) cannot change the hit: if it hit then, hit.t has
// been <= its t since, and the strict < rejects it now; if it missed, it
// misses again, the same arithmetic giving the same edge functions and t
// against a hit.t that has only shrunk. (A culled triangle never entered the
// mailbox in the first place.) The block tests all its lanes anyway, so a
// mailbox could only save the plane distance of a passing lane: it saved
// 0.3 % of the instructions on bunny, sponza and conference and no time in
// paired rounds, so this path goes without. (Smaller leaves keep the
// scalar loop, mailbox included.)
//
// noinline (and flatten, so that the shared inline functions it calls are
// still inlined, see trace_kernels.cpp): inlined, the blocks' code made the
// rest of the traversal loop slower even where no leaf took them.
template <uint32_t L, LeafBoxes kBoxes>
__attribute__((noinline)) BSPLAB_KERNEL_FLATTEN void intersect_leaf_hits_only(
    const TreeView& tree, Node node, const uint32_t* list, uint32_t n_refs,
    const ShearedRay& sray, const float org[3], const float dir[3], float t0, float t1,
    float tmin, double t_e, float pad, Closest& hit) {
    SegmentBox seg;
    if constexpr (kBoxes != LeafBoxes::None)
        seg.set(org, dir, t0, std::min(t1, hit.reach), pad);
    for (uint32_t first = 0; first < n_refs; first += L) {
        const EdgeBlock<L> e =
            edge_test_block<L>(sray, tree.tris, list + first, std::min(L, n_refs - first));
        for (uint32_t lanes = e.passed; lanes; lanes &= lanes - 1) {
            const uint32_t lane = uint32_t(__builtin_ctz(lanes));
            const uint32_t p = list[first + lane];
            if constexpr (kBoxes != LeafBoxes::None) {
                const uint32_t box = kBoxes == LeafBoxes::Triangle ? p : node.first + first + lane;
                if (seg.misses(tree.boxes[box])) continue;
            }
            const double td = ray_distance(tree.tris[p], sray);
            const float t = float(td);
            if (!(t > tmin && hit.beaten_by(t, td, p))) continue;
            if (tree.box_kind != LeafBoxes::None &&
                !leaf_accepts(culling_box(tree, p, node.first + first + lane), org, dir, t0,
                              std::min(t1, hit.reach), t, t_e, pad))
                continue;
            float u, v;
            barycentrics(e.U[lane], e.V[lane], e.W[lane], u, v);
            hit.take(t, td, p, u, v, t_e);
            if constexpr (kBoxes != LeafBoxes::None)
                seg.set(org, dir, t0, std::min(t1, hit.reach), pad);
        }
    }
}

// Tests the triangles of leaf `index` (node `node`) over the ray's range
// [t0, t1] in it, keeping the closest hit in `hit`. The counting path tests
// one triangle at a time, so that its counts of tests and culls keep their
// meaning; the hits-only path tests big leaves in SIMD blocks.
template <LeafBoxes kBoxes, bool kSimdLeaves, class Counters>
inline void intersect_leaf(const TreeView& tree, Node node, uint32_t index, const ShearedRay& sray,
                           const float org[3], const float dir[3], float t0, float t1, float tmin,
                           double t_e, float pad, Mailbox& mailbox, Closest& hit,
                           Counters& count) {
    const uint32_t n_refs = node.count();
    const uint32_t* list =
        n_refs == 1 && tree.inline_single ? &tree.nodes[index].first : tree.refs + node.first;
    if constexpr (kSimdLeaves) {
        static_assert(std::is_same_v<Counters, CountNothing>, "the counting path tests one by one");
        if (n_refs >= kSimdLeafMin) {
            intersect_leaf_hits_only<kWideLanes, kBoxes>(tree, node, list, n_refs, sray, org,
                                                         dir, t0, t1, tmin, t_e, pad, hit);
            return;
        }
    }
    SegmentBox seg;
    if constexpr (kBoxes != LeafBoxes::None)
        seg.set(org, dir, t0, std::min(t1, hit.reach), pad);
    for (uint32_t i = 0; i < n_refs; ++i) {
        const uint32_t p = list[i];
        if constexpr (kBoxes != LeafBoxes::None) {
            // A culled triangle is not marked in the mailbox: it may
            // still be hit in a later leaf that references it.
            const Box& b = tree.boxes[kBoxes == LeafBoxes::Triangle ? p : node.first + i];
            if (seg.misses(b)) {
                count.cull(p);
                continue;
            }
        }
        if (mailbox.seen(p)) {
            count.seen(p);
            continue;
        }
        count.test(p);
        TriangleHit th;
        bool accepted = intersect_triangle(sray, tree.tris[p], tmin, hit.t, th, hit.td,
                                           int32_t(p) < hit.prim);
        if (accepted && tree.box_kind != LeafBoxes::None &&
            !leaf_accepts(culling_box(tree, p, node.first + i), org, dir, t0,
                          std::min(t1, hit.reach), th.t, t_e, pad)) {
            accepted = false;
            mailbox.forget(p);  // another leaf may accept it
        }
        if (accepted) {
            count.hit(th.t);
            hit.take(th.t, th.td, p, th.u, th.v, t_e);
            if constexpr (kBoxes != LeafBoxes::None)
                seg.set(org, dir, t0, std::min(t1, hit.reach), pad);
        } else {
            count.miss();
        }
    }
}

// Pops the next cell of the stack that may still hold a hit as close as the
// closest hit (whose walk parameter is at most `reach`); false when none is
// left. A cell that starts beyond it cannot improve it. Cells deeper in the stack usually lie beyond it too, but
// not always (a ray in a plane visits both sides over its whole range), so
// the search goes on rather than stopping at the first such cell.
// The check is needed here only: while the ray descends, neither its entry
// distance t0 nor the closest hit changes.
inline bool pop_cell(const StackEntry* stack, int& top, float reach, uint32_t& index, float& t0,
                     float& t1) {
    while (top > 0) {
        const StackEntry& e = stack[--top];
        if (!(reach < e.tmin)) {
            index = e.node;
            t0 = e.tmin;
            t1 = e.tmax;
            return true;
        }
    }
    return false;
}

// The same for the in-plane walk, which also takes back the cell's sides.
inline bool pop_cell(const InPlaneStackEntry* stack, int& top, float reach, uint32_t& index,
                     float& t0, float& t1, InPlaneWalk::Sides& sides) {
    while (top > 0) {
        const InPlaneStackEntry& e = stack[--top];
        if (!(reach < e.tmin)) {
            index = e.node;
            t0 = e.tmin;
            t1 = e.tmax;
            sides = e.sides;
            return true;
        }
    }
    return false;
}

// One ray through the tree. kGeneral = false is the kd-only instantiation
// for trees without general nodes (TreeView::has_general): every interior
// node is then a kd node, and the general node's plane arithmetic and its
// branch drop out of the hot loop. kPrefetchAbove: the loop for incoherent
// rays (trace_single_rays), which also skips more empty children from their
// parent (see the three cases below). kInPlane: the in-plane walk (in_plane.hpp),
// which remembers the planes the ray lies in and skips their flat cells.
// The ordinary walk returns false, its work undone, for a ray that may lie
// in a kd plane (at its start) or a general one (at the first general node
// it is parallel to): trace_ray then takes the in-plane walk.
template <LeafBoxes kBoxes, bool kGeneral, bool kSimdLeaves, bool kPrefetchAbove, bool kInPlane,
          class Counters>
bool trace_one(const TreeView& tree, const Vec3& o, const Vec3& d, float tmin, float tmax,
               Closest& hit, Counters& count) {
    // The walk runs from the ray's entry into the scene box (walk_start.hpp):
    // its t0, t1 and crossings are s = t - t_e; the hits keep the ray's t.
    const RayWalk ray(tree, o, d, tmin, tmax, hit);
    const WalkStart& walk = ray.walk;
    const float *dir = ray.dir, *idir = ray.idir, *org = walk.org;
    const double t_e = walk.t_e;
    float t0 = ray.s_lo, t1 = ray.s_hi;
    if (!clip_to_box(tree.bounds, org, idir, dir, walk.org_err, t0, t1)) return true;
    float axis_err[3];
    axis_crossing_errors(walk, t0, t1, axis_err);
    const ShearedRay sray = ray.test_ray();
    // Locals, so that the hot loop keeps them in registers.
    const Node* nodes = tree.nodes;
    const Plane* planes = tree.planes;
    // A general plane's crossing is widened to [t - err, t + err] with
    //   err = (cross_a + |t| cross_b) / |n.d|
    // (walk_start.hpp says what the terms bound), an axis crossing - a kd
    // node's - by axis_err[axis].
    const float cross_a = walk.cross_a, cross_b = walk.cross_b;
    // The leaves' box padding: the builders' (cull_pad), and the triangle
    // test's displacement from the exact ray (walk_start.hpp, kTestRel).
    const float pad = tree.cull_pad + walk.slack;
    Mailbox mailbox;
    using Entry = std::conditional_t<kInPlane, InPlaneStackEntry, StackEntry>;
    Entry stack[72];
    int top = 0;
    uint32_t index = 0;
    // The in-plane walk's planes, and the sides of them the cell lies on. A
    // ray lying in a face plane of the scene box starts on its inner side.
    InPlaneWalk in_plane;
    InPlaneWalk::Sides sides = 0;
    if constexpr (kInPlane) {
        for (int k = 0; k < 3; ++k) {
            if (dir[k] != 0.0f) continue;
            if (org[k] == tree.bounds.lo[k]) {
                const int i = in_plane.index_of(axis_plane(k, tree.bounds.lo[k]));
                if (i >= 0) sides = InPlaneWalk::with(sides, i, PlaneSide::Above);
            } else if (org[k] == tree.bounds.hi[k]) {
                const int i = in_plane.index_of(axis_plane(k, tree.bounds.hi[k]));
                if (i >= 0) sides = InPlaneWalk::with(sides, i, PlaneSide::Below);
            }
        }
    }

    // Skipping an empty exit child changes which nodes the walk visits
    // (steps), so only the hits-only path does it (see below).
    constexpr bool kSkipEmptyExit =
        kPrefetchAbove && std::is_same_v<Counters, CountNothing>;
    for (;;) {
        const Node node = nodes[index];
        count.step(index, t0, t1, t_e);
        if (kGeneral ? !node.is_leaf() : node.is_kd()) {
            // Both kinds reduce to: where the ray crosses the plane, and
            // which child it enters from. Before the crossing the ray is on
            // the side it moves away from (the entry side), after it on the
            // side it moves towards. Deciding by the direction's sign rather
            // than by the origin's side keeps every case consistent,
            // including rays parallel to the plane (t = +-inf) and rays lying
            // in it (t = NaN: both sides).
            float tplane, err;
            bool down;  // the ray moves towards the child below the plane
            uint32_t above_child;
            if (!kGeneral || node.is_kd()) {
                const int axis = node.axis();
                tplane = (node.split - org[axis]) * idir[axis];
                err = axis_err[axis];
                down = std::signbit(dir[axis]);
                above_child = node.kd_above();
                // Incoherent rays: fetch the child above the plane now,
                // whichever child the ray takes. The child below follows its
                // parent (most often in the same cache line), the one above
                // lies anywhere. The branches below mispredict about once a
                // step on such rays, and the path the processor then really
                // takes starts with a node already on its way (random rays
                // about 4 % faster against Embree, median of the shared
                // scenes; on camera rays, whose branches predict well, the
                // extra fetch cost 1-7 %: docs/performance.md).
                if constexpr (kPrefetchAbove) __builtin_prefetch(nodes + above_child);
            } else {
                count.general_step();
                const Plane& p = planes[node.first];
                const float no = p.nx * org[0] + p.ny * org[1] + p.nz * org[2];
                const float nd = p.nx * dir[0] + p.ny * dir[1] + p.nz * dir[2];
                const float inv_nd = 1.0f / nd;
                // Parallel to the plane (or within a denormal of it): the ray
                // may lie in it, which the in-plane walk handles.
                if constexpr (!kInPlane)
                    if (!(std::fabs(inv_nd) < kInf)) [[unlikely]]
                        return false;
                tplane = (p.d - no) * inv_nd;
                // Parallel to the plane (t = +-inf): on the origin's side for
                // good, unless the origin lies within the error of the plane.
                err = nd != 0.0f ? (cross_a + std::fabs(tplane) * cross_b) * std::fabs(inv_nd)
                      : std::fabs(p.d - no) > cross_a ? 0.0f
                                                      : std::numeric_limits<float>::quiet_NaN();
                down = std::signbit(nd);
                above_child = node.general_above();
            }
            const uint32_t entry = down ? above_child : index + 1;
            const uint32_t exit = down ? index + 1 : above_child;
            // The exact crossing lies in [t_lo, t_hi].
            // Three cases (branches, not conditional moves: measured
            // faster on coherent rays, whose branches predict well, and no
            // slower on random rays, where they mispredict: selects put the
            // crossing's arithmetic between one node's load and the next,
            // while a branch lets the processor load ahead, rightly most of
            // the time. A branchless step - the far entry always written,
            // the stack top advanced by the "both" case, next node and t1
            // by bit masks - traced primary rays at 0.2-0.4 of this speed
            // and random rays at 0.9-1.0; docs/performance.md):
            //   crossed before this cell (or behind the origin): the exit
            //     child only, over the same [t0, t1];
            //   crossed beyond this cell: the entry child only;
            //   crossed inside it, or NaN (the ray lies in the plane, and
            //     either side may hold its hit): the entry child now over
            //     [t0, t_hi], the exit child later over [t_lo, t1].
            // NaN needs no case of its own: both comparisons are false, and
            // std::max(t0, NaN) is t0, std::min(t1, NaN) is t1, so both
            // children get the whole range.
            const float t_lo = tplane - err, t_hi = tplane + err;
            if (t_hi < t0) {
                index = exit;
            } else if (t_lo > t1) {
                index = entry;
            } else if (kInPlane && t_lo != t_lo) {
                // The ray lies in the plane (in_plane.hpp). (The ordinary
                // walk never gets here: rays that can lie in a plane took
                // the in-plane walk, see trace_ray.)
                if constexpr (kInPlane) {
                    const bool kd = !kGeneral || node.is_kd();
                    const int i = in_plane.index_of(kd ? axis_plane(node.axis(), node.split)
                                                       : planes[node.first]);
                    const PlaneSide side = i >= 0 ? InPlaneWalk::side(sides, i) : PlaneSide::Unknown;
                    if (side != PlaneSide::Unknown) {
                        // The cell lies on one side: the other child is flat.
                        index = side == PlaneSide::Below ? index + 1 : above_child;
                    } else {
                        // Both children over the whole range, each on its side.
                        const PlaneSide entry_side = down ? PlaneSide::Above : PlaneSide::Below;
                        const PlaneSide exit_side = down ? PlaneSide::Below : PlaneSide::Above;
                        stack[top++] = {{exit, t0, t1},
                                        i >= 0 ? InPlaneWalk::with(sides, i, exit_side) : sides};
                        if (i >= 0) sides = InPlaneWalk::with(sides, i, entry_side);
                        index = entry;
                    }
                }
            } else {
                const float far_t0 = std::max(t0, t_lo);
                // An empty entry child (most leaves of a kd tree are empty)
                // has nothing to test: counted as visited, as the walk
                // visits it, but the ray goes straight on to the exit child,
                // without pushing it, a loop turn, and popping it back. Its
                // node is the one the next step would load anyway.
                if (is_empty_leaf(nodes[entry])) {
                    count.step(entry, t0, std::min(t1, t_hi), t_e);
                    // pop_cell's early exit for the exit child.
                    if (hit.reach < far_t0) goto next_cell;
                    index = exit;
                    t0 = far_t0;
                    continue;
                }
                // An empty exit child need not be pushed, on the hits-only
                // path for incoherent rays (whose exit child has been
                // fetched: kPrefetchAbove). The counting paths push it, so
                // that it counts as a step when popped, as before.
                if constexpr (kSkipEmptyExit)
                    if (is_empty_leaf(nodes[exit])) {
                        index = entry;
                        t1 = std::min(t1, t_hi);
                        continue;
                    }
                // The far child is visited later, unless a hit ends the ray
                // first: fetch its node meanwhile.
                __builtin_prefetch(nodes + exit);
                if constexpr (kInPlane)
                    stack[top++] = {{exit, far_t0, t1}, sides};
                else
                    stack[top++] = {exit, far_t0, t1};
                index = entry;
                t1 = std::min(t1, t_hi);
                continue;
            }
            // One child over the same [t0, t1]: on incoherent rays an empty
            // one is counted as visited and the next cell popped at once,
            // without the loop turn (callgrind, bunny random: 1 mispredict a
            // ray fewer; on camera rays 2.4 more, for 18 more branches: not
            // there, nor in the in-plane walk, which takes the plain loop).
            if constexpr (kPrefetchAbove)
                if (is_empty_leaf(nodes[index])) {
                    count.step(index, t0, t1, t_e);
                    goto next_cell;
                }
            continue;
        }
        // Empty leaves (most leaves of a kd tree) have nothing to test.
        if (node.count() != 0)
            intersect_leaf<kBoxes, kSimdLeaves>(tree, node, index, sray, org, dir, t0, t1, tmin,
                                                t_e, pad, mailbox, hit, count);
    next_cell:
        // Early exit: pop_cell skips every cell that starts beyond the
        // closest hit. (Not `hit.t <= t1` here: with widened crossings, and
        // for rays in a plane, a cell still on the stack may start before
        // this one ends.)
        if constexpr (kInPlane) {
            if (!pop_cell(stack, top, hit.reach, index, t0, t1, sides)) break;
        } else {
            if (!pop_cell(stack, top, hit.reach, index, t0, t1)) break;
        }
    }
    return true;
}

inline bool denormal_or_zero(float x) {
    return (std::bit_cast<uint32_t>(x) & 0x7f800000u) == 0;
}

// One ray, for trace_path (trace_path.cpp, whose policy records the walk):
// the ordinary walk, or, for a ray that may lie in a split plane, the
// in-plane walk from the start (in_plane.hpp), as trace_rays traces it.
// The batch loop (trace_rays) defers such rays instead (trace_ray_at).
template <LeafBoxes kBoxes, bool kGeneral, bool kSimdLeaves, bool kPrefetchAbove, class Counters>
inline void trace_ray(const TreeView& tree, const Vec3& o, const Vec3& d, float tmin, float tmax,
                      Closest& hit, Counters& count) {
    if (!(denormal_or_zero(d.x) | denormal_or_zero(d.y) | denormal_or_zero(d.z)) &&
        trace_one<kBoxes, kGeneral, kSimdLeaves, kPrefetchAbove, false>(tree, o, d, tmin, tmax,
                                                                         hit, count))
        return;
    hit = Closest();
    count.restart();
    trace_one<kBoxes, kGeneral, false, false, true>(tree, o, d, tmin, tmax, hit, count);
}

// What trace_rays writes as a ray's prim when the ordinary walk left it to
// the in-plane walk, which traces it after the loop (never returned).
constexpr int32_t kInPlaneLater = -2;

// Traces ray i of the batch and stores its hit and counts; or, when the
// ordinary walk (kInPlane = false) leaves the ray to the in-plane walk,
// stores nothing and returns false.
template <LeafBoxes kBoxes, bool kGeneral, bool kSimdLeaves, bool kPrefetchAbove, bool kInPlane,
          class Counters>
inline bool trace_ray_at(const TreeView& view, const RayBatch& rays, const HitBatch& hits,
                         size_t i) {
    const double scale = view.scale;
    const float* o = rays.origins + 3 * i;
    const float* d = rays.directions + 3 * i;
    // Only a ray with an infinite inverse direction component can lie in a
    // kd plane, and only a zero or denormal component has one: such rays
    // take the in-plane walk from the start. (Tested on the bits, here, this
    // is nearly free; as a test of the inverses inside trace_one it cost
    // 2-3 % of the instructions per ray.)
    if constexpr (!kInPlane)
        if (denormal_or_zero(d[0]) | denormal_or_zero(d[1]) | denormal_or_zero(d[2])) [[unlikely]]
            return false;
    Closest c;
    Counters count;
    const float tmin = rays.tmin[i * rays.tmin_stride];
    const float tmax = rays.tmax[i * rays.tmax_stride];
    if (scale == 1.0 && !view.moved) {
        if (!trace_one<kBoxes, kGeneral, kSimdLeaves, kPrefetchAbove, kInPlane>(
                view, Vec3(o[0], o[1], o[2]), Vec3(d[0], d[1], d[2]), tmin, tmax, c, count))
            return false;
    } else {
        // Into the tree's frame and scaled space: o moves and scales, the
        // range scales, d does neither.
        const Vec3 so = to_tree_space(view, o);
        if (!trace_one<kBoxes, kGeneral, kSimdLeaves, kPrefetchAbove, kInPlane>(
                view, so, Vec3(d[0], d[1], d[2]), float(tmin * scale), float(tmax * scale), c,
                count))
            return false;
        c.t = float(c.t * (1.0 / scale));
        if (!(c.t < tmax)) c.prim = -1;  // tmax * scale rounded up (or overflowed)
    }
    const bool hit = c.prim >= 0;
    hits.t[i] = hit ? c.t : kInf;
    hits.prim[i] = c.prim;
    hits.u[i] = hit ? c.u : 0.0f;
    hits.v[i] = hit ? c.v : 0.0f;
    count.store(hits, i);
    return true;
}

// The rays of [begin, end) that the ordinary walk left (kInPlaneLater),
// through the in-plane walk. Out of line: a call in the ray loop itself,
// even one never taken, cost the ordinary walk 2-3 % of its instructions.
template <LeafBoxes kBoxes, bool kGeneral, class Counters>
__attribute__((noinline)) BSPLAB_KERNEL_FLATTEN void trace_in_plane_rays(
    const TreeView& view, const RayBatch& rays, const HitBatch& hits, size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i)
        if (hits.prim[i] == kInPlaneLater)
            trace_ray_at<kBoxes, kGeneral, false, false, true, Counters>(view, rays, hits, i);
}

// The ray loop of one traversal kind (kGeneral, kSimdLeaves, kPrefetchAbove:
// see trace_one and intersect_leaf).
template <LeafBoxes kBoxes, bool kGeneral, bool kSimdLeaves, bool kPrefetchAbove, class Counters>
void trace_rays(const TreeView& view, const RayBatch& rays, const HitBatch& hits, size_t begin,
                size_t end) {
    bool in_plane = false;
    for (size_t i = begin; i < end; ++i) {
        if (!trace_ray_at<kBoxes, kGeneral, kSimdLeaves, kPrefetchAbove, false, Counters>(
                view, rays, hits, i)) [[unlikely]] {
            hits.prim[i] = kInPlaneLater;
            in_plane = true;
        }
    }
    if (in_plane) trace_in_plane_rays<kBoxes, kGeneral, Counters>(view, rays, hits, begin, end);
}

// The kd-only or general traversal (TreeView::has_general).
template <LeafBoxes kBoxes, bool kSimdLeaves, bool kPrefetchAbove, class Counters>
void trace_rays_of_tree(const TreeView& view, const RayBatch& rays, const HitBatch& hits,
                        size_t begin, size_t end) {
    if (view.has_general)
        trace_rays<kBoxes, true, kSimdLeaves, kPrefetchAbove, Counters>(view, rays, hits, begin,
                                                                         end);
    else
        trace_rays<kBoxes, false, kSimdLeaves, kPrefetchAbove, Counters>(view, rays, hits, begin,
                                                                          end);
}

// Traces rays [begin, end) one by one (see kernel_set.hpp), with the kd-only
// traversal when the tree has no general node, and on the hits-only path
// with SIMD leaf blocks when its leaves are big (kSimdLeafMean) and with the
// far-child prefetch when the rays are incoherent (rays_are_coherent: the
// prefetch pays on random rays and costs on camera rays). The counting path
// keeps one loop: its counts are the same either way.
template <LeafBoxes kBoxes, class Counters>
void trace_single_rays(const TreeView& view, const RayBatch& rays, const HitBatch& hits,
                       size_t begin, size_t end) {
    if constexpr (std::is_same_v<Counters, CountNothing>) {
        const bool simd = view.mean_leaf_refs >= kSimdLeafMean;
        const bool coherent = rays_are_coherent(rays, begin, end);
        if (simd && coherent)
            trace_rays_of_tree<kBoxes, true, false, Counters>(view, rays, hits, begin, end);
        else if (simd)
            trace_rays_of_tree<kBoxes, true, true, Counters>(view, rays, hits, begin, end);
        else if (coherent)
            trace_rays_of_tree<kBoxes, false, false, Counters>(view, rays, hits, begin, end);
        else
            trace_rays_of_tree<kBoxes, false, true, Counters>(view, rays, hits, begin, end);
    } else {
        trace_rays_of_tree<kBoxes, false, false, Counters>(view, rays, hits, begin, end);
    }
}

}  // namespace
}  // namespace bsp::BSPLAB_ISA_NS
