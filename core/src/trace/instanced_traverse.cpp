// Closest hits in an instanced scene (instanced.hpp): the top level's BVH
// walked nearest box first, two levels a step, in float with a per-ray bound
// on the rounding (top_walk.hpp's walk_top and TopRay; its boxes are padded
// besides, so the walk only needs to be conservative, not exact); at each
// instance the ray carried into object space and traced through the
// instance's mesh tree by that tree's own kernel (the selected instruction
// set's, as intersect() would), its segment cut at the closest hit so far.
// The packet path walks groups of rays with top_walk.hpp's pieces.
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

#include "instanced.hpp"
#include "parallel.hpp"
#include "trace/cpu_dispatch.hpp"
#include "trace/kernels/kernel_set.hpp"
#include "trace/kernels/tree_view.hpp"
#include "trace/ray_order.hpp"
#include "trace/top_walk.hpp"

namespace bsp {

namespace {

using top_walk::BottomHit;
using top_walk::Closest;
using top_walk::kTopStack;
using top_walk::object_ray;
using top_walk::scene_max_of;
using top_walk::TopRay;
using top_walk::TopVisit;
using top_walk::walk_top;

// Rays per thread's chunk (and progress step) on both paths.
constexpr size_t kChunk = 256;

// The kernel intersect() would take for a bottom tree, without culling: its
// packet kernel on the packet path (a BVH's: its single rays, as intersect's).
TraceRange bottom_kernel(const Tree& tree, bool counting, bool packets) {
    const KernelSet& k = selected_kernels();
    if (tree.structure == Structure::Bvh) return k.bvh_single_ray[counting];
    return packets ? k.packets : k.single_ray[counting][int(LeafBoxes::None)];
}

struct Bottom {
    TraceRange trace;
    TreeView view;
};

// walk_top's policy on the single-ray path: each instance's mesh tree traced
// by its kernel; with counting, the top level's steps, the instances entered
// and the mesh trees' counters (steps, general steps, tests, culled, box
// tests) summed over them.
struct CountTop {
    static constexpr bool kRecords = false;
    const std::vector<Bottom>& bottom;
    bool counting;
    uint32_t top_steps = 0, visits = 0;
    uint32_t c[5] = {0, 0, 0, 0, 0};

    void top_step(const TopVisit&) { ++top_steps; }
    void trace_instance(uint32_t, const Instance& inst, const float ob[3], const float db[3],
                        float tmin, float limit, BottomHit& h) {
        ++visits;
        RayBatch one;
        one.origins = ob;
        one.directions = db;
        one.tmin = &tmin;
        one.tmax = &limit;
        one.count = 1;
        uint32_t n[5] = {0, 0, 0, 0, 0};
        HitBatch out{&h.t, &h.prim, &h.u, &h.v};
        if (counting) {
            out.steps = n;
            out.general_steps = n + 1;
            out.tests = n + 2;
            out.culled = n + 3;
            out.box_tests = n + 4;
        }
        const Bottom& b = bottom[inst.mesh];
        b.trace(b.view, one, out, 0, 1);
        for (int k = 0; k < 5; ++k) c[k] += n[k];
    }
};

}  // namespace

bool orders_batch(const InstancedScene& scene, const RayBatch& rays, RayOrder order,
                  int threads) {
    // As for a single BVH, a scene whose mesh trees are all BVHs keeps the
    // given order: on two threads it measured 0.5 - 6.5 % slower sorted.
    const bool all_bvh = std::all_of(scene.meshes.begin(), scene.meshes.end(), [](const Tree* t) {
        return t->structure == Structure::Bvh;
    });
    if (all_bvh) return false;
    // The probe of RayOrder::Auto: a few of the rays on the counting path,
    // on this thread; a step of the top level counts as one of a mesh tree.
    // Made at the probe's first group, as for a tree (traverse.cpp).
    std::optional<ProbeHits> counted;
    const CountSteps count_steps = [&scene, &counted](const RayBatch& probe) {
        if (!counted) counted.emplace(kProbeGroup);
        HitBatch hits = counted->hits();
        InstanceHits extra{counted->instance.data(), counted->top_steps.data(),
                           counted->instance_visits.data()};
        intersect_instanced(scene, probe, hits, extra, 1, nullptr, RayOrder::Given);
        return counted->sum(counted->steps, probe.count) +
               counted->sum(counted->top_steps, probe.count);
    };
    return order_rays(rays, order, count_steps,
                      order_min_steps(true, resolve_threads(threads)));
}

void intersect_instanced(const InstancedScene& scene, const RayBatch& rays, HitBatch& hits,
                         InstanceHits& extra, int threads, Progress* progress, RayOrder order) {
    const bool counting = hits.steps != nullptr;
    if (counting != (extra.top_steps != nullptr) ||
        (counting && (!hits.general_steps || !hits.tests || !hits.culled || !hits.box_tests ||
                      !extra.instance_visits)))
        throw std::invalid_argument("intersect_instanced: give all the counter arrays or none");
    std::vector<Bottom> bottom;
    bottom.reserve(scene.meshes.size());
    for (const Tree* t : scene.meshes)
        bottom.push_back({bottom_kernel(*t, counting, false), make_tree_view(*t)});
    const float scene_max = scene_max_of(scene);
    const uint64_t units_per_ray = rays.count ? Progress::kScale / rays.count : 0;
    // A batch (the caller's, or a window of it in spatial order) traced
    // ray by ray on the threads; the captures name what every batch shares.
    const auto trace_batch = [&scene, &bottom, scene_max, counting, threads, progress,
                              units_per_ray](const RayBatch& rays, const HitBatch& hits,
                                             const InstanceHits& extra) {
        parallel_for(rays.count, kChunk, resolve_threads(threads), [&](size_t begin, size_t end) {
            if (progress) progress->check();
            for (size_t i = begin; i < end; ++i) {
                const float* of = rays.origins + 3 * i;
                const float* df = rays.directions + 3 * i;
                const float tmin = rays.tmin[i * rays.tmin_stride];
                const float tmax = rays.tmax[i * rays.tmax_stride];
                const double o[3] = {of[0], of[1], of[2]}, d[3] = {df[0], df[1], df[2]};
                const TopRay ray(of, df, scene_max);
                Closest best;
                best.t = tmax;
                CountTop count{bottom, counting};
                walk_top(scene, ray, o, d, tmin, tmax, best, count);
                best.write(hits, extra, i);
                if (counting) {
                    hits.steps[i] = count.c[0];
                    hits.general_steps[i] = count.c[1];
                    hits.tests[i] = count.c[2];
                    hits.culled[i] = count.c[3];
                    hits.box_tests[i] = count.c[4];
                    extra.top_steps[i] = count.top_steps;
                    extra.instance_visits[i] = count.visits;
                }
            }
            if (progress) progress->add(units_per_ray * (end - begin));
        });
    };
    // The hits-only path traces an incoherent batch in windows of rays in
    // their spatial order (ray_order.hpp), as Tree.intersect does: the same
    // hits, the instance index written back with them. Neighbouring rays
    // then enter the same instances and walk the same nodes of the top
    // level and of the mesh trees (docs/instances.md has the gain).
    if (counting || !orders_batch(scene, rays, order, threads)) {
        trace_batch(rays, hits, extra);
        return;
    }
    std::vector<int32_t> instance(std::min(rays.count, kOrderWindow));
    for (size_t begin = 0; begin < rays.count; begin += kOrderWindow) {
        const OrderedRays ordered(rays, begin, std::min(rays.count, begin + kOrderWindow),
                                  resolve_threads(threads));
        const InstanceHits ordered_extra{instance.data()};
        trace_batch(ordered.rays(), ordered.hits(), ordered_extra);
        ordered.scatter(hits);
        ordered.scatter(instance.data(), extra.instance);
    }
}

// Rays walked together through the top level on the packet path.
constexpr int kGroup = 8;

void intersect_instanced_packets(const InstancedScene& scene, const RayBatch& rays, HitBatch& hits,
                                 InstanceHits& extra, int threads, Progress* progress) {
    if (hits.steps || extra.top_steps || extra.instance_visits)
        throw std::invalid_argument(
            "intersect: packets trace hits only; pass counters=False with packets=True");
    std::vector<Bottom> bottom;
    bottom.reserve(scene.meshes.size());
    for (const Tree* t : scene.meshes)
        bottom.push_back({bottom_kernel(*t, false, true), make_tree_view(*t)});
    const TopLevel::Pair* pairs = scene.top.pairs.data();
    const float scene_max = scene_max_of(scene);
    const uint64_t units_per_ray = rays.count ? Progress::kScale / rays.count : 0;
    static_assert(kChunk % kGroup == 0, "groups stay inside a thread's chunk");
    parallel_for(rays.count, kChunk, resolve_threads(threads), [&](size_t begin, size_t end) {
        if (progress) progress->check();
        for (size_t first = begin; first < end; first += kGroup) {
            // A group of consecutive rays (a tile of camera rays: render's
            // order) walks the top level as one: a node is entered by the
            // rays whose own test (TopRay, their own closest hit) enters it,
            // and at an instance those rays, carried into its object space
            // each as on the single-ray path, go through the mesh tree's
            // packet kernel together. A ray may see an instance its own walk
            // would have passed by - its box not entered before the ray's
            // closest hit, so nothing there is nearer - and the closest hit
            // over instances does not depend on their order, as long as a
            // mesh tree's closest hit does not depend on the segment's end
            // (each instance's limit is the closest hit so far, met in
            // another order here). It does on rays lying in a triangle's
            // plane: a fuzzed kd tree hit at 0.430 with tmax = inf and
            // missed with tmax = 0.687 (Embree: 0.549), which the oracle's
            // in-plane rule excuses. There the two paths may differ; on
            // every other ray they agree bit for bit.
            const int g = int(std::min<size_t>(kGroup, end - first));
            TopRay ray[kGroup];
            double o[kGroup][3], d[kGroup][3];
            float tmin[kGroup], tmax[kGroup];
            Closest best[kGroup];
            uint32_t mask = 0;
            for (int j = 0; j < g; ++j) {
                const size_t i = first + size_t(j);
                const float* of = rays.origins + 3 * i;
                const float* df = rays.directions + 3 * i;
                for (int k = 0; k < 3; ++k) o[j][k] = of[k], d[j][k] = df[k];
                tmin[j] = rays.tmin[i * rays.tmin_stride];
                tmax[j] = rays.tmax[i * rays.tmax_stride];
                ray[j] = TopRay(of, df, scene_max);
                best[j].t = tmax[j];
                float t0 = tmin[j], t1 = tmax[j];
                if (!scene.top.empty() && ray[j].clip(scene.top.root, t0, t1)) mask |= 1u << j;
            }
            struct Entry {
                TopLevel::Link node;
                uint32_t rays;
            } stack[kTopStack];
            int top = 0;
            TopLevel::Link n = scene.top.root_link;
            while (mask) {
                if (!n.is_leaf()) {
                    const TopLevel::Pair& p = TopLevel::pair_of(pairs, n.left());
                    uint32_t in_a = 0, in_b = 0;
                    int nearer_b = 0;  // rays that enter B first, less those that enter A first
                    for (uint32_t m = mask; m; m &= m - 1) {
                        const int j = __builtin_ctz(m);
                        float a0, b0;
                        const int e = ray[j].pair(p, tmin[j], best[j].t, a0, b0);
                        in_a |= uint32_t(e & 1) << j;
                        in_b |= uint32_t(e >> 1) << j;
                        nearer_b += (e == 2 || (e == 3 && b0 < a0)) ? 1 : (e != 0 ? -1 : 0);
                    }
                    if (in_a | in_b) {
                        // The child most of the group enters first, now; the
                        // other, with its rays, pushed.
                        const unsigned near_b = in_a == 0 || (in_b != 0 && nearer_b > 0);
                        const uint32_t far_rays = near_b ? in_a : in_b;
                        if (far_rays) stack[top++] = {p.link[near_b ^ 1u], far_rays};
                        n = p.link[near_b];
                        mask = near_b ? in_b : in_a;
                        continue;
                    }
                } else {
                    for (uint32_t k = 0; k < n.count(); ++k) {
                        const uint32_t id = scene.top_order[n.first + k];
                        const Instance& inst = scene.instances[id];
                        float ob[kGroup][3], db[kGroup][3], lo[kGroup], limit[kGroup];
                        int slot[kGroup], count = 0;
                        for (uint32_t m = mask; m; m &= m - 1) {
                            const int j = __builtin_ctz(m);
                            if (!object_ray(inst, o[j], d[j], ob[count], db[count])) continue;
                            lo[count] = tmin[j];
                            limit[count] = best[j].limit(tmax[j]);
                            slot[count++] = j;
                        }
                        if (count == 0) continue;
                        float t[kGroup], u[kGroup], v[kGroup];
                        int32_t prim[kGroup];
                        RayBatch batch;
                        batch.origins = &ob[0][0];
                        batch.directions = &db[0][0];
                        batch.tmin = lo;
                        batch.tmax = limit;
                        batch.tmin_stride = batch.tmax_stride = 1;
                        batch.count = size_t(count);
                        const HitBatch out{t, prim, u, v};
                        const Bottom& b = bottom[inst.mesh];
                        b.trace(b.view, batch, out, 0, size_t(count));
                        for (int c = 0; c < count; ++c)
                            if (prim[c] >= 0)
                                best[slot[c]].take(t[c], u[c], v[c], prim[c], id,
                                                   scene.flat_offset[id] + uint64_t(prim[c]));
                    }
                }
                mask = 0;
                while (top > 0 && !mask) {
                    const Entry e = stack[--top];
                    n = e.node;
                    mask = e.rays;
                }
            }
            for (int j = 0; j < g; ++j) best[j].write(hits, extra, first + size_t(j));
        }
        if (progress) progress->add(units_per_ray * (end - begin));
    });
}

}  // namespace bsp
