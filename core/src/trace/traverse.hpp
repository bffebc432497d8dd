// Closest-hit traversal of kd and general BSP trees, and of BVHs, over batches of rays.
#pragma once
#include <cstddef>
#include <cstdint>

#include "tree.hpp"
#include "progress.hpp"

namespace bsp {

// Views of caller-owned arrays (numpy buffers); nothing here allocates.
struct RayBatch {
    const float* origins = nullptr;     // n x 3
    const float* directions = nullptr;  // n x 3
    const float* tmin = nullptr;        // n, or one value when tmin_stride == 0
    const float* tmax = nullptr;
    size_t tmin_stride = 0, tmax_stride = 0;
    size_t count = 0;
};

struct HitBatch {
    float* t;        // inf on miss
    int32_t* prim;   // -1 on miss
    float* u;
    float* v;
    // The counters: all five arrays, or all five null for the hits-only
    // path, which is compiled without any counting (same hits, bit for bit).
    // Nodes visited, of every kind. An empty leaf the walk skips from its
    // parent (single_ray.hpp) still counts: the counts are the walk's nodes.
    uint32_t* steps = nullptr;
    uint32_t* general_steps = nullptr;  // general (plane) nodes among them
    uint32_t* tests = nullptr;          // ray-triangle tests performed
    uint32_t* culled = nullptr;         // tests skipped by the segment-box check
    uint32_t* box_tests = nullptr;      // ray-box tests (BVH trees; 0 on kd and BSP trees)
};

// How the single-ray hits-only path of a kd or BSP tree orders a batch
// (Tree.intersect's ray_order; an instanced scene's too). Spatial traces an
// incoherent batch - random or scattered rays, not a camera's nor rays cast
// from its hits in pixel order - in windows sorted by the rays' origins and
// directions (ray_order.hpp): neighbouring rays then walk mostly the same
// nodes, and the walk runs faster. Auto does so only when the rays' walks
// are long enough to pay for the sort (a probe of the batch on the counting
// path, ray_order.hpp): rays that mostly miss the scene trace faster as
// given. Given traces every batch in the caller's order. The hits are the
// same in every order, bit for bit; the counting path, the packets and the
// BVH always take the given order. The values are Python's ray_order
// strings' indices ("auto", "spatial", "given"; bsplab.checks.RAY_ORDERS).
enum class RayOrder : int { Auto = 0, Spatial = 1, Given = 2 };

// With `cull` (and boxes in the tree), a leaf skips the triangles whose box
// misses the box of the ray's segment inside the leaf. Throws
// std::invalid_argument when only some of the counter arrays are given.
// A BVH tree (Structure::Bvh) takes the BVH kernel (kernels/bvh_single_ray.hpp),
// for which cull changes nothing: its leaves' boxes are already tight.
void intersect(const Tree& tree, const RayBatch& rays, HitBatch& hits, int threads, bool cull,
               Progress* progress = nullptr, RayOrder order = RayOrder::Auto);

// Whether intersect()'s hits-only path traces this batch in spatial order
// (ray_order.hpp) on `threads` threads (0: all): never on a BVH, which keeps
// the given order.
bool orders_batch(const Tree& tree, const RayBatch& rays, RayOrder order, int threads);

// The same closest hits, traced in packets of consecutive rays (as many as
// the selected level's SIMD lanes; kernels/packet.hpp): fast when consecutive
// rays are coherent, e.g. camera rays in tile order. Hits only, no culling:
// throws std::invalid_argument when counter arrays are given.
void intersect_packets(const Tree& tree, const RayBatch& rays, HitBatch& hits, int threads,
                       Progress* progress = nullptr);

// True when every origin and direction is finite and no direction is zero:
// what the Python layer checks before a trace, here in one pass over the
// bits (numpy's checks cost a quarter of a packet trace). The caller finds
// and names the bad rays when this says there are some.
bool rays_are_valid(const float* origins, const float* directions, size_t count);

}  // namespace bsp
