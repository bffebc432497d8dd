#include "builders/build_tree.hpp"

#include "builders/cost_model.hpp"
#include "parallel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <new>
#include <stdexcept>
#include <tuple>

namespace bsp {
namespace {

bool is_degenerate(const Triangle& t) {
    double n[3];
    t.normal_double(n);
    return n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0;
}

// Scales every coordinate by a power of two so the largest lies in [1, 2).
// Exact (unless a coordinate falls below 2^-126 of the largest), and it
// keeps every product the builders and the traversal form - areas, normals,
// edge functions, SAH costs - far from float underflow and overflow whatever
// the scene's units: at 1e-15 the unscaled traversal found no hits, below
// 1e-22 every triangle's float normal underflowed to zero, and at 1e19 the
// cell areas overflowed to a NaN cost. Returns the factor.
double normalise_scale(std::vector<Triangle>& triangles) {
    float largest = 0;
    for (const Triangle& t : triangles)
        for (const Vec3& v : t.v)
            largest = std::max({largest, std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)});
    if (!(largest > 0) || !std::isfinite(largest)) return 1.0;
    const double s = std::ldexp(1.0, -std::ilogb(largest));
    if (s == 1.0) return 1.0;
    for (Triangle& t : triangles)
        for (Vec3& v : t.v)
            v = Vec3(float(v.x * s), float(v.y * s), float(v.z * s));
    return s;
}

using Direction = std::tuple<float, float, float>;

struct StatsWalker {
    const CostModel cost;
    BuildStats& st;
    double inv_root_area = 0;
    double leaf_depth_sum = 0;
    uint64_t single_leaves = 0;  // one-reference leaves: inlined unless boxes are clipped
    std::vector<std::vector<Direction>> level_dirs{};  // general nodes' normals per level
    std::vector<uint8_t> level_axes{};                 // per level: a bit per kd axis used
    std::vector<uint64_t> level_planes{};              // per level: interior nodes

    void walk(const BuildNode& n, int depth) {
        const double p = double(n.area) * inv_root_area;
        st.max_depth = std::max(st.max_depth, depth);
        st.sah_cost += cost.tree_term(p, n.kind, n.count);
        if (n.kind == NodeKind::Leaf) {
            ++st.leaves;
            const uint64_t c = n.count;
            if (c == 0) ++st.empty_leaves;
            if (c == 1) ++single_leaves;
            st.references += c;
            st.max_leaf_size = std::max(st.max_leaf_size, c);
            leaf_depth_sum += depth;
            return;
        }
        ++st.interior_nodes;
        if (level_dirs.size() <= size_t(depth)) {
            level_dirs.resize(depth + 1);
            level_axes.resize(depth + 1);
            level_planes.resize(depth + 1);
        }
        ++level_planes[depth];
        if (is_kd(n.kind)) {
            // A bit, not a direction per node: a kd tree has a million nodes
            // and three directions, and sorting their copies showed up in
            // the build's profile.
            ++st.kd_nodes;
            level_axes[depth] |= uint8_t(1u << axis_of(n.kind));
        } else {
            ++st.general_nodes;
            level_dirs[depth].emplace_back(n.plane.nx, n.plane.ny, n.plane.nz);
        }
        walk(*n.child[0], depth + 1);
        walk(*n.child[1], depth + 1);
    }
};

struct Flattener {
    Tree& tree;

    uint32_t emit(const BuildNode& n) {
        if (tree.nodes.size() >= kMaxNodes) throw std::length_error("tree exceeds 2^29 nodes");
        const uint32_t index = uint32_t(tree.nodes.size());
        if (n.kind == NodeKind::Leaf) {
            if (n.count > kMaxLeafCount) throw std::length_error("a leaf exceeds 2^29 references");
            const uint32_t count = n.count;
            const bool clipped = tree.options.leaf_boxes == LeafBoxes::Clipped;
            if (clipped) tree.boxes.insert(tree.boxes.end(), n.ref_boxes, n.ref_boxes + count);
            if (count == 1 && !clipped) {
                tree.nodes.push_back(Node::leaf(n.refs[0], 1));
            } else {
                tree.nodes.push_back(Node::leaf(uint32_t(tree.refs.size()), count));
                tree.refs.insert(tree.refs.end(), n.refs, n.refs + count);
            }
            return index;
        }
        tree.nodes.push_back(Node());
        emit(*n.child[0]);
        const uint32_t above = emit(*n.child[1]);
        if (is_kd(n.kind)) {
            tree.nodes[index] = Node::kd(axis_of(n.kind), n.split, above);
        } else {
            tree.nodes[index] = Node::general(uint32_t(tree.planes.size()), above);
            tree.planes.push_back(n.plane);
        }
        return index;
    }
};

}  // namespace

float robust_epsilon(const std::vector<Triangle>& triangles) {
    float scale = 0;
    for (const Triangle& t : triangles)
        for (const Vec3& v : t.v)
            scale = std::max({scale, std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)});
    return scale * (1.0f / (1 << 19));
}

Prepared prepare(Tree& tree, const BuildOptions& options) {
    Prepared p;
    tree.options = options;
    tree.scale = normalise_scale(tree.triangles);
    const uint32_t n = uint32_t(tree.triangles.size());
    for (uint32_t i = 0; i < n; ++i) {
        if (is_degenerate(tree.triangles[i])) continue;
        p.live.push_back(i);
        tree.bounds.extend(tree.triangles[i].bounds());
    }
    tree.stats.triangles = n;
    tree.stats.degenerate = n - p.live.size();
    int limit = options.max_depth > 0
                    ? options.max_depth
                    : int(std::lround(8.0 + 1.3 * std::log2(std::max<double>(1, p.live.size()))));
    p.depth_limit = std::min(limit, 64);
    tree.options.max_depth = p.depth_limit;
    tree.stats.depth_limit = p.depth_limit;
    p.ref_budget = std::max(1.0, double(options.max_duplication)) * double(p.live.size());
    return p;
}

std::vector<std::string> degeneracy_warnings(const BuildStats& st) {
    std::vector<std::string> out;
    const uint64_t live = st.triangles - st.degenerate;
    char buf[256];
    if (st.max_leaf_size > kBigLeafMin && double(st.max_leaf_size) > kBigLeafShare * double(live)) {
        std::snprintf(buf, sizeof buf,
                      "degenerate tree: one leaf holds %llu of the %llu triangles (%.0f%%), "
                      "so every ray reaching it tests them all",
                      (unsigned long long)st.max_leaf_size, (unsigned long long)live,
                      100.0 * double(st.max_leaf_size) / double(live));
        out.push_back(buf);
    }
    const uint64_t full = st.leaves - st.empty_leaves;
    const double mean_leaf = full ? double(st.references) / double(full) : 0.0;
    if (live > kSmallTreeMin && (mean_leaf > double(kBigLeafMin) || 4 * st.max_depth < st.depth_limit)) {
        std::snprintf(buf, sizeof buf,
                      "degenerate tree: %llu nodes, depth %d (limit %d) for %llu triangles; "
                      "a leaf holds %.0f triangles on average",
                      (unsigned long long)(st.interior_nodes + st.leaves), st.max_depth,
                      st.depth_limit, (unsigned long long)live, mean_leaf);
        out.push_back(buf);
    }
    return out;
}

void finish(Tree& tree, const BuildNode& root, MemoryBudget& budget) {
    BuildStats& st = tree.stats;
    StatsWalker w{CostModel(tree.options), st};
    w.inv_root_area = root.area > 0 ? 1.0 / double(root.area) : 0.0;
    w.walk(root, 0);
    st.mean_leaf_depth = st.leaves ? w.leaf_depth_sum / double(st.leaves) : 0.0;
    for (size_t depth = 0; depth < w.level_dirs.size(); ++depth) {
        std::vector<Direction>& dirs = w.level_dirs[depth];
        LevelStats ls;
        ls.planes = w.level_planes[depth];
        for (int axis = 0; axis < 3; ++axis)
            if (w.level_axes[depth] & (1u << axis))
                dirs.emplace_back(float(axis == 0), float(axis == 1), float(axis == 2));
        std::sort(dirs.begin(), dirs.end());
        ls.directions = uint64_t(std::unique(dirs.begin(), dirs.end()) - dirs.begin());
        st.levels.push_back(ls);
    }
    st.warnings = degeneracy_warnings(st);

    // The flat tree's size is known before it is built: check the limit
    // first, then count the flat arrays while the pointer tree still exists.
    const bool clipped = tree.options.leaf_boxes == LeafBoxes::Clipped;
    const uint64_t n_nodes = st.interior_nodes + st.leaves;
    const uint64_t n_refs = st.references - (clipped ? 0 : w.single_leaves);
    const uint64_t n_boxes = tree.options.leaf_boxes == LeafBoxes::Triangle ? tree.triangles.size()
                             : clipped                                    ? st.references
                                                                          : 0;
    const uint64_t flat = n_nodes * sizeof(Node) + n_refs * sizeof(uint32_t) +
                          st.general_nodes * sizeof(Plane) + n_boxes * sizeof(Box);
    const uint64_t total = flat + tree.triangles.size() * sizeof(Triangle);
    if (double(total) > budget.limit_bytes()) {
        char buf[256];
        std::snprintf(buf, sizeof buf,
                      "the finished tree takes %s (%llu nodes, %llu references, %llu triangles"
                      "%s); raise memory_limit_mb, or lower max_duplication or max_depth",
                      format_mb(double(total)).c_str(), (unsigned long long)n_nodes,
                      (unsigned long long)st.references,
                      (unsigned long long)tree.triangles.size(),
                      n_boxes ? (", " + format_mb(double(n_boxes * sizeof(Box))) + " of boxes").c_str()
                              : "");
        budget.fail(budget.headline() + buf);
    }
    TaskCredit credit(budget);
    Charge flat_charge(credit, flat, -1, "the flat tree");
    tree.nodes.reserve(n_nodes);
    tree.refs.reserve(n_refs);
    tree.planes.reserve(st.general_nodes);
    tree.boxes.reserve(n_boxes);

    Flattener{tree}.emit(root);
    if (tree.options.leaf_boxes == LeafBoxes::Triangle) {
        for (const Triangle& t : tree.triangles) tree.boxes.push_back(t.bounds());
    }
    tree.cull_pad = 2.0f * robust_epsilon(tree.triangles);
    st.box_bytes = tree.boxes.size() * sizeof(Box);
    st.nodes = tree.nodes.size();
    st.bytes = tree.nodes.size() * sizeof(Node) + tree.refs.size() * sizeof(uint32_t) +
               tree.planes.size() * sizeof(Plane) + tree.triangles.size() * sizeof(Triangle) +
               st.box_bytes;
}

}  // namespace bsp
