// Batches of rays through a tree: checks the arguments, hands chunks of rays
// to threads and each chunk to the kernel of the selected instruction set
// (kernels/, cpu_dispatch.cpp).
#include "trace/traverse.hpp"

#include <algorithm>
#include <bit>
#include <cstdlib>
#include <optional>
#include <string>
#include <stdexcept>

#include "trace/cpu_dispatch.hpp"
#include "trace/ray_order.hpp"
#include "parallel.hpp"

namespace bsp {

namespace {

constexpr int kCounterArrays = 5;

// The BVH's hits-only walk: the wide one (BvhWideNode::kWidth = 8
// children), or - with the environment variable BSPLAB_BVH_WALK=binary,
// read once - the binary walk, for the layout's benchmark
// (docs/performance.md, "The BVH"): the same hits.
TraceRange bvh_hits_kernel() {
    static const bool binary = [] {
        const char* env = std::getenv("BSPLAB_BVH_WALK");
        const std::string walk = env ? env : "";
        if (!walk.empty() && walk != "binary" && walk != "wide")
            throw std::invalid_argument("BSPLAB_BVH_WALK=" + walk + ": use wide or binary");
        return walk == "binary";
    }();
    return binary ? selected_kernels().bvh_binary_hits : selected_kernels().bvh_single_ray[0];
}

int counter_arrays(const HitBatch& hits) {
    return (hits.steps != nullptr) + (hits.general_steps != nullptr) + (hits.tests != nullptr) +
           (hits.culled != nullptr) + (hits.box_tests != nullptr);
}

// Chunks of rays to threads, each chunk to the kernel. Chunks are a multiple
// of every packet width, so a packet never straddles two chunks.
// `units_per_ray`: the progress a ray is worth (the whole batch's rays
// make Progress::kScale).
void run(TraceRange trace, const TreeView& view, const RayBatch& rays, const HitBatch& out,
         int threads, Progress* progress, uint64_t units_per_ray) {
    constexpr size_t kChunk = 1024;
    parallel_for(rays.count, kChunk, resolve_threads(threads), [&](size_t begin, size_t end) {
        if (progress) progress->check();
        trace(view, rays, out, begin, end);
        if (progress) progress->add(units_per_ray * (end - begin));
    });
}

void run(TraceRange trace, const Tree& tree, const RayBatch& rays, const HitBatch& out,
         int threads, Progress* progress) {
    const uint64_t units_per_ray = rays.count ? Progress::kScale / rays.count : 0;
    run(trace, make_tree_view(tree), rays, out, threads, progress, units_per_ray);
}

// The kd/BSP hits-only path: an incoherent batch is traced in windows of
// rays in their spatial order (ray_order.hpp), the same hits.
void run_hits_only(TraceRange trace, const Tree& tree, const RayBatch& rays,
                   const HitBatch& out, int threads, Progress* progress, RayOrder order) {
    if (!orders_batch(tree, rays, order, threads)) {
        run(trace, tree, rays, out, threads, progress);
        return;
    }
    const TreeView view = make_tree_view(tree);
    const uint64_t units_per_ray = Progress::kScale / rays.count;
    for (size_t begin = 0; begin < rays.count; begin += kOrderWindow) {
        const size_t end = std::min(rays.count, begin + kOrderWindow);
        const OrderedRays ordered(rays, begin, end, resolve_threads(threads));
        run(trace, view, ordered.rays(), ordered.hits(), threads, progress, units_per_ray);
        ordered.scatter(out);
    }
}

}  // namespace

bool orders_batch(const Tree& tree, const RayBatch& rays, RayOrder order, int threads) {
    if (tree.structure == Structure::Bvh) return false;
    // The probe of RayOrder::Auto: a few of the rays on the counting path,
    // without culling (which skips tests, not nodes), on this thread.
    // Made at the probe's first group: most batches (camera rays, short or
    // coherent ones) are decided without a probe.
    std::optional<ProbeHits> counted;
    const CountSteps count_steps = [&tree, &counted](const RayBatch& probe) {
        if (!counted) counted.emplace(kProbeGroup);
        run(selected_kernels().single_ray[1][int(LeafBoxes::None)], tree, probe, counted->hits(),
            1, nullptr);
        return counted->sum(counted->steps, probe.count);
    };
    return order_rays(rays, order, count_steps,
                      order_min_steps(false, resolve_threads(threads)));
}

void intersect(const Tree& tree, const RayBatch& rays, HitBatch& hits, int threads, bool cull,
               Progress* progress, RayOrder order) {
    const int given = counter_arrays(hits);
    if (given != 0 && given != kCounterArrays)
        throw std::invalid_argument("intersect: give all five counter arrays or none");
    if (tree.structure == Structure::Bvh) {
        // No culling: a BVH leaf's box is already its triangles' tight box.
        // Rays in their given order: the BVH's walk gains about what the
        // spatial order costs on one thread, and less than it costs on two
        // (docs/performance.md, "The sort made cheaper").
        run(given != 0 ? selected_kernels().bvh_single_ray[1] : bvh_hits_kernel(), tree, rays,
            hits, threads, progress);
        return;
    }
    // The kd/BSP kernels do no box tests.
    if (given != 0) std::fill(hits.box_tests, hits.box_tests + rays.count, 0u);
    // One instantiation per box kind keeps the culling check out of the loop
    // when off, one per counting policy keeps the counters out of the
    // hits-only path.
    const LeafBoxes boxes = cull ? tree.options.leaf_boxes : LeafBoxes::None;
    const TraceRange kernel = selected_kernels().single_ray[given != 0][int(boxes)];
    if (given != 0)
        run(kernel, tree, rays, hits, threads, progress);
    else
        run_hits_only(kernel, tree, rays, hits, threads, progress, order);
}

void intersect_packets(const Tree& tree, const RayBatch& rays, HitBatch& hits, int threads,
                       Progress* progress) {
    if (counter_arrays(hits) != 0)
        throw std::invalid_argument(
            "intersect: packets trace hits only; the counters are single-ray quantities "
            "(use counters=False with packets=True)");
    // A BVH's packets are its single rays (the same hits; no packet kernel yet).
    run(tree.structure == Structure::Bvh ? bvh_hits_kernel() : selected_kernels().packets,
        tree, rays, hits, threads, progress);
}

bool rays_are_valid(const float* origins, const float* directions, size_t count) {
    constexpr uint32_t kExponent = 0x7F800000u, kMagnitude = 0x7FFFFFFFu;
    // Accumulated without branches, so that the loops vectorize.
    uint32_t bad = 0;
    for (size_t i = 0; i < 3 * count; ++i) {  // inf or NaN: every exponent bit set
        bad |= uint32_t((std::bit_cast<uint32_t>(origins[i]) & kExponent) == kExponent);
        bad |= uint32_t((std::bit_cast<uint32_t>(directions[i]) & kExponent) == kExponent);
    }
    for (size_t i = 0; i < 3 * count; i += 3) {  // +-0 in every component
        const uint32_t any = std::bit_cast<uint32_t>(directions[i]) |
                             std::bit_cast<uint32_t>(directions[i + 1]) |
                             std::bit_cast<uint32_t>(directions[i + 2]);
        bad |= uint32_t((any & kMagnitude) == 0);
    }
    return bad == 0;
}

}  // namespace bsp
