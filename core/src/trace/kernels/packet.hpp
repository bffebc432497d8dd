// The packet kernel: a group of coherent rays (consecutive rays of the batch,
// e.g. a 4 x 4 screen tile: camera.tile_order) traced together through kd and general
// nodes, one ray per SIMD lane. Included by kernels/trace_kernels.cpp only,
// inside the namespace of one instruction-set level, like single_ray.hpp.
//
// Every lane follows exactly the path single-ray tracing would take: a node's
// crossing is computed per lane with the same float expressions as trace_one,
// a lane is active in a child only where trace_one would visit it, over the
// same [t0, t1], and it visits the children in the same order. The leaf test
// is intersect_triangle's arithmetic lane by lane. So t, prim, u and v are
// bit-identical to the single-ray hits-only path, whatever the packet holds.
//
// Where the active lanes disagree on which child comes first (the sign of the
// direction along the split's normal), the packet splits in two sub-packets,
// each visiting the node's children in its own order; the lanes of one never
// see the other's cells, and the packet goes on coherent below the node.
#pragma once
#include <immintrin.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>

#include "trace/traverse.hpp"
#include "tree.hpp"
#include "trace/triangle.hpp"
#include "trace/kernels/leaf_acceptance.hpp"
#include "trace/kernels/single_ray.hpp"
#include "trace/kernels/tree_view.hpp"
#include "trace/kernels/walk_start.hpp"

#ifndef BSPLAB_ISA_NS
#error "packet.hpp is compiled per instruction set: include it from trace_kernels.cpp"
#endif

namespace bsp::BSPLAB_ISA_NS {
namespace {

// One lane per ray, as wide as the level's widest float registers.
#if defined(__AVX512F__)
constexpr int kLanes = 16;
#elif defined(__AVX2__)
constexpr int kLanes = 8;
#else
constexpr int kLanes = 4;
#endif
constexpr uint32_t kAllLanes = (1u << kLanes) - 1;

typedef float vfloat __attribute__((vector_size(4 * kLanes)));
typedef int32_t vint __attribute__((vector_size(4 * kLanes)));
typedef double vdouble __attribute__((vector_size(8 * kLanes)));
// One bit per lane, lane i in bit i.
using LaneMask = uint32_t;

// The lanes whose comparison result is true (all ones).
inline LaneMask lane_bits(vint m) {
#if defined(__AVX512DQ__)
    return LaneMask(_mm512_movepi32_mask(__m512i(m)));
#elif defined(__AVX2__)
    return LaneMask(_mm256_movemask_ps(__m256(m)));
#else
    return LaneMask(_mm_movemask_ps(__m128(m)));
#endif
}

// x in every lane. (Not 0 + x, which would turn -0 into +0.)
inline vfloat splat(float x) { return x - vfloat{}; }

inline vfloat vabs(vfloat x) { return vfloat(vint(x) & 0x7FFFFFFF); }

inline vfloat select(vint m, vfloat a, vfloat b) { return m ? a : b; }

inline vdouble to_double(vfloat x) { return __builtin_convertvector(x, vdouble); }

// All ones in the lanes whose bit is set.
inline vint lane_vector(LaneMask m) {
    vint bit;
    for (int i = 0; i < kLanes; ++i) bit[i] = int32_t(1u << i);
    return (bit & int32_t(m)) != 0;
}

// The rays of one packet, in the tree's (scaled) space, as trace_one sees
// them: `org` is where each lane tests triangles from (at t = test_t on its
// ray), `walk` where it walks from (at t_e), as WalkStart says.
struct PacketRays {
    vfloat org[3], dir[3], idir[3];
    vdouble org_d[3], dir_d[3];  // for the hits' distance in double
    vdouble test_t, t_e;
    vfloat tmin;
    // The walk origin, its error along each axis, the axis crossings' bounds.
    vfloat walk[3], org_err[3], axis_err[3];
    vfloat cross_a, cross_b;  // a general crossing's error terms (trace_one)
    vfloat slack;             // WalkStart::slack: in the leaves' box padding
    // The shear of intersect_triangle per lane: the origin's and a vertex's
    // coordinates along kx, ky, kz, and sx, sy.
    vfloat okx, oky, okz, sx, sy;
    // Lanes whose kx (ky, kz) is 0 or 1; unused when every lane has the same.
    vint kx0, kx1, ky0, ky1, kz0, kz1;
    bool same_shear;
    int kx, ky, kz;  // every lane's, when same_shear
    // signbit(dir[axis]) per lane: which child a kd node's lanes enter first.
    LaneMask dir_negative[3];
};

// A vertex's coordinates along each lane's kx, ky, kz.
struct ShearedVertex {
    vfloat x, y, z;
};

inline vfloat pick(vint is0, vint is1, const Vec3& v) {
    return select(is0, splat(v.x), select(is1, splat(v.y), splat(v.z)));
}

// v[k] as one indexed load (Vec3's operator[] is a chain of selects).
inline float coordinate(const Vec3& v, int k) {
    static_assert(sizeof(Vec3) == 3 * sizeof(float), "Vec3 is x, y, z");
    float c[3];
    std::memcpy(c, &v, sizeof c);
    return c[k];
}

inline ShearedVertex shear_vertex(const PacketRays& r, const Vec3& v) {
    if (r.same_shear)
        return {splat(coordinate(v, r.kx)), splat(coordinate(v, r.ky)), splat(coordinate(v, r.kz))};
    return {pick(r.kx0, r.kx1, v), pick(r.ky0, r.ky1, v), pick(r.kz0, r.kz1, v)};
}

// The closest hits of a packet; prim -1 where none yet. Ties as in
// single_ray.hpp's Closest: of equal float t the nearer in double (td), then
// the smallest triangle index wins.
struct PacketHits {
    vfloat t, u, v;
    vint prim;
    vdouble td;  // the hits' double distances (Closest::td)
};

// Closest::reach for lane i: the walk parameter beyond which its cell cannot
// hold a hit as close as its closest one (walk_reach_exact; before the
// first hit walk_reach of tmax).
inline float lane_reach_of(const PacketRays& r, const PacketHits& hits, int i) {
    return hits.prim[i] >= 0 ? walk_reach_exact(hits.td[i], r.t_e[i])
                             : walk_reach(hits.t[i], r.t_e[i]);
}

// lane_reach_of for every lane.
inline vfloat lane_reach(const PacketRays& r, const PacketHits& hits) {
    vfloat reach;
    for (int i = 0; i < kLanes; ++i) reach[i] = lane_reach_of(r, hits, i);
    return reach;
}

// ray_distance (triangle.hpp) for every lane: the same double operations
// in the same order, the triangle's normal computed once.
inline vdouble plane_distances(const PacketRays& r, const Triangle& tri) {
    double n[3];
    tri.normal_double(n);
    const vdouble num = n[0] * (double(tri.v[0].x) - r.org_d[0]) +
                        n[1] * (double(tri.v[0].y) - r.org_d[1]) +
                        n[2] * (double(tri.v[0].z) - r.org_d[2]);
    const vdouble den = n[0] * r.dir_d[0] + n[1] * r.dir_d[1] + n[2] * r.dir_d[2];
    return r.test_t + num / den;
}

// ray_distance for the lanes in `lanes` one by one (the other lanes: 0).
inline vdouble plane_distances_of(const PacketRays& r, const Triangle& tri, LaneMask lanes) {
    vdouble t{};
    for (; lanes; lanes &= lanes - 1) {
        const int i = __builtin_ctz(lanes);
        const Vec3 o(r.org[0][i], r.org[1][i], r.org[2][i]);
        const Vec3 d(r.dir[0][i], r.dir[1][i], r.dir[2][i]);
        t[i] = r.test_t[i] + plane_distance(tri, o, d);
    }
    return t;
}

// intersect_triangle for the lanes in `lanes`, each against its own closest
// hit: the same operations in the same order, so the same bits. The rare
// recompute of an edge function of exactly zero runs lane by lane.
// Returns the lanes that passed the triangle test but whose hit the leaf
// did not accept (leaf_acceptance.hpp; the leaf's box `slot`, its
// ranges [t0, t1]): the mailbox forgets them.
inline LaneMask intersect_packet_triangle(const TreeView& tree, const PacketRays& r,
                                          const Triangle& tri, uint32_t prim, uint32_t slot,
                                          LaneMask lanes, vfloat t0, vfloat t1,
                                          PacketHits& hits) {
    const ShearedVertex a = shear_vertex(r, tri.v[0]), b = shear_vertex(r, tri.v[1]),
                        c = shear_vertex(r, tri.v[2]);
    // A = v0 - org, then Ax = A[kx] - sx A[kz], as in intersect_triangle.
    const vfloat Az = a.z - r.okz, Bz = b.z - r.okz, Cz = c.z - r.okz;
    const vfloat Ax = (a.x - r.okx) - r.sx * Az, Ay = (a.y - r.oky) - r.sy * Az;
    const vfloat Bx = (b.x - r.okx) - r.sx * Bz, By = (b.y - r.oky) - r.sy * Bz;
    const vfloat Cx = (c.x - r.okx) - r.sx * Cz, Cy = (c.y - r.oky) - r.sy * Cz;
    vfloat U = Cx * By - Cy * Bx;
    vfloat V = Ax * Cy - Ay * Cx;
    vfloat W = Bx * Ay - By * Ax;
    const vfloat zero{};
    for (LaneMask on_edge = lanes & lane_bits((U == zero) | (V == zero) | (W == zero)); on_edge;
         on_edge &= on_edge - 1) {
        const int i = __builtin_ctz(on_edge);
        U[i] = float(double(Cx[i]) * double(By[i]) - double(Cy[i]) * double(Bx[i]));
        V[i] = float(double(Ax[i]) * double(Cy[i]) - double(Ay[i]) * double(Cx[i]));
        W[i] = float(double(Bx[i]) * double(Ay[i]) - double(By[i]) * double(Ax[i]));
    }
    const vint outside = ((U < zero) | (V < zero) | (W < zero)) & ((U > zero) | (V > zero) | (W > zero));
    const vfloat det = U + V + W;
    const LaneMask inside = lanes & ~lane_bits(outside | (det == zero));
    if (!inside) return 0;
    // The distance of the lanes that pass the edge test (most of them hit:
    // this runs about once per hit, not per test). A lane or two, as in
    // packets that spread over small triangles, take the scalar division.
    const vdouble td = __builtin_popcount(inside) <= 2 ? plane_distances_of(r, tri, inside)
                                                       : plane_distances(r, tri);
    const vfloat t = __builtin_convertvector(td, vfloat);
    const vint prims = int32_t(prim) + vint{};
    // Closest::beaten_by, lane by lane.
    const vint nearer = __builtin_convertvector(td < hits.td, vint);
    const vint as_near = __builtin_convertvector(td == hits.td, vint);
    vint closer = lane_vector(inside) & (t > r.tmin) &
                  ((t < hits.t) | ((t == hits.t) & (nearer | (as_near & (prims < hits.prim)))));
    LaneMask rejected = 0;
    if (tree.box_kind != LeafBoxes::None) {
        const Box& box = culling_box(tree, prim, slot);
        for (LaneMask m = lane_bits(closer); m; m &= m - 1) {
            const int i = __builtin_ctz(m);
            const float org[3] = {r.walk[0][i], r.walk[1][i], r.walk[2][i]};
            const float dir[3] = {r.dir[0][i], r.dir[1][i], r.dir[2][i]};
            const float s1 = std::min(t1[i], lane_reach_of(r, hits, i));
            if (!leaf_accepts(box, org, dir, t0[i], s1, t[i], r.t_e[i],
                              tree.cull_pad + r.slack[i])) {
                closer[i] = 0;
                rejected |= 1u << i;
            }
        }
    }
    const vfloat inv = 1.0f / det;
    hits.t = select(closer, t, hits.t);
    for (LaneMask m = lane_bits(closer); m; m &= m - 1) hits.td[__builtin_ctz(m)] = td[__builtin_ctz(m)];
    hits.u = select(closer, V * inv, hits.u);
    hits.v = select(closer, W * inv, hits.v);
    hits.prim = closer ? prims : hits.prim;
    // Where the reciprocal overflowed, barycentrics()' double quotients
    // (triangle.hpp), lane by lane, so that u, v match the single rays'.
    for (LaneMask m = lane_bits(closer); m; m &= m - 1) {
        const int i = __builtin_ctz(m);
        if (std::isinf(inv[i])) [[unlikely]] {
            float u, v;
            barycentrics(U[i], V[i], W[i], u, v);
            hits.u[i] = u;
            hits.v[i] = v;
        }
    }
    return rejected;
}

// The mailbox of a packet: which lanes already tested a triangle. A lane
// that tested it gets the same answer again (its closest hit only got
// closer), so skipping it changes nothing but the time.
struct PacketMailbox {
    static constexpr uint32_t kSize = 16;
    uint32_t prim[kSize];
    LaneMask tested[kSize];
    PacketMailbox() {
        std::fill(prim, prim + kSize, 0xFFFFFFFFu);
        std::fill(tested, tested + kSize, 0u);
    }
    // The lanes of `lanes` still to test `p`, now marked as tested.
    LaneMask untested(uint32_t p, LaneMask lanes) {
        const uint32_t s = p & (kSize - 1);
        if (prim[s] != p) {
            prim[s] = p;
            tested[s] = lanes;
            return lanes;
        }
        const LaneMask fresh = lanes & ~tested[s];
        tested[s] |= lanes;
        return fresh;
    }
    // Unmarks the lanes of `lanes` for `p` (their leaf rejected its hit).
    void forget(uint32_t p, LaneMask lanes) {
        const uint32_t s = p & (kSize - 1);
        if (prim[s] == p) tested[s] &= ~lanes;
    }
};

inline void intersect_packet_leaf(const TreeView& tree, Node node, uint32_t index,
                                  const PacketRays& rays, LaneMask lanes, vfloat t0, vfloat t1,
                                  PacketMailbox& mailbox, PacketHits& hits) {
    const uint32_t n_refs = node.count();
    const uint32_t* list =
        n_refs == 1 && tree.inline_single ? &tree.nodes[index].first : tree.refs + node.first;
    for (uint32_t i = 0; i < n_refs; ++i) {
        const uint32_t p = list[i];
        const LaneMask todo = mailbox.untested(p, lanes);
        if (!todo) continue;
        const LaneMask rejected =
            intersect_packet_triangle(tree, rays, tree.tris[p], p, node.first + i, todo, t0, t1, hits);
        if (rejected) mailbox.forget(p, rejected);
    }
}

// A node still to visit, by the lanes in `lanes`, each over its [t0, t1].
struct PacketCell {
    vfloat t0, t1;
    uint32_t node;
    LaneMask lanes;
};

// Where each lane crosses a node's plane, [t_lo, t_hi] (NaN for a ray in the
// plane), and which lanes move towards the child below it: trace_one's
// expressions, lane by lane.
struct PacketCrossing {
    vfloat t_lo, t_hi;
    LaneMask down;
    uint32_t above_child;
};

inline PacketCrossing cross_node(const TreeView& tree, const PacketRays& r, Node node) {
    if (node.is_kd()) {
        const int axis = node.axis();
        const vfloat t = (splat(node.split) - r.walk[axis]) * r.idir[axis];
        return {t - r.axis_err[axis], t + r.axis_err[axis], r.dir_negative[axis],
                node.kd_above()};
    }
    const Plane& p = tree.planes[node.first];
    const vfloat no = p.nx * r.walk[0] + p.ny * r.walk[1] + p.nz * r.walk[2];
    const vfloat nd = p.nx * r.dir[0] + p.ny * r.dir[1] + p.nz * r.dir[2];
    const vfloat inv_nd = 1.0f / nd;
    const vfloat tplane = (p.d - no) * inv_nd;
    const vfloat zero{};
    const vfloat parallel =
        select(vabs(p.d - no) > r.cross_a, zero, splat(std::numeric_limits<float>::quiet_NaN()));
    const vfloat err =
        select(nd != zero, (r.cross_a + vabs(tplane) * r.cross_b) * vabs(inv_nd), parallel);
    return {tplane - err, tplane + err, lane_bits(vint(nd) < 0), node.general_above()};
}

// Lane-wise `m ? a : b` for the integer lanes.
inline vint select(vint m, vint a, vint b) { return m ? a : b; }

// The lanes' coordinates along the axes in `k` (0, 1 or 2 per lane).
inline vfloat along(vint k, const vfloat v[3]) {
    return select(k == 0, v[0], select(k == 1, v[1], v[2]));
}

// clip_to_box for every lane: the same operations, the early return of a
// lane that misses replaced by its bit in the returned mask.
inline LaneMask clip_lanes_to_box(const Box& box, const PacketRays& r, vfloat& t0, vfloat& t1) {
    vint miss{};
    const vfloat zero{};
    for (int k = 0; k < 3; ++k) {
        const vint flat = r.dir[k] == zero;
        miss |= flat & ((r.walk[k] < box.lo[k]) | (r.walk[k] > box.hi[k]));
        const vfloat tn = (box.lo[k] - r.walk[k]) * r.idir[k];
        const vfloat tf = (box.hi[k] - r.walk[k]) * r.idir[k];
        const vint swap = tn > tf;
        vfloat near = select(swap, tf, tn);
        vfloat far = select(swap, tn, tf);
        near -= r.org_err[k] + vabs(near) * kCrossRel;
        far += r.org_err[k] + vabs(far) * kCrossRel;
        // std::max(t0, near) and std::min(t1, far), on the lanes not parallel.
        t0 = select(flat, t0, select(t0 < near, near, t0));
        t1 = select(flat, t1, select(far < t1, far, t1));
        miss |= ~flat & (t0 > t1);
    }
    return ~lane_bits(miss);
}

// ShearedRay's constants for every lane (same comparisons, same divisions).
inline void shear_lanes(PacketRays& r) {
    const vfloat ax = vabs(r.dir[0]), ay = vabs(r.dir[1]), az = vabs(r.dir[2]);
    const vint zero{}, one = zero + 1, two = zero + 2;
    const vint kz = select(ax > ay, select(ax > az, zero, two), select(ay > az, one, two));
    vint kx = select(kz == 2, zero, kz + 1);
    vint ky = select(kx == 2, zero, kx + 1);
    const vfloat dkz = along(kz, r.dir);
    // Swap kx and ky where the dominant direction is negative (the winding).
    const vint negative = dkz < 0.0f;
    const vint swapped_x = select(negative, ky, kx);
    ky = select(negative, kx, ky);
    kx = swapped_x;
    r.sx = along(kx, r.dir) / dkz;
    r.sy = along(ky, r.dir) / dkz;
    r.okx = along(kx, r.org), r.oky = along(ky, r.org), r.okz = along(kz, r.org);
    r.kx0 = kx == 0, r.kx1 = kx == 1;
    r.ky0 = ky == 0, r.ky1 = ky == 1;
    r.kz0 = kz == 0, r.kz1 = kz == 1;
    r.kx = kx[0], r.ky = ky[0], r.kz = kz[0];
    r.same_shear = lane_bits((kx == r.kx) & (ky == r.ky) & (kz == r.kz)) == kAllLanes;
}

// Sets up a packet of rays [first, first + n) in the tree's space; the lanes
// from n on repeat the first ray and stay inactive. Returns the lanes whose
// ray meets the scene box, with their ranges in t0, t1.
inline LaneMask setup_packet(const TreeView& tree, const RayBatch& batch, size_t first, int n,
                             PacketRays& r, vfloat& t0, vfloat& t1, vfloat& tmax) {
    const double scale = tree.scale;
    for (int i = 0; i < kLanes; ++i) {
        const size_t k = first + size_t(i < n ? i : 0);
        const float* o = batch.origins + 3 * k;
        const float* d = batch.directions + 3 * k;
        const float tmin = batch.tmin[k * batch.tmin_stride];
        const float tm = batch.tmax[k * batch.tmax_stride];
        for (int c = 0; c < 3; ++c) r.dir[c][i] = d[c];
        if (scale == 1.0 && !tree.moved) {
            for (int c = 0; c < 3; ++c) r.org[c][i] = o[c];
            r.tmin[i] = tmin, tmax[i] = tm;
        } else {
            // Into the tree's frame and scaled space, as trace_single_rays:
            // o moves and scales, the range scales, d does neither.
            const Vec3 so = to_tree_space(tree, o);
            for (int c = 0; c < 3; ++c) r.org[c][i] = so[c];
            r.tmin[i] = float(tmin * scale), tmax[i] = float(tm * scale);
        }
    }
    for (int c = 0; c < 3; ++c) {
        r.idir[c] = 1.0f / r.dir[c];
        r.dir_d[c] = to_double(r.dir[c]);
    }
    // Each lane's walk, as trace_one's (a far lane's test origin moves to it).
    for (int i = 0; i < kLanes; ++i) {
        const float o[3] = {r.org[0][i], r.org[1][i], r.org[2][i]};
        const float d[3] = {r.dir[0][i], r.dir[1][i], r.dir[2][i]};
        const float idir[3] = {r.idir[0][i], r.idir[1][i], r.idir[2][i]};
        const WalkStart w(tree, o, d, idir);
        for (int c = 0; c < 3; ++c) {
            r.walk[c][i] = w.org[c], r.org_err[c][i] = w.org_err[c];
            r.org[c][i] = w.test_org[c];
        }
        r.t_e[i] = w.t_e, r.test_t[i] = w.test_t;
        r.cross_a[i] = w.cross_a, r.cross_b[i] = w.cross_b;
        r.slack[i] = w.slack;
        t0[i] = walk_lower(r.tmin[i], w.t_e), t1[i] = walk_upper(tmax[i], w.t_e);
    }
    for (int c = 0; c < 3; ++c) r.org_d[c] = to_double(r.org[c]);
    shear_lanes(r);
    for (int c = 0; c < 3; ++c) r.dir_negative[c] = lane_bits(vint(r.dir[c]) < 0);
    const LaneMask rays_here = n == kLanes ? kAllLanes : (1u << n) - 1;
    const LaneMask in_box = clip_lanes_to_box(tree.bounds, r, t0, t1) & rays_here;
    // axis_crossing_errors, lane by lane.
    const vfloat rel = kCrossRel * select(vabs(t0) > vabs(t1), vabs(t0), vabs(t1));
    for (int c = 0; c < 3; ++c) r.axis_err[c] = r.org_err[c] + rel;
    return in_box;
}

// The lanes of `group` that visit a node's entry child and its exit child.
// trace_one: a lane in the plane (NaN) visits both; one crossing beyond its
// range only the entry; one crossed before it only the exit. With t0 <= t1,
// which holds for every active lane, that is: the entry unless t_hi < t0,
// the exit unless t_lo > t1 (comparisons with NaN are false, so a lane in
// the plane visits both).
inline void child_lanes(vfloat t_lo, vfloat t_hi, vfloat t0, vfloat t1, LaneMask group,
                        LaneMask& enter, LaneMask& leave) {
    enter = group & ~lane_bits(t_hi < t0);
    leave = group & ~lane_bits(t_lo > t1);
}

// Trees are at most 64 levels deep (build_tree.cpp caps the depth), and a
// packet pushes at most three cells per level of its path: the exit child,
// and a split packet's deferred group's entry and exit.
constexpr int kPacketStack = 3 * 64 + 8;

// Traces one packet's active lanes to their closest hits. Returns the lanes
// that lie in a split plane somewhere on their walk: their hits are the
// single-ray in-plane walk's (in_plane.hpp), which the caller traces again.
inline LaneMask trace_packet(const TreeView& tree, const PacketRays& rays, LaneMask active,
                             vfloat t0, vfloat t1, PacketHits& hits) {
    LaneMask in_plane = 0;
    PacketCell stack[kPacketStack];
    int top = 0;
    uint32_t index = 0;
    PacketMailbox mailbox;
    const Node* nodes = tree.nodes;
    vfloat reach = lane_reach(rays, hits);
    active &= ~lane_bits(reach < t0);
    for (;;) {
        const Node node = nodes[index];
        if (active && !node.is_leaf()) {
            const PacketCrossing x = cross_node(tree, rays, node);
            in_plane |= active & lane_bits(x.t_lo != x.t_lo);
            const LaneMask down = active & x.down;
            LaneMask enter, leave;
            if (down && down != active) {
                // The lanes disagree on the child order: the lanes moving
                // down wait on the stack (their entry child on top), the
                // others go on now.
                child_lanes(x.t_lo, x.t_hi, t0, t1, down, enter, leave);
                if (leave) stack[top++] = {select(x.t_lo > t0, x.t_lo, t0), t1, index + 1, leave};
                if (enter) stack[top++] = {t0, select(x.t_hi < t1, x.t_hi, t1), x.above_child, enter};
                active &= ~down;
            }
            const bool moves_down = down != 0 && active == down;
            child_lanes(x.t_lo, x.t_hi, t0, t1, active, enter, leave);
            const uint32_t entry = moves_down ? x.above_child : index + 1;
            const uint32_t exit = moves_down ? index + 1 : x.above_child;
            // The comparisons are false for NaN, which keeps a lane in the
            // plane on its whole range, as std::max / std::min do in trace_one.
            if (leave) stack[top++] = {select(x.t_lo > t0, x.t_lo, t0), t1, exit, leave};
            index = entry;
            t1 = select(x.t_hi < t1, x.t_hi, t1);
            active = enter;
            continue;
        }
        if (active) {
            intersect_packet_leaf(tree, node, index, rays, active, t0, t1, mailbox, hits);
            reach = lane_reach(rays, hits);
        }
        // Pop the next cell its lanes still need: a lane leaves a cell that
        // starts beyond its closest hit (trace_one's early exit, lane by
        // lane). Only a leaf changes the hits, and an entry child starts
        // where its parent does, so the check is needed after pops only.
        do {
            if (top == 0) return in_plane;
            const PacketCell& c = stack[--top];
            index = c.node, t0 = c.t0, t1 = c.t1;
            active = c.lanes & ~lane_bits(reach < t0);
        } while (!active);
    }
}

// Traces rays [begin, end) in packets of kLanes consecutive rays (see
// kernel_set.hpp); hits only, no culling.
inline void trace_packets(const TreeView& view, const RayBatch& batch, const HitBatch& out,
                          size_t begin, size_t end) {
    const double inv_scale = 1.0 / view.scale;
    for (size_t first = begin; first < end; first += kLanes) {
        const int n = int(std::min<size_t>(kLanes, end - first));
        PacketRays rays;
        vfloat t0, t1, tmax;
        const LaneMask active = setup_packet(view, batch, first, n, rays, t0, t1, tmax);
        PacketHits hits{tmax, vfloat{}, vfloat{}, vint{} - 1, vdouble{} - INFINITY};
        const LaneMask in_plane = active ? trace_packet(view, rays, active, t0, t1, hits) : 0;
        for (int i = 0; i < n; ++i) {
            const size_t k = first + size_t(i);
            float t = hits.t[i];
            int32_t prim = hits.prim[i];
            if (view.scale != 1.0) {
                t = float(t * inv_scale);
                // tmax * scale rounded up (or overflowed), as trace_single_rays
                if (!(t < batch.tmax[k * batch.tmax_stride])) prim = -1;
            }
            const bool hit = prim >= 0;
            out.t[k] = hit ? t : kInf;
            out.prim[k] = prim;
            out.u[k] = hit ? hits.u[i] : 0.0f;
            out.v[k] = hit ? hits.v[i] : 0.0f;
        }
        // Rays lying in a split plane take the single-ray in-plane walk, as
        // they do on every path.
        for (LaneMask m = in_plane; m; m &= m - 1) {
            const size_t k = first + size_t(__builtin_ctz(m));
            trace_rays_of_tree<LeafBoxes::None, false, false, CountNothing>(view, batch, out, k,
                                                                            k + 1);
        }
    }
}

}  // namespace
}  // namespace bsp::BSPLAB_ISA_NS
