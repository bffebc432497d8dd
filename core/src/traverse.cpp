// Front-to-back traversal of kd and general nodes with early exit (pbrt-v3 / Havran style),
// a small per-ray mailbox, and the watertight triangle test.
#include "traverse.hpp"

#include <algorithm>

#include "parallel.hpp"
#include "triangle.hpp"

namespace bsp {
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
};

struct Closest {
    float t;
    int32_t prim = -1;
    float u = 0, v = 0;
};

// Clips [t0, t1] to the box; false when the ray misses it.
bool clip_to_box(const Box& b, const Vec3& o, const Vec3& inv, const Vec3& d, float& t0,
                 float& t1) {
    for (int k = 0; k < 3; ++k) {
        if (d[k] == 0.0f) {
            if (o[k] < b.lo[k] || o[k] > b.hi[k]) return false;
            continue;
        }
        float tn = (b.lo[k] - o[k]) * inv[k];
        float tf = (b.hi[k] - o[k]) * inv[k];
        if (tn > tf) std::swap(tn, tf);
        tf *= 1.0f + 4.0f * std::numeric_limits<float>::epsilon();  // never lose the far side
        t0 = std::max(t0, tn);
        t1 = std::min(t1, tf);
        if (t0 > t1) return false;
    }
    return true;
}

struct StackEntry {
    uint32_t node;
    float tmin, tmax;
};

// The box of the ray's segment o + [t0, t1] d, padded so that no float error
// of the end points (or of the traversal's plane crossings, which the
// builders' fattening already bounds by tree.cull_pad / 2) can cull a hit.
struct SegmentBox {
    float lo[3], hi[3];
    void set(const float* org, const float* dir, float t0, float t1, float pad) {
        for (int k = 0; k < 3; ++k) {
            const float a = org[k] + t0 * dir[k], b = org[k] + t1 * dir[k];
            const float p = pad + (std::fabs(a) + std::fabs(b)) * (1.0f / (1 << 20));
            lo[k] = std::min(a, b) - p;
            hi[k] = std::max(a, b) + p;
        }
    }
    bool misses(const Box& b) const {
        return b.lo.x > hi[0] || b.hi.x < lo[0] || b.lo.y > hi[1] || b.hi.y < lo[1] ||
               b.lo.z > hi[2] || b.hi.z < lo[2];
    }
};

template <LeafBoxes kBoxes>
void trace_one(const Tree& tree, const Vec3& o, const Vec3& d, float tmin, float tmax,
               Closest& hit, uint32_t& steps, uint32_t& general_steps, uint32_t& tests,
               uint32_t& culled) {
    hit.t = tmax;
    const Vec3 inv(1.0f / d.x, 1.0f / d.y, 1.0f / d.z);
    float t0 = tmin, t1 = tmax;
    if (!clip_to_box(tree.bounds, o, inv, d, t0, t1)) return;

    // Plain arrays: the axis is a run-time index in the hot loop.
    const float org[3] = {o.x, o.y, o.z}, dir[3] = {d.x, d.y, d.z};
    const float idir[3] = {inv.x, inv.y, inv.z};
    const ShearedRay sray(o, d);
    const Node* nodes = tree.nodes.data();
    const Plane* planes = tree.planes.data();
    const uint32_t* refs = tree.refs.data();
    const Triangle* tris = tree.triangles.data();
    Mailbox mailbox;
    StackEntry stack[72];
    int top = 0;
    uint32_t index = 0;
    uint32_t n_steps = 0, n_general = 0, n_tests = 0, n_culled = 0;
    const Box* boxes = tree.boxes.data();
    // Trees with a box per reference keep one-triangle leaves in refs[] too.
    const bool inline_single = tree.options.leaf_boxes != LeafBoxes::Clipped;

    for (;;) {
        if (hit.t < t0) break;  // everything left lies beyond the closest hit
        const Node node = nodes[index];
        ++n_steps;
        if (!node.is_leaf()) {
            // Both kinds reduce to: the plane's distance along the ray, and
            // which child holds the origin.
            float tplane;
            bool below_first;
            uint32_t above_child;
            if (node.is_kd()) {
                const int axis = node.axis();
                tplane = (node.split - org[axis]) * idir[axis];
                below_first =
                    org[axis] < node.split || (org[axis] == node.split && dir[axis] <= 0.0f);
                above_child = node.kd_above();
            } else {
                ++n_general;
                const Plane& p = planes[node.first];
                const float no = p.nx * org[0] + p.ny * org[1] + p.nz * org[2];
                const float nd = p.nx * dir[0] + p.ny * dir[1] + p.nz * dir[2];
                tplane = (p.d - no) / nd;
                below_first = no < p.d || (no == p.d && nd <= 0.0f);
                above_child = node.general_above();
            }
            const uint32_t first = below_first ? index + 1 : above_child;
            const uint32_t second = below_first ? above_child : index + 1;
            if (tplane > t1 || tplane <= 0.0f) {
                index = first;
            } else if (tplane < t0) {
                index = second;
            } else if (tplane == tplane) {
                stack[top++] = {second, tplane, t1};
                index = first;
                t1 = tplane;
            } else {
                // NaN: the ray lies in the plane, and either side may hold its hit.
                stack[top++] = {second, t0, t1};
                index = first;
            }
            continue;
        }
        const uint32_t count = node.count();
        const uint32_t* list = count == 1 && inline_single ? &nodes[index].first : refs + node.first;
        SegmentBox seg;
        if constexpr (kBoxes != LeafBoxes::None)
            seg.set(org, dir, t0, std::min(t1, hit.t), tree.cull_pad);
        for (uint32_t i = 0; i < count; ++i) {
            const uint32_t p = list[i];
            if constexpr (kBoxes != LeafBoxes::None) {
                // A culled triangle is not marked in the mailbox: it may
                // still be hit in a later leaf that references it.
                const Box& b = boxes[kBoxes == LeafBoxes::Triangle ? p : node.first + i];
                if (seg.misses(b)) {
                    ++n_culled;
                    continue;
                }
            }
            if (mailbox.seen(p)) continue;
            ++n_tests;
            TriangleHit th;
            if (intersect_triangle(sray, tris[p], tmin, hit.t, th)) {
                hit.t = th.t;
                hit.prim = int32_t(p);
                hit.u = th.u;
                hit.v = th.v;
                if constexpr (kBoxes != LeafBoxes::None)
                    seg.set(org, dir, t0, std::min(t1, hit.t), tree.cull_pad);
            }
        }
        if ((hit.prim >= 0 && hit.t <= t1) || top == 0) break;
        --top;
        index = stack[top].node;
        t0 = stack[top].tmin;
        t1 = stack[top].tmax;
    }
    steps = n_steps;
    general_steps = n_general;
    tests = n_tests;
    culled = n_culled;
}

template <LeafBoxes kBoxes>
void intersect_all(const Tree& tree, const RayBatch& rays, HitBatch& hits, int threads,
                   Progress* progress) {
    constexpr size_t kChunk = 1024;
    const uint64_t units_per_ray = rays.count ? Progress::kScale / rays.count : 0;
    parallel_for(rays.count, kChunk, resolve_threads(threads), [&](size_t begin, size_t end) {
        if (progress) progress->check();
        for (size_t i = begin; i < end; ++i) {
            const float* o = rays.origins + 3 * i;
            const float* d = rays.directions + 3 * i;
            Closest c;
            uint32_t steps = 0, general = 0, tests = 0, culled = 0;
            trace_one<kBoxes>(tree, Vec3(o[0], o[1], o[2]), Vec3(d[0], d[1], d[2]),
                              rays.tmin[i * rays.tmin_stride], rays.tmax[i * rays.tmax_stride], c,
                              steps, general, tests, culled);
            const bool hit = c.prim >= 0;
            hits.t[i] = hit ? c.t : kInf;
            hits.prim[i] = c.prim;
            hits.u[i] = hit ? c.u : 0.0f;
            hits.v[i] = hit ? c.v : 0.0f;
            hits.steps[i] = steps;
            hits.general_steps[i] = general;
            hits.tests[i] = tests;
            hits.culled[i] = culled;
        }
        if (progress) progress->add(units_per_ray * (end - begin));
    });
}

}  // namespace

void intersect(const Tree& tree, const RayBatch& rays, HitBatch& hits, int threads, bool cull,
               Progress* progress) {
    // One instantiation per box kind keeps the check out of the loop when off.
    switch (cull ? tree.options.leaf_boxes : LeafBoxes::None) {
        case LeafBoxes::None:
            return intersect_all<LeafBoxes::None>(tree, rays, hits, threads, progress);
        case LeafBoxes::Triangle:
            return intersect_all<LeafBoxes::Triangle>(tree, rays, hits, threads, progress);
        case LeafBoxes::Clipped:
            return intersect_all<LeafBoxes::Clipped>(tree, rays, hits, threads, progress);
    }
}

}  // namespace bsp
