// Closest hits in an instanced scene (instanced.hpp): the top level's BVH
// walked nearest box first, in double precision (its boxes are padded, so
// the walk only needs to be conservative, not exact); at each instance the
// ray carried into object space and traced through the instance's mesh tree
// by that tree's own kernel (the selected instruction set's, as intersect()
// would), its segment cut at the closest hit so far.
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <emmintrin.h>
#include <xmmintrin.h>

#include "instanced.hpp"
#include "parallel.hpp"
#include "trace/cpu_dispatch.hpp"
#include "trace/kernels/kernel_set.hpp"
#include "trace/kernels/tree_view.hpp"

namespace bsp {

namespace {

// The top level's stack: one entry per level (kBvhMaxDepth bounds the depth).
constexpr int kTopStack = 64;

// The kernel intersect() would take for a bottom tree, without culling.
TraceRange bottom_kernel(const Tree& tree, bool counting) {
    const KernelSet& k = selected_kernels();
    return tree.structure == Structure::Bvh ? k.bvh_single_ray[counting]
                                            : k.single_ray[counting][int(LeafBoxes::None)];
}

// The top level's box test, both children of a node at once in SSE: per
// axis the lanes (A near, B near, A far, B far) - the near face the high one
// where d < 0 - their crossings (x - o) / d in float, the far lanes negated,
// so that one MAXPS per axis gives both entries and both (negated) exits.
// Float is conservative here with a per-ray bound: a crossing's rounding is
// at most three of 2^-24 of |x - o| |1/d| <= (the scene's largest coordinate
// + |o|) |1/d|, and every crossing is widened by 2^-21 of that (kCrossSlack),
// so a box's range holds the exact ray's range in it; the boxes are padded
// besides (instanced_build.cpp). A NaN crossing (an origin in a face plane,
// the ray parallel to it) loses the max and is ignored. trace_path
// (bsplab/instanced.py) replays exactly this arithmetic.
constexpr float kCrossSlack = 1.0f / (1 << 21);

struct TopRay {
    __m128 org[3], sidir[3], err[3], swap[3];
    float o[3], inv[3], e[3];
    bool neg[3];

    TopRay(const float* of, const float* df, float scene_max) {
        for (int k = 0; k < 3; ++k) {
            o[k] = of[k];
            inv[k] = 1.0f / df[k];
            e[k] = df[k] == 0.0f ? 0.0f : kCrossSlack * (scene_max + std::fabs(of[k])) * std::fabs(inv[k]);
            neg[k] = std::signbit(df[k]);
            org[k] = _mm_set1_ps(o[k]);
            sidir[k] = _mm_setr_ps(inv[k], inv[k], -inv[k], -inv[k]);
            err[k] = _mm_set1_ps(e[k]);
            swap[k] = _mm_castsi128_ps(_mm_set1_epi32(neg[k] ? -1 : 0));
        }
    }

    // Lanes 0, 1: the entries of the children A, B within [s0, s1]; lanes
    // 2, 3: their exits, negated.
    void pair(const BvhNode* children, float s0, float s1, float out[4]) const {
        const float* f = reinterpret_cast<const float*>(children);
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

    // One box (the root): the same arithmetic, lane by lane.
    bool clip(const Box& b, float& t0, float& t1) const {
        for (int k = 0; k < 3; ++k) {
            const float nearf = neg[k] ? b.hi[k] : b.lo[k], farf = neg[k] ? b.lo[k] : b.hi[k];
            const float tn = (nearf - o[k]) * inv[k] - e[k];
            const float tf = (farf - o[k]) * -inv[k] - e[k];
            if (tn > t0) t0 = tn;
            if (tf > -t1) t1 = -tf;
        }
        return t0 <= t1;
    }
};

struct Bottom {
    TraceRange trace;
    TreeView view;
};

}  // namespace

void intersect_instanced(const InstancedScene& scene, const RayBatch& rays, HitBatch& hits,
                         InstanceHits& extra, int threads, Progress* progress) {
    const bool counting = hits.steps != nullptr;
    if (counting != (extra.top_steps != nullptr) ||
        (counting && (!hits.general_steps || !hits.tests || !hits.culled || !hits.box_tests ||
                      !extra.instance_visits)))
        throw std::invalid_argument("intersect_instanced: give all the counter arrays or none");
    std::vector<Bottom> bottom;
    bottom.reserve(scene.meshes.size());
    for (const Tree* t : scene.meshes) bottom.push_back({bottom_kernel(*t, counting), make_tree_view(*t)});
    const BvhNode* nodes = scene.top_nodes.data();
    // The scene's largest coordinate: the top level's crossing bound (TopRay).
    float scene_max = 0.0f;
    if (!scene.top_nodes.empty())
        for (int k = 0; k < 3; ++k)
            scene_max = std::max({scene_max, std::fabs(nodes[0].lo[k]), std::fabs(nodes[0].hi[k])});
    const uint64_t units_per_ray = rays.count ? Progress::kScale / rays.count : 0;
    constexpr size_t kChunk = 256;
    parallel_for(rays.count, kChunk, resolve_threads(threads), [&](size_t begin, size_t end) {
        if (progress) progress->check();
        for (size_t i = begin; i < end; ++i) {
            const float* of = rays.origins + 3 * i;
            const float* df = rays.directions + 3 * i;
            const float tmin = rays.tmin[i * rays.tmin_stride];
            const float tmax = rays.tmax[i * rays.tmax_stride];
            const double o[3] = {of[0], of[1], of[2]}, d[3] = {df[0], df[1], df[2]};
            const TopRay ray(of, df, scene_max);
            float best_t = tmax, best_u = 0, best_v = 0;
            int32_t best_prim = -1, best_instance = -1;
            uint64_t best_flat = std::numeric_limits<uint64_t>::max();
            uint32_t top_steps = 0, visits = 0, steps = 0, general = 0, tests = 0, culled = 0,
                     box_tests = 0;
            struct Entry {
                uint32_t node;
                float t0;
            } stack[kTopStack];
            int top = 0;
            float t0 = tmin, t1 = tmax;
            if (!scene.top_nodes.empty() && ray.clip(nodes[0].box(), t0, t1))
                stack[top++] = {0, t0};
            while (top > 0) {
                const Entry e = stack[--top];
                // A box entered beyond the closest hit holds nothing closer
                // (equal t stays: the tie rule decides between instances).
                if (e.t0 > best_t) continue;
                const BvhNode& n = nodes[e.node];
                ++top_steps;
                if (!n.is_leaf()) {
                    const uint32_t l = n.left();
                    float lanes[4];
                    ray.pair(nodes + l, tmin, best_t, lanes);
                    const float a0 = lanes[0], b0 = lanes[1];
                    const bool ha = a0 <= -lanes[2], hb = b0 <= -lanes[3];
                    // The nearer on top of the stack.
                    if (ha && hb) {
                        const bool a_first = a0 <= b0;
                        stack[top++] = {a_first ? l + 1 : l, a_first ? b0 : a0};
                        stack[top++] = {a_first ? l : l + 1, a_first ? a0 : b0};
                    } else if (ha || hb) {
                        stack[top++] = {ha ? l : l + 1, ha ? a0 : b0};
                    }
                    continue;
                }
                for (uint32_t k = 0; k < n.count(); ++k) {
                    const uint32_t id = scene.top_order[n.first + k];
                    const Instance& inst = scene.instances[id];
                    const double* m = inst.object_from_world;
                    float ob[3], db[3];
                    bool representable = true;
                    for (int r = 0; r < 3; ++r) {
                        const double x = m[4 * r] * o[0] + m[4 * r + 1] * o[1] +
                                         m[4 * r + 2] * o[2] + m[4 * r + 3];
                        const double y = m[4 * r] * d[0] + m[4 * r + 1] * d[1] + m[4 * r + 2] * d[2];
                        // Beyond float's range in object space (a ray from
                        // 10^38 units away to a small mesh): no float ray there.
                        representable &= std::fabs(x) <= double(FLT_MAX) && std::fabs(y) <= double(FLT_MAX);
                        ob[r] = representable ? float(x) : 0.0f;
                        db[r] = representable ? float(y) : 0.0f;
                    }
                    if (!representable) continue;
                    if (db[0] == 0.0f && db[1] == 0.0f && db[2] == 0.0f) continue;  // underflow
                    ++visits;
                    // Beyond the closest hit by one ulp, so that a hit at the
                    // same t comes back and the tie rule can take it.
                    const float limit = best_prim < 0 ? tmax : std::nextafter(best_t, kInf);
                    float t, u, v;
                    int32_t prim;
                    uint32_t c[5] = {0, 0, 0, 0, 0};
                    RayBatch one;
                    one.origins = ob;
                    one.directions = db;
                    one.tmin = &tmin;
                    one.tmax = &limit;
                    one.count = 1;
                    HitBatch out{&t, &prim, &u, &v};
                    if (counting) {
                        out.steps = c;
                        out.general_steps = c + 1;
                        out.tests = c + 2;
                        out.culled = c + 3;
                        out.box_tests = c + 4;
                    }
                    const Bottom& b = bottom[inst.mesh];
                    b.trace(b.view, one, out, 0, 1);
                    steps += c[0], general += c[1], tests += c[2], culled += c[3];
                    box_tests += c[4];
                    if (prim < 0) continue;
                    const uint64_t flat = scene.flat_offset[id] + uint64_t(prim);
                    if (t < best_t || (t == best_t && flat < best_flat)) {
                        best_t = t;
                        best_u = u;
                        best_v = v;
                        best_prim = prim;
                        best_instance = int32_t(id);
                        best_flat = flat;
                    }
                }
            }
            hits.t[i] = best_prim >= 0 ? best_t : kInf;
            hits.prim[i] = best_prim;
            hits.u[i] = best_u;
            hits.v[i] = best_v;
            extra.instance[i] = best_instance;
            if (counting) {
                hits.steps[i] = steps;
                hits.general_steps[i] = general;
                hits.tests[i] = tests;
                hits.culled[i] = culled;
                hits.box_tests[i] = box_tests;
                extra.top_steps[i] = top_steps;
                extra.instance_visits[i] = visits;
            }
        }
        if (progress) progress->add(units_per_ray * (end - begin));
    });
}

}  // namespace bsp
