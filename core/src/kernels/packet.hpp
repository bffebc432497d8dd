// The packet kernel: a group of coherent rays (consecutive rays of the batch,
// e.g. a row pair of a screen tile) traced together through kd and general
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
#include <cstdint>
#include <cstring>
#include <immintrin.h>

#include "single_ray.hpp"

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

typedef float vfloat __attribute__((vector_size(4 * kLanes)));
typedef int32_t vint __attribute__((vector_size(4 * kLanes)));
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

inline vfloat splat(float x) { return vfloat{} + x; }

inline vfloat vabs(vfloat x) { return vfloat(vint(x) & 0x7FFFFFFF); }

inline vfloat select(vint m, vfloat a, vfloat b) { return m ? a : b; }

// The rays of one packet, in the tree's (scaled) space, as trace_one sees them.
struct PacketRays {
    vfloat org[3], dir[3], idir[3];
    vfloat tmin;
    vfloat cross_a, cross_b;  // a general crossing's error terms (trace_one)
    // The shear of intersect_triangle per lane: the origin's and a vertex's
    // coordinates along kx, ky, kz, and sx, sy.
    vfloat okx, oky, okz, sx, sy;
    int kx[kLanes], ky[kLanes], kz[kLanes];
    // Lanes whose kx (ky, kz) is 0 or 1; unused when every lane has the same.
    vint kx0, kx1, ky0, ky1, kz0, kz1;
    bool same_shear;
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

inline ShearedVertex shear_vertex(const PacketRays& r, const Vec3& v) {
    if (r.same_shear) return {splat(v[r.kx[0]]), splat(v[r.ky[0]]), splat(v[r.kz[0]])};
    return {pick(r.kx0, r.kx1, v), pick(r.ky0, r.ky1, v), pick(r.kz0, r.kz1, v)};
}

// The closest hits of a packet; prim -1 where none yet.
struct PacketHits {
    vfloat t;
    int32_t prim[kLanes];
    float u[kLanes], v[kLanes];
};

// intersect_triangle for the lanes in `lanes`, each against its own closest
// hit: the same operations in the same order, so the same bits. The rare
// parts (an edge function of exactly zero, the double-precision distance of
// a ray that passes the edge test) run lane by lane in scalar code.
inline void intersect_packet_triangle(const PacketRays& r, const Triangle& tri, uint32_t prim,
                                      LaneMask lanes, PacketHits& hits) {
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
    for (LaneMask inside = lanes & ~lane_bits(outside | (det == zero)); inside;
         inside &= inside - 1) {
        const int i = __builtin_ctz(inside);
        const Vec3 o(r.org[0][i], r.org[1][i], r.org[2][i]), d(r.dir[0][i], r.dir[1][i], r.dir[2][i]);
        const float tf = float(plane_distance(tri, o, d));
        if (!(tf > r.tmin[i] && tf < hits.t[i])) continue;
        const float inv = 1.0f / det[i];
        hits.t[i] = tf;
        hits.prim[i] = int32_t(prim);
        hits.u[i] = V[i] * inv;
        hits.v[i] = W[i] * inv;
    }
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
};

inline void intersect_packet_leaf(const TreeView& tree, Node node, uint32_t index,
                                  const PacketRays& rays, LaneMask lanes, PacketMailbox& mailbox,
                                  PacketHits& hits) {
    const uint32_t n_refs = node.count();
    const uint32_t* list =
        n_refs == 1 && tree.inline_single ? &tree.nodes[index].first : tree.refs + node.first;
    for (uint32_t i = 0; i < n_refs; ++i) {
        const uint32_t p = list[i];
        const LaneMask todo = mailbox.untested(p, lanes);
        if (todo) intersect_packet_triangle(rays, tree.tris[p], p, todo, hits);
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
        const vfloat t = (splat(node.split) - r.org[axis]) * r.idir[axis];
        return {t, t, r.dir_negative[axis], node.kd_above()};
    }
    const Plane& p = tree.planes[node.first];
    const vfloat no = p.nx * r.org[0] + p.ny * r.org[1] + p.nz * r.org[2];
    const vfloat nd = p.nx * r.dir[0] + p.ny * r.dir[1] + p.nz * r.dir[2];
    const vfloat inv_nd = 1.0f / nd;
    const vfloat tplane = (p.d - no) * inv_nd;
    const bool axis_plane = (p.nx == 0.0f) + (p.ny == 0.0f) + (p.nz == 0.0f) == 2;
    const vfloat zero{};
    vfloat err = zero;
    if (!axis_plane) {
        const vfloat parallel =
            select(vabs(p.d - no) > r.cross_a, zero,
                   splat(std::numeric_limits<float>::quiet_NaN()));
        err = select(nd != zero, (r.cross_a + vabs(tplane) * r.cross_b) * vabs(inv_nd), parallel);
    }
    return {tplane - err, tplane + err, lane_bits(vint(nd) < 0), node.general_above()};
}

// Sets up a packet of rays [first, first + n) in the tree's space; the lanes
// from n on repeat the first ray and stay inactive. Returns the lanes whose
// ray meets the scene box, with their ranges in t0, t1.
inline LaneMask setup_packet(const TreeView& tree, const RayBatch& batch, size_t first, int n,
                             PacketRays& r, vfloat& t0, vfloat& t1, vfloat& tmax) {
    const double scale = tree.scale;
    constexpr float kCrossUlps = 1.0f / (1 << 20);  // as in trace_one
    LaneMask active = 0;
    for (int i = 0; i < kLanes; ++i) {
        const size_t k = first + size_t(i < n ? i : 0);
        const float* o = batch.origins + 3 * k;
        const float* d = batch.directions + 3 * k;
        float tmin = batch.tmin[k * batch.tmin_stride], tm = batch.tmax[k * batch.tmax_stride];
        Vec3 org(o[0], o[1], o[2]);
        if (scale != 1.0) {
            // Into the tree's scaled space, as trace_single_rays: o and the
            // range scale, d does not.
            org = Vec3(float(o[0] * scale), float(o[1] * scale), float(o[2] * scale));
            tmin = float(tmin * scale);
            tm = float(tm * scale);
        }
        const Vec3 dir(d[0], d[1], d[2]);
        const Vec3 inv(1.0f / dir.x, 1.0f / dir.y, 1.0f / dir.z);
        for (int k3 = 0; k3 < 3; ++k3) {
            r.org[k3][i] = org[k3];
            r.dir[k3][i] = dir[k3];
            r.idir[k3][i] = inv[k3];
        }
        r.tmin[i] = tmin;
        tmax[i] = tm;
        r.cross_a[i] = kCrossUlps * (tree.two_scene_scale + std::fabs(org.x) + std::fabs(org.y) +
                                     std::fabs(org.z));
        r.cross_b[i] = kCrossUlps * (std::fabs(dir.x) + std::fabs(dir.y) + std::fabs(dir.z));
        const ShearedRay s(org, dir);
        r.kx[i] = s.kx, r.ky[i] = s.ky, r.kz[i] = s.kz;
        r.okx[i] = org[s.kx], r.oky[i] = org[s.ky], r.okz[i] = org[s.kz];
        r.sx[i] = s.sx, r.sy[i] = s.sy;
        r.kx0[i] = -(s.kx == 0), r.kx1[i] = -(s.kx == 1);
        r.ky0[i] = -(s.ky == 0), r.ky1[i] = -(s.ky == 1);
        r.kz0[i] = -(s.kz == 0), r.kz1[i] = -(s.kz == 1);
        float a = tmin, b = tm;
        if (i < n && clip_to_box(tree.bounds, org, inv, dir, a, b)) active |= 1u << i;
        t0[i] = a;
        t1[i] = b;
    }
    r.same_shear = true;
    for (int i = 1; i < kLanes; ++i)
        r.same_shear &= r.kx[i] == r.kx[0] && r.ky[i] == r.ky[0] && r.kz[i] == r.kz[0];
    for (int k3 = 0; k3 < 3; ++k3) r.dir_negative[k3] = lane_bits(vint(r.dir[k3]) < 0);
    return active;
}

// The children a group of lanes visits at an inner node, in trace_one's
// order for that group: its entry child over [t0, min(t1, t_hi)] by the lanes
// that visit it, then its exit child over [max(t0, t_lo), t1]. A lane in the
// plane (NaN) visits both over its whole range.
struct ChildVisits {
    PacketCell entry, exit;
};

inline ChildVisits visit_children(const PacketCrossing& x, uint32_t index, LaneMask group,
                                  bool down, vfloat t0, vfloat t1) {
    const vint in_plane = !(x.t_lo <= x.t_hi);
    const vint beyond = x.t_lo > t1;   // crosses beyond the range: entry only
    const vint before = x.t_hi < t0;   // crossed before it: exit only
    const LaneMask enter = group & lane_bits(in_plane | beyond | !before);
    const LaneMask leave = group & lane_bits(in_plane | !beyond);
    // The comparisons are false for NaN, which keeps a lane in the plane on
    // its whole range, as std::min / std::max do in trace_one.
    const vfloat entry_t1 = select(x.t_hi < t1, x.t_hi, t1);
    const vfloat exit_t0 = select(x.t_lo > t0, x.t_lo, t0);
    const uint32_t entry = down ? x.above_child : index + 1;
    const uint32_t exit = down ? index + 1 : x.above_child;
    return {{t0, entry_t1, entry, enter}, {exit_t0, t1, exit, leave}};
}

// The deepest trees (depth 64) push at most three cells per level: the exit
// child, and a split packet's second group's entry and exit.
constexpr int kPacketStack = 3 * 64 + 8;

// Traces one packet's active lanes to their closest hits.
inline void trace_packet(const TreeView& tree, const PacketRays& rays, LaneMask active, vfloat t0,
                         vfloat t1, PacketHits& hits) {
    PacketCell stack[kPacketStack];
    int top = 0;
    uint32_t index = 0;
    PacketMailbox mailbox;
    const Node* nodes = tree.nodes;
    auto push = [&](const PacketCell& c) {
        if (c.lanes) stack[top++] = c;
    };
    auto pop = [&]() {
        if (top == 0) return false;
        const PacketCell& c = stack[--top];
        index = c.node, t0 = c.t0, t1 = c.t1, active = c.lanes;
        return true;
    };
    for (;;) {
        // A lane leaves the packet's cell when it starts beyond the lane's
        // closest hit (trace_one's early exit, lane by lane).
        active &= ~lane_bits(hits.t < t0);
        if (!active) {
            if (!pop()) break;
            continue;
        }
        const Node node = nodes[index];
        if (!node.is_leaf()) {
            const PacketCrossing x = cross_node(tree, rays, node);
            const LaneMask down = active & x.down;
            const LaneMask up = active & ~x.down;
            // The lanes moving down are deferred (pushed) when the packet
            // splits; either way the current group continues in its entry.
            if (down && up) {
                const ChildVisits later = visit_children(x, index, down, true, t0, t1);
                push(later.exit);
                push(later.entry);
            }
            const bool now_down = up == 0;
            const ChildVisits v = visit_children(x, index, now_down ? down : up, now_down, t0, t1);
            push(v.exit);
            index = v.entry.node, t1 = v.entry.t1, active = v.entry.lanes;
            continue;
        }
        intersect_packet_leaf(tree, node, index, rays, active, mailbox, hits);
        if (!pop()) break;
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
        PacketHits hits;
        hits.t = tmax;
        std::fill(hits.prim, hits.prim + kLanes, -1);
        if (active) trace_packet(view, rays, active, t0, t1, hits);
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
    }
}

}  // namespace
}  // namespace bsp::BSPLAB_ISA_NS
