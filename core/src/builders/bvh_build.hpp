// The BVH builder: binned SAH over primitive boxes (Wald 2007, "On fast
// construction of SAH-based bounding volume hierarchies"), into the 32-byte
// binary nodes of bvh_node.hpp.
//
// The core (build_bvh) knows nothing of triangles: it takes an array of
// boxes and centroids, so that a top level over instance boxes can reuse it.
// build_bvh_tree is its first user, the registry's builder for triangles.
#pragma once
#include <cstdint>
#include <vector>

#include "builders/memory.hpp"
#include "progress.hpp"
#include "tree.hpp"

namespace bsp {

// Centroid bins per axis unless the options say (BuildOptions::bins). 32,
// not 16: the SAH costs hardly differ (bunny 33.6 with 16, 33.5 with 32),
// but on sponza's axis-aligned walls 16 bins put splits beside the walls
// where 32 put them on them, and camera rays visited 10.6 wide nodes a ray
// with 16 bins against 6.9 with 32 (time 1.58x Embree's against 1.27x;
// docs/performance.md, "The BVH").
constexpr int kBvhBins = 32;
constexpr int kBvhMinBins = 2, kBvhMaxBins = 256;
// Below the root, a node of n primitives bins into at most kBvhFewestBins +
// n / kBvhPrimsPerBin bins (builders/bvh_build.cpp, bins_for).
constexpr uint32_t kBvhFewestBins = 4, kBvhPrimsPerBin = 20;
// A node of more primitives than this is split even where the SAH prefers a
// leaf (a leaf's tests are linear in its size; a forced split bounds them).
constexpr uint32_t kBvhMaxLeaf = 16;
// The traversal's stack holds one entry per level: no leaf deeper than this.
constexpr int kBvhMaxDepth = 60;
// Nodes of more primitives than this build their second child on a task of
// their own (down to spawn_depth(threads)), and bin on all threads at once.
constexpr size_t kBvhMinSpawn = 4096;
constexpr size_t kBvhMinParallelBinning = 1 << 16;

struct BvhSettings {
    int bins = kBvhBins;
    float traversal_cost = 1.0f;  // one node visited: the two child boxes tested
    float intersect_cost = 1.5f;  // one primitive tested
    uint32_t leaf_size = 1;       // nodes of at most this many primitives become leaves
    int depth_limit = kBvhMaxDepth;
    int threads = 1;
};

struct BvhResult {
    std::vector<BvhNode> nodes;   // root first, children in pairs
    std::vector<uint32_t> order;  // the primitives' ids in leaf order (leaf.first indexes it)
    double sah_cost = 0;          // sum of Ct P(interior) + Ci n P(leaf), P = area / root area
    int max_depth = 0;
    uint64_t leaves = 0, max_leaf_size = 0;
    double mean_leaf_depth = 0;
};

// The BVH over primitives `ids` (boxes[id], centroids[id]). Deterministic:
// the same nodes for any thread count. Throws Cancelled, MemoryLimitExceeded.
BvhResult build_bvh(const std::vector<Box>& boxes, const std::vector<Vec3>& centroids,
                    const std::vector<uint32_t>& ids, const BvhSettings& settings,
                    Progress* progress, MemoryBudget& budget);

// The registry's BVH builder (BuildFunction, builder.hpp): over the live
// triangles' boxes, their centres as centroids.
Tree build_bvh_tree(std::vector<Triangle> triangles, const BuildOptions& options,
                    Progress* progress);

}  // namespace bsp
