// Incoherent rays traced in a spatial order. A batch of random or
// secondary rays visits the tree's nodes in no order: each ray's walk
// starts with cold caches and branches the predictor has not seen. Sorted
// by their origins' and directions' cells (one Morton code over six
// coordinates), neighbouring rays start in the same part of the scene and
// run the same way, so they walk mostly the same nodes one after the other.
// The hits are the same bit for bit, since each ray is traced alone as
// before; only the order in which the rays are traced changes, and the hits
// are written back in the caller's order.
#pragma once
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "trace/ray_coherence.hpp"
#include "trace/traverse.hpp"

namespace bsp {

// An incoherent batch of at least this many rays is traced in order: at
// 4,096 random rays the sort about pays for itself (0.98 - 0.99 of the
// time), the gain grows with the batch (docs/performance.md).
constexpr size_t kOrderMinRays = 4096;
// The rays are ordered in windows of at most this many, which bounds the
// copies' memory (68 bytes a ray, 17 MiB) whatever the batch's size.
constexpr size_t kOrderWindow = size_t(1) << 18;
// Cells per axis of the origins' box (2^bits) and of the directions'
// cube, in the sort key: 5 + 5 bits on six coordinates, a 30-bit key.
constexpr int kOrderOriginBits = 5;
constexpr int kOrderDirectionBits = 5;

// The sort pays only for walks that cost more than it does (about 25 ns a
// ray on a real tree, its radix sort on one thread): random rays drawn in a
// box a few times a scene's size mostly miss it, walk a few nodes each, and
// traced up to 1.66 x slower sorted on two threads (docs/performance.md).
// Under RayOrder::Auto an incoherent batch is sorted only when a probe of
// its rays walks at least kOrderMinSteps nodes a ray in a tree, or
// kOrderMinInstancedSteps in an instanced scene (top level and mesh trees
// together: a two-level walk gains less from the order and its sort writes
// one more column back), half of each on one thread (below). The probe: at
// most kProbeRays rays spread evenly over the batch, traced on the counting
// path (one thread) in groups of kProbeGroup, stopping as soon as the steps
// reach the bar.
constexpr uint32_t kOrderMinSteps = 8;
constexpr uint32_t kOrderMinInstancedSteps = 16;
// A trace on one thread has half the bars. The radix sort runs on one
// thread whatever the trace's count, so beside a one-thread trace it weighs
// half as much: there random rays walking 4.6 - 7.8 nodes a ray traced 7 -
// 20 % faster sorted (bunny, conference, Šibenik), while at 1.9 - 3.5 the
// sort gained at most 5 % or lost (docs/performance.md, "One thread, half
// the bar").
constexpr uint32_t kOrderMinStepsOneThread = 4;
constexpr uint32_t kOrderMinInstancedStepsOneThread = 8;

// The bar of a trace on `threads` threads (resolved: 0 is not "all" here).
constexpr uint32_t order_min_steps(bool instanced, int threads) {
    if (threads <= 1) return instanced ? kOrderMinInstancedStepsOneThread : kOrderMinStepsOneThread;
    return instanced ? kOrderMinInstancedSteps : kOrderMinSteps;
}
constexpr size_t kProbeRays = 128;
constexpr size_t kProbeGroup = 16;

// Traces a probe's rays on the counting path and returns the nodes they
// visited in all (an instanced scene's: the top level's and the mesh
// trees'). The probe's rays have per-ray limits.
using CountSteps = std::function<uint64_t(const RayBatch&)>;

// Whether intersect() traces this batch in spatial order (RayOrder, in
// traverse.hpp): an incoherent batch of at least kOrderMinRays rays, whose
// directions and origins are both unlike their neighbours', and under
// RayOrder::Auto whose probe walks at least `min_steps` nodes a ray
// (`count_steps`; without one, Auto orders as Spatial does).
bool order_rays(const RayBatch& rays, RayOrder order, const CountSteps& count_steps = {},
                uint32_t min_steps = kOrderMinSteps);

// Whether the batch's rays walk at least `min_steps` nodes each on average,
// by the probe above.
bool walks_pay_for_order(const RayBatch& rays, const CountSteps& count_steps, uint32_t min_steps);

// The counting path's output for a group of a probe's rays (at most the
// size it was made for): hits and every counter, an instanced scene's
// included. One per probe, re-used by its groups.
struct ProbeHits {
    explicit ProbeHits(size_t n);
    HitBatch hits();
    // A counter's sum over the group's first `n` rays.
    static uint64_t sum(const std::vector<uint32_t>& counter, size_t n);
    std::vector<float> t, u, v;
    std::vector<int32_t> prim, instance;
    std::vector<uint32_t> steps, general_steps, tests, culled, box_tests, top_steps,
        instance_visits;
};

// The ordering's steps (the origins' box, the keys, the copy, the scatter)
// run on the tracing threads in chunks of this many rays; only the radix
// sort runs on one.
constexpr size_t kOrderChunk = size_t(1) << 14;

// Rays [begin, end) of a batch copied in their sort order, with room for
// their hits; scatter() writes the hits back to the caller's rays. The
// copies live in the calling thread's buffers: one OrderedRays at a time
// per thread. `threads` (at least 1) share the work; the order is the same
// whatever their number.
class OrderedRays {
public:
    OrderedRays(const RayBatch& rays, size_t begin, size_t end, int threads = 1);
    const RayBatch& rays() const { return rays_; }
    const HitBatch& hits() const { return hits_; }
    // The hits of the ordered rays into `out`, at the rays' own indices.
    void scatter(const HitBatch& out) const;
    // One more column of per-ray results (the instanced path's instance
    // index): `ordered[i]` of the i-th ray traced into `out` at its index.
    void scatter(const int32_t* ordered, int32_t* out) const;

private:
    size_t begin_, count_;
    int threads_;
    // In the calling thread's scratch (ray_order.cpp), valid until its next
    // OrderedRays: order_[i] is the caller's ray (from begin) traced i-th.
    const uint32_t* order_ = nullptr;
    RayBatch rays_;
    HitBatch hits_{};
};

}  // namespace bsp
