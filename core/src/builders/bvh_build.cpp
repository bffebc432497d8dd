#include "builders/bvh_build.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <future>
#include <list>
#include <mutex>
#include <stdexcept>

#include "builders/build_tree.hpp"
#include "builders/bvh_collapse.hpp"
#include "parallel.hpp"

namespace bsp {

static_assert(BuildOptions{}.bins == kBvhBins, "one default for the BVH's bins");

namespace {

// Subtrees go to tasks of their own down to this depth: a few more tasks than
// cores, for balance. (A BVH splits by object, into two sizeable parts near
// the root; the kd and BSP builders, whose SAH peels off thin slabs, spawn by
// size instead: BuilderBase::spawns.)
int spawn_depth(int threads) {
    int depth = 0;
    while ((1 << depth) < threads) ++depth;
    return threads > 1 ? depth + 2 : 0;
}

// A primitive as the builder moves it around: its box, centroid and id.
struct PrimRef {
    Box box;
    Vec3 c;
    uint32_t id;
};

// One bin of one axis: the boxes and the centroids that fall into it.
struct Bin {
    Box box, cbox;
    uint32_t count = 0;
    void add(const PrimRef& p) {
        box.extend(p.box);
        cbox.extend(p.c);
        ++count;
    }
    void add(const Bin& b) {
        box.extend(b.box);
        cbox.extend(b.cbox);
        count += b.count;
    }
};

// The intermediate tree: nodes in per-task arenas (deques: their addresses
// stay put), linked by pointer, flattened once at the end in depth-first
// order - so node indices never depend on which task built what.
struct TmpNode {
    Box box;
    uint32_t first = 0, count = 0;  // the node's primitives [first, first + count)
    bool leaf = true;
    TmpNode* child[2] = {nullptr, nullptr};
};
constexpr uint64_t kTmpNodeBytes = 64;  // a deque slot, rounded up
static_assert(kTmpNodeBytes >= sizeof(TmpNode), "a BVH build node costs more than charged");

// A node's split: axis and bin (primitives of bins < bin go left), the
// children's boxes and centroid boxes, the SAH cost times the node's area.
struct Split {
    int axis = -1;
    int bin = 0;
    double cost = 0;
    Bin left, right;
};

// Where a centroid falls along an axis: the same float arithmetic for the
// binning and the partition, so both put every primitive in the same bin.
struct Binner {
    float lo[3], k[3];
    int bins;
    Binner(const Box& cbox, int n_bins) : bins(n_bins) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = cbox.lo[a];
            const float extent = cbox.hi[a] - cbox.lo[a];
            // Scaled a little below bins / extent, so the highest centroid
            // lands in the last bin rather than one beyond it.
            k[a] = extent > 0 ? float(n_bins) * (1.0f - 1.0f / (1 << 20)) / extent : 0.0f;
        }
    }
    int bin(const Vec3& c, int a) const {
        const int b = int((c[a] - lo[a]) * k[a]);
        return std::min(std::max(b, 0), bins - 1);
    }
};

class BvhBuilder {
public:
    BvhBuilder(std::vector<PrimRef>& prims, const BvhSettings& s, Progress* progress,
               MemoryBudget& memory)
        : prims_(prims), s_(s), progress_(progress), memory_(memory),
          spawn_depth_(spawn_depth(s.threads)) {}

    TmpNode* build_root(const Box& box, const Box& cbox) {
        std::deque<TmpNode>& arena = new_arena();
        TaskCredit credit(memory_);
        return build(arena, credit, 0, uint32_t(prims_.size()), box, cbox, 0);
    }

private:
    std::vector<PrimRef>& prims_;
    const BvhSettings& s_;
    Progress* progress_;
    MemoryBudget& memory_;
    int spawn_depth_;
    std::mutex arenas_mutex_;
    std::list<std::deque<TmpNode>> arenas_;

    std::deque<TmpNode>& new_arena() {
        std::lock_guard<std::mutex> lock(arenas_mutex_);
        return arenas_.emplace_back();
    }

    // The bins of a node of n primitives: the option's count near the root,
    // fewer below, where a sweep over all of them would cost more than the
    // binning (as Embree's builders do: 4 + n / 20, at most the option's).
    // A 40-primitive node sweeps 6 bins instead of 32.
    int bins_for(uint32_t n) const {
        return int(std::min<uint32_t>(uint32_t(s_.bins), kBvhFewestBins + n / kBvhPrimsPerBin));
    }

    void check_stop() const {
        if (progress_) progress_->check();
        memory_.check();
    }

    // The bins of primitives [begin, end) on every axis; on all threads for
    // a big node near the root (bins merge exactly: counts, mins and maxes).
    void bin(uint32_t begin, uint32_t end, const Binner& binner, int depth,
             std::vector<Bin> (&out)[3]) const {
        for (auto& b : out) b.assign(size_t(binner.bins), Bin());
        auto bin_range = [&](size_t b, size_t e, std::vector<Bin> (&into)[3]) {
            for (size_t i = b; i < e; ++i) {
                const PrimRef& p = prims_[i];
                for (int a = 0; a < 3; ++a) into[a][size_t(binner.bin(p.c, a))].add(p);
            }
        };
        const size_t n = end - begin;
        if (n < kBvhMinParallelBinning || s_.threads < 2 || (1 << depth) >= s_.threads) {
            bin_range(begin, end, out);
            return;
        }
        const size_t chunk = (n + size_t(s_.threads) - 1) / size_t(s_.threads);
        std::vector<std::vector<Bin>> parts(size_t(s_.threads) * 3);
        parallel_for(n, chunk, s_.threads, [&](size_t b, size_t e) {
            const size_t part = b / chunk;
            std::vector<Bin> local[3];
            for (auto& l : local) l.assign(size_t(binner.bins), Bin());
            bin_range(begin + b, begin + e, local);
            for (int a = 0; a < 3; ++a) parts[part * 3 + size_t(a)] = std::move(local[a]);
        });
        for (size_t part = 0; part < size_t(s_.threads); ++part)
            for (int a = 0; a < 3; ++a)
                for (size_t i = 0; i < parts[part * 3 + size_t(a)].size(); ++i)
                    out[a][i].add(parts[part * 3 + size_t(a)][i]);
    }

    // The cheapest bin boundary of the three axes (cost times the node's
    // area: Ct A + Ci (A_L n_L + A_R n_R)); axis -1 when the centroids
    // coincide on every axis.
    Split best_split(uint32_t begin, uint32_t end, const Box& box, const Box& cbox,
                     int depth) const {
        Split best;
        const int nb = bins_for(end - begin);
        const Binner binner(cbox, nb);
        // Each thread's bins, kept from node to node (best_split does not
        // recurse): no allocation per node.
        thread_local std::vector<Bin> bins[3], right;
        bin(begin, end, binner, depth, bins);
        right.resize(static_cast<size_t>(nb));
        for (int a = 0; a < 3; ++a) {
            if (!(cbox.hi[a] > cbox.lo[a])) continue;
            const std::vector<Bin>& b = bins[a];
            right[size_t(nb - 1)] = b[size_t(nb - 1)];
            for (int i = nb - 2; i >= 1; --i) {
                right[size_t(i)] = right[size_t(i) + 1];
                right[size_t(i)].add(b[size_t(i)]);
            }
            Bin left;
            for (int i = 1; i < nb; ++i) {
                left.add(b[size_t(i) - 1]);
                const Bin& r = right[size_t(i)];
                if (left.count == 0 || r.count == 0) continue;
                const double cost =
                    double(s_.traversal_cost) * box.area() +
                    double(s_.intersect_cost) * (double(left.box.area()) * left.count +
                                                 double(r.box.area()) * r.count);
                if (best.axis < 0 || cost < best.cost) {
                    best.axis = a;
                    best.bin = i;
                    best.cost = cost;
                    best.left = left;
                    best.right = r;
                }
            }
        }
        return best;
    }

    TmpNode* make_leaf(TmpNode* node, uint32_t begin, uint32_t end, int depth) const {
        node->leaf = true;
        node->first = begin;
        node->count = end - begin;
        report_leaf(progress_, depth);
        return node;
    }

    TmpNode* build(std::deque<TmpNode>& arena, TaskCredit& credit, uint32_t begin, uint32_t end,
                   const Box& box, const Box& cbox, int depth) {
        check_stop();
        Charge(credit, kTmpNodeBytes, depth, "a BVH build node").keep();
        TmpNode* node = &arena.emplace_back();
        node->box = box;
        const uint32_t n = end - begin;
        if (n <= s_.leaf_size || depth >= s_.depth_limit) return make_leaf(node, begin, end, depth);

        Split split = best_split(begin, end, box, cbox, depth);
        uint32_t mid;
        if (split.axis < 0) {
            // Every centroid the same: no bin boundary separates them. Small
            // nodes stay leaves; big ones are halved in their order.
            if (n <= kBvhMaxLeaf) return make_leaf(node, begin, end, depth);
            mid = begin + n / 2;
            split.left = Bin();
            split.right = Bin();
            for (uint32_t i = begin; i < mid; ++i) split.left.add(prims_[i]);
            for (uint32_t i = mid; i < end; ++i) split.right.add(prims_[i]);
        } else {
            const double leaf_cost = double(s_.intersect_cost) * double(n) * box.area();
            if (n <= kBvhMaxLeaf && !(split.cost < leaf_cost))
                return make_leaf(node, begin, end, depth);
            const Binner binner(cbox, bins_for(n));
            const int axis = split.axis, at = split.bin;
            const auto it = std::partition(prims_.begin() + begin, prims_.begin() + end,
                                           [&](const PrimRef& p) { return binner.bin(p.c, axis) < at; });
            mid = uint32_t(it - prims_.begin());
        }
        node->leaf = false;
        if (depth < spawn_depth_ && n > kBvhMinSpawn) {
            auto right = std::async(std::launch::async, [&, mid] {
                std::deque<TmpNode>& own = new_arena();
                TaskCredit own_credit(memory_);
                return build(own, own_credit, mid, end, split.right.box, split.right.cbox,
                             depth + 1);
            });
            try {
                node->child[0] =
                    build(arena, credit, begin, mid, split.left.box, split.left.cbox, depth + 1);
            } catch (...) {
                right.wait();  // it reads the split: let it finish (or fail) first
                throw;
            }
            node->child[1] = right.get();
        } else {
            node->child[0] =
                build(arena, credit, begin, mid, split.left.box, split.left.cbox, depth + 1);
            node->child[1] =
                build(arena, credit, mid, end, split.right.box, split.right.cbox, depth + 1);
        }
        return node;
    }
};

// The pointer tree into BvhNodes, depth first, each node's children as a
// pair; the statistics on the way.
struct BvhFlattener {
    const BvhSettings& s;
    BvhResult& out;
    double inv_root_area;
    double leaf_depth_sum = 0;

    void emit(const TmpNode& n, uint32_t index, int depth) {
        out.max_depth = std::max(out.max_depth, depth);
        const double p = double(n.box.area()) * inv_root_area;
        if (n.leaf) {
            out.nodes[index] = BvhNode::leaf(n.box, n.first, n.count);
            out.sah_cost += p * double(s.intersect_cost) * double(n.count);
            ++out.leaves;
            out.max_leaf_size = std::max<uint64_t>(out.max_leaf_size, n.count);
            leaf_depth_sum += depth;
            return;
        }
        out.sah_cost += p * double(s.traversal_cost);
        const uint32_t left = uint32_t(out.nodes.size());
        out.nodes.resize(out.nodes.size() + 2);
        out.nodes[index] = BvhNode::interior(n.box, left);
        emit(*n.child[0], left, depth + 1);
        emit(*n.child[1], left + 1, depth + 1);
    }
};

}  // namespace

BvhResult build_bvh(const std::vector<Box>& boxes, const std::vector<Vec3>& centroids,
                    const std::vector<uint32_t>& ids, const BvhSettings& settings,
                    Progress* progress, MemoryBudget& budget) {
    BvhSettings s = settings;
    s.bins = std::min(std::max(s.bins, kBvhMinBins), kBvhMaxBins);
    s.threads = std::max(1, s.threads);
    s.leaf_size = std::max(1u, s.leaf_size);
    s.depth_limit = std::min(std::max(s.depth_limit, 0), kBvhMaxDepth);
    BvhResult out;
    const size_t n = ids.size();
    if (n > BvhNode::kMaxCount) throw std::length_error("a BVH holds at most 2^32 - 2 primitives");
    TaskCredit credit(budget);
    Charge prim_charge(credit, n * sizeof(PrimRef), 0, "the BVH's primitive references");
    std::vector<PrimRef> prims(n);
    Box box, cbox;
    for (size_t i = 0; i < n; ++i) {
        const uint32_t id = ids[i];
        prims[i] = {boxes[id], centroids[id], id};
        box.extend(boxes[id]);
        cbox.extend(centroids[id]);
    }
    if (n == 0) {  // the empty tree: one leaf of nothing, its box inverted (missed by every ray)
        out.nodes.push_back(BvhNode::leaf(Box(), 0, 0));
        out.leaves = 1;
        if (progress) progress->add(Progress::kScale);
        return out;
    }
    BvhBuilder builder(prims, s, progress, budget);
    const TmpNode* root = builder.build_root(box, cbox);
    // The flat tree: fewer than 2n nodes.
    Charge flat(credit, 2 * n * sizeof(BvhNode) + n * sizeof(uint32_t), -1, "the flat BVH");
    out.nodes.reserve(2 * n);
    out.nodes.resize(1);
    BvhFlattener f{s, out, root->box.area() > 0 ? 1.0 / double(root->box.area()) : 0.0};
    f.emit(*root, 0, 0);
    out.mean_leaf_depth = f.leaf_depth_sum / double(out.leaves);
    out.order.resize(n);
    for (size_t i = 0; i < n; ++i) out.order[i] = prims[i].id;
    flat.keep();
    return out;
}

Tree build_bvh_tree(std::vector<Triangle> triangles, const BuildOptions& options,
                    Progress* progress) {
    const auto t0 = std::chrono::steady_clock::now();
    Tree tree;
    tree.structure = Structure::Bvh;
    tree.triangles = std::move(triangles);
    const Prepared prep = prepare(tree, options);
    // A BVH's depth is bounded by its stack, not by pbrt's kd rule.
    const int depth_limit =
        options.max_depth > 0 ? std::min(options.max_depth, kBvhMaxDepth) : kBvhMaxDepth;
    tree.options.max_depth = depth_limit;
    tree.stats.depth_limit = depth_limit;
    MemoryBudget budget(options.memory_limit_mb);
    const size_t n = tree.triangles.size();
    budget.charge(n * (sizeof(Triangle) + sizeof(Box) + sizeof(Vec3)) +
                      prep.live.size() * sizeof(uint32_t),
                  -1, "the triangles and their boxes");
    std::vector<Box> boxes(n);
    std::vector<Vec3> centroids(n);
    for (const uint32_t i : prep.live) {
        boxes[i] = tree.triangles[i].bounds();
        centroids[i] = (boxes[i].lo + boxes[i].hi) * 0.5f;
    }
    BvhSettings s;
    s.bins = options.bins;
    s.traversal_cost = options.traversal_cost;
    s.intersect_cost = options.intersect_cost;
    s.leaf_size = uint32_t(std::max(1, options.leaf_size));
    s.depth_limit = depth_limit;
    s.threads = resolve_threads(options.threads);
    BvhResult r = build_bvh(boxes, centroids, prep.live, s, progress, budget);
    boxes = {};
    centroids = {};

    BuildStats& st = tree.stats;
    tree.bvh_nodes = std::move(r.nodes);
    tree.refs = std::move(r.order);
    // Its wide collapse, which every path traces (about one wide node per
    // kWidth - 1 binary interior nodes, half the nodes being leaves).
    budget.charge(tree.bvh_nodes.size() / (2 * (BvhWideNode::kWidth - 1)) *
                      (sizeof(BvhWideNode) + BvhWideNode::kWidth * sizeof(uint32_t)),
                  -1, "the wide BVH");
    tree.bvh_wide = collapse_bvh(tree.bvh_nodes, &tree.bvh_wide_binary);
    budget.charge(tree.refs.size() * sizeof(BvhLeafTriangle), -1, "the triangles in leaf order");
    tree.bvh_leaf_tris.reserve(tree.refs.size());
    for (const uint32_t p : tree.refs) tree.bvh_leaf_tris.push_back({tree.triangles[p], p});
    st.nodes = tree.bvh_nodes.size();
    st.leaves = r.leaves;
    st.interior_nodes = st.nodes - st.leaves;
    st.empty_leaves = prep.live.empty() ? 1 : 0;
    st.references = tree.refs.size();
    st.max_leaf_size = r.max_leaf_size;
    st.max_depth = r.max_depth;
    st.mean_leaf_depth = r.mean_leaf_depth;
    st.sah_cost = r.sah_cost;
    // Interior nodes per level (a BVH node has no direction: 0).
    std::vector<uint32_t> stack{0};
    std::vector<int> depth_of(tree.bvh_nodes.size(), 0);
    while (!stack.empty()) {
        const uint32_t i = stack.back();
        stack.pop_back();
        const BvhNode& node = tree.bvh_nodes[i];
        if (node.is_leaf()) continue;
        const int d = depth_of[i];
        if (st.levels.size() <= size_t(d)) st.levels.resize(size_t(d) + 1);
        ++st.levels[size_t(d)].planes;
        for (const uint32_t c : {node.left(), node.right()}) {
            depth_of[c] = d + 1;
            stack.push_back(c);
        }
    }
    st.warnings = degeneracy_warnings(st);
    tree.cull_pad = 2.0f * robust_epsilon(tree.triangles);
    st.box_bytes = 0;
    st.bytes = tree.bvh_nodes.size() * sizeof(BvhNode) +
               tree.bvh_wide.size() * sizeof(BvhWideNode) + tree.refs.size() * sizeof(uint32_t) +
               tree.bvh_leaf_tris.size() * sizeof(BvhLeafTriangle) +
               tree.bvh_wide_binary.size() * sizeof(uint32_t) +
               tree.triangles.size() * sizeof(Triangle);
    const double total = double(st.bytes);
    if (total > budget.limit_bytes())
        budget.fail(budget.headline() + "the finished BVH takes " + format_mb(total) +
                    "; raise memory_limit_mb");
    st.peak_bytes = budget.peak();
    st.build_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return tree;
}

}  // namespace bsp
