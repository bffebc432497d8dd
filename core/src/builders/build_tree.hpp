// What every builder shares: input preparation, the intermediate pointer
// tree, and the finishing pass (statistics, flattening to the compact layout).
#pragma once
#include <atomic>
#include <chrono>
#include <cmath>
#include <future>
#include <memory>
#include <vector>

#include "builders/cost_model.hpp"
#include "builders/memory.hpp"
#include "builders/node_arena.hpp"
#include "progress.hpp"
#include "tree.hpp"

namespace bsp {

// A node of the pointer tree, in the build's NodeArena (as are a leaf's lists).
struct BuildNode {
    NodeKind kind = NodeKind::Leaf;
    float split = 0;  // kd nodes: the plane's position along the axis
    Plane plane{};  // general nodes: the plane n.x = d
    float area = 0; // surface area of the node's cell (for the SAH cost stat)
    uint32_t count = 0;  // leaves: references
    BuildNode* child[2] = {nullptr, nullptr};
    uint32_t* refs = nullptr;  // leaves: the triangles, ascending
    Box* ref_boxes = nullptr;  // LeafBoxes::Clipped: the clipped box of each reference
};
static_assert(kBuildNodeBytes >= sizeof(BuildNode) + 16, "a build node costs more than charged");

// What a leaf with `count` references costs in the pointer tree.
inline uint64_t leaf_bytes(const BuildOptions& opt, size_t count) {
    const uint64_t per_ref =
        sizeof(uint32_t) + (opt.leaf_boxes == LeafBoxes::Clipped ? sizeof(Box) : 0);
    return kBuildNodeBytes + per_ref * count;
}

// The fattening of extents along non-axis planes and the padding of the
// segment box in leaf culling: 2^-19 of the scene's largest coordinate, well
// beyond the float error of a plane crossing or a segment end point.
float robust_epsilon(const std::vector<Triangle>& triangles);

struct Prepared {
    std::vector<uint32_t> live;  // indices of the non-degenerate triangles
    int depth_limit = 0;
    double ref_budget = 0;       // references allowed in the whole tree
};

// Copies the options, counts degenerate triangles, sets bounds and limits.
Prepared prepare(Tree& tree, const BuildOptions& options);

// A tree degenerates - and stats.warnings says so - when
//  * its largest leaf holds more than kBigLeafMin triangles and more than
//    kBigLeafShare of the live triangles: every ray reaching it tests them all;
//  * or, with more than kSmallTreeMin live triangles, the tree is small for the
//    scene: its non-empty leaves hold more than kBigLeafMin triangles on
//    average, or it stays shallower than a quarter of its depth limit.
// Well-built SAH trees hold a few triangles per leaf and reach their depth limit.
constexpr uint64_t kBigLeafMin = 64;
constexpr double kBigLeafShare = 0.05;
constexpr uint64_t kSmallTreeMin = 10000;
std::vector<std::string> degeneracy_warnings(const BuildStats& stats);

// Fills tree.stats from the pointer tree, flattens it into tree.nodes/refs/
// planes, and enforces the memory limit on the finished tree and on the
// flattening (MemoryLimitExceeded, before anything is flattened).
void finish(Tree& tree, const BuildNode& root, MemoryBudget& budget);

// A node builds its right subtree on a task of its own while it holds at
// least 1 / (kSpawnShare x threads) of the scene's triangles and each child
// more than kMinSpawnTriangles: a few more tasks than cores, for balance.
// The rule goes by size, not depth, because an SAH tree peels empty space
// and thin slabs off its big nodes: conference's kd root keeps 206,656 of
// its right child's 206,737 triangles for two more levels, and a rule of
// "spawn above depth 3" spent its tasks there and left that subtree - 62 %
// of the build - to one thread. Every task builds the nodes it would
// serially, so the trees do not depend on the threads.
constexpr size_t kSpawnShare = 4;
// Below this many triangles a child is not worth a thread of its own.
constexpr size_t kMinSpawnTriangles = 4096;
// At most this many tasks per thread run at once: a scene whose splits
// duplicate most triangles has many big nodes.
constexpr int kMaxTasksPerThread = 4;

// What the node recursion of every builder reads - the triangles, the
// options and their cost model, progress, threads, the memory budget, the
// node arena - and
// the two decisions they share: stop (cancelled, over budget) and spawn.
class BuilderBase {
public:
    BuilderBase(const std::vector<Triangle>& tris, const BuildOptions& opt, Progress* progress,
                int threads, MemoryBudget& memory, NodeArena& arena)
        : tris_(tris), opt_(opt), cost_(opt), progress_(progress), threads_(threads),
          memory_(memory), arena_(arena) {}

protected:
    // Throws Cancelled or MemoryLimitExceeded when the build must stop.
    void check_stop() const {
        if (progress_) progress_->check();
        memory_.check();
    }

    // True when a node of `triangles` (references) whose smaller child holds
    // `smaller` builds its right subtree on a task of its own; it then takes
    // one of the open task slots, which spawn() gives back when the task ends.
    bool spawns(size_t triangles, size_t smaller) {
        if (threads_ <= 1 || smaller <= kMinSpawnTriangles ||
            triangles * kSpawnShare * size_t(threads_) < tris_.size())
            return false;
        if (open_tasks_.fetch_add(1) < kMaxTasksPerThread * threads_) return true;
        open_tasks_.fetch_sub(1);
        return false;
    }

    // Runs `work` on a task of its own (after spawns() said yes), holding
    // the slot spawns() took until the work returns or throws.
    template <class Work>
    auto spawn(Work work) {
        return std::async(std::launch::async, [this, work = std::move(work)]() mutable {
            const SpawnedTask slot(open_tasks_);
            return work();
        });
    }

    const std::vector<Triangle>& tris_;
    const BuildOptions& opt_;
    const CostModel cost_;
    Progress* progress_;
    int threads_;
    std::atomic<int> open_tasks_{0};  // spawned tasks still running
    MemoryBudget& memory_;
    NodeArena& arena_;  // the pointer tree's nodes and leaf lists (a Local per task)

private:
    class SpawnedTask {
    public:
        explicit SpawnedTask(std::atomic<int>& open) : open_(open) {}
        ~SpawnedTask() { open_.fetch_sub(1); }
        SpawnedTask(const SpawnedTask&) = delete;
        SpawnedTask& operator=(const SpawnedTask&) = delete;

    private:
        std::atomic<int>& open_;
    };
};

// Each child may use the parent's reference budget in proportion to its
// share, which bounds the tree's total references deterministically.
inline void split_budget(double budget, double n_left, double n_right, double& left,
                         double& right) {
    left = std::floor(budget * n_left / (n_left + n_right));
    right = budget - left;
}

// Runs a builder: prepares the tree, lets build_root(tree, prepared, budget,
// arena) build the pointer tree over the live triangles in `arena` (not
// called when there are none), then fills the statistics, flattens, and
// times the whole build; the arena frees the pointer tree at once. The
// memory budget starts with the triangles themselves.
template <class BuildRoot>
Tree run_builder(std::vector<Triangle> triangles, const BuildOptions& options,
                 BuildRoot&& build_root) {
    const auto t0 = std::chrono::steady_clock::now();
    Tree tree;
    tree.triangles = std::move(triangles);
    const Prepared prep = prepare(tree, options);
    MemoryBudget budget(options.memory_limit_mb);
    budget.charge(tree.triangles.capacity() * sizeof(Triangle) +
                      prep.live.capacity() * sizeof(uint32_t),
                  -1, "the triangles");
    NodeArena arena;
    const BuildNode* root = prep.live.empty() ? NodeArena::Local(arena).make<BuildNode>()
                                              : build_root(tree, prep, budget, arena);
    finish(tree, *root, budget);
    tree.stats.peak_bytes = budget.peak();
    tree.stats.build_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return tree;
}

// Adds a leaf's share to the build progress: a leaf at depth d completes
// 2^-d of a binary tree, so the shares of all leaves sum to one.
inline void report_leaf(Progress* progress, int depth) {
    if (progress && depth < 52) progress->add(Progress::kScale >> depth);
}

}  // namespace bsp
