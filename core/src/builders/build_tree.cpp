#include "builders/build_tree.hpp"

#include "builders/cost_model.hpp"
#include "frame.hpp"
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

// The statistics of a walk over a part of the pointer tree, all but the SAH
// cost (summed from the flat tree, in its order: finish() below). Parts are
// walked on threads of their own and merged; every sum here is of integers
// (the leaf depths too, exact in a double), so the order does not matter.
struct StatsWalker {
    uint64_t interior_nodes = 0, kd_nodes = 0, general_nodes = 0;
    uint64_t leaves = 0, empty_leaves = 0, references = 0, max_leaf_size = 0;
    int max_depth = 0;
    double leaf_depth_sum = 0;
    uint64_t single_leaves = 0;  // one-reference leaves: inlined unless boxes are clipped
    std::vector<std::vector<Direction>> level_dirs{};  // general nodes' normals per level
    std::vector<uint8_t> level_axes{};                 // per level: a bit per kd axis used
    std::vector<uint64_t> level_planes{};              // per level: interior nodes

    // Counts one node; false for a leaf.
    bool visit(const BuildNode& n, int depth) {
        max_depth = std::max(max_depth, depth);
        if (n.kind == NodeKind::Leaf) {
            ++leaves;
            const uint64_t c = n.count;
            if (c == 0) ++empty_leaves;
            if (c == 1) ++single_leaves;
            references += c;
            max_leaf_size = std::max(max_leaf_size, c);
            leaf_depth_sum += depth;
            return false;
        }
        ++interior_nodes;
        grow(size_t(depth) + 1);
        ++level_planes[depth];
        if (is_kd(n.kind)) {
            // A bit, not a direction per node: a kd tree has a million nodes
            // and three directions, and sorting their copies showed up in
            // the build's profile.
            ++kd_nodes;
            level_axes[depth] |= uint8_t(1u << axis_of(n.kind));
        } else {
            ++general_nodes;
            level_dirs[depth].emplace_back(n.plane.nx, n.plane.ny, n.plane.nz);
        }
        return true;
    }

    void walk(const BuildNode& n, int depth) {
        if (!visit(n, depth)) return;
        walk(*n.child[0], depth + 1);
        walk(*n.child[1], depth + 1);
    }

    void merge(const StatsWalker& o) {
        interior_nodes += o.interior_nodes;
        kd_nodes += o.kd_nodes;
        general_nodes += o.general_nodes;
        leaves += o.leaves;
        empty_leaves += o.empty_leaves;
        references += o.references;
        max_leaf_size = std::max(max_leaf_size, o.max_leaf_size);
        max_depth = std::max(max_depth, o.max_depth);
        leaf_depth_sum += o.leaf_depth_sum;
        single_leaves += o.single_leaves;
        grow(o.level_planes.size());
        for (size_t d = 0; d < o.level_planes.size(); ++d) {
            level_planes[d] += o.level_planes[d];
            level_axes[d] |= o.level_axes[d];
            level_dirs[d].insert(level_dirs[d].end(), o.level_dirs[d].begin(), o.level_dirs[d].end());
        }
    }

private:
    void grow(size_t levels) {
        if (level_planes.size() >= levels) return;
        level_dirs.resize(levels);
        level_axes.resize(levels);
        level_planes.resize(levels);
    }
};

// Where a part of the tree starts in each flat array. A node takes one
// entry of `nodes` and one of `terms` (its SAH term, at its index); a leaf
// its references (unless inlined) and, with clipped leaf boxes, their
// boxes; a general node its plane, after its children's planes.
struct FlatCursor {
    uint64_t node = 0, ref = 0, plane = 0, box = 0;
};

// What a part of the tree adds to each flat array.
FlatCursor flat_sizes(const StatsWalker& w, bool clipped) {
    FlatCursor c;
    c.node = w.interior_nodes + w.leaves;
    c.ref = w.references - (clipped ? 0 : w.single_leaves);
    c.plane = w.general_nodes;
    c.box = clipped ? w.references : 0;
    return c;
}

// Writes a subtree into the flat arrays (sized beforehand) in depth-first
// order, the child below the plane first, from `at` on; the arrays are
// shared by the threads writing disjoint parts of them.
struct Flattener {
    Tree& tree;
    const CostModel& cost;
    double inv_root_area;
    double* terms;  // each node's SAH term, at its index
    FlatCursor at;

    // The next flat index, for `n`, with its SAH term.
    uint32_t claim(const BuildNode& n) {
        const uint32_t index = uint32_t(at.node++);
        terms[index] = cost.tree_term(double(n.area) * inv_root_area, n.kind, n.count);
        return index;
    }

    uint32_t emit(const BuildNode& n) {
        const uint32_t index = claim(n);
        if (n.kind == NodeKind::Leaf) {
            if (n.count > kMaxLeafCount) throw std::length_error("a leaf exceeds 2^29 references");
            const uint32_t count = n.count;
            const bool clipped = tree.options.leaf_boxes == LeafBoxes::Clipped;
            if (clipped) {
                std::copy(n.ref_boxes, n.ref_boxes + count, tree.boxes.begin() + std::ptrdiff_t(at.box));
                at.box += count;
            }
            if (count == 1 && !clipped) {
                tree.nodes[index] = Node::leaf(n.refs[0], 1);
            } else {
                tree.nodes[index] = Node::leaf(uint32_t(at.ref), count);
                std::copy(n.refs, n.refs + count, tree.refs.begin() + std::ptrdiff_t(at.ref));
                at.ref += count;
            }
            return index;
        }
        emit(*n.child[0]);
        const uint32_t above = emit(*n.child[1]);
        write_interior(n, index, above);
        return index;
    }

    // An interior node, once its children are placed: a general node's
    // plane goes after its children's planes.
    void write_interior(const BuildNode& n, uint32_t index, uint32_t above) {
        if (is_kd(n.kind)) {
            tree.nodes[index] = Node::kd(axis_of(n.kind), n.split, above);
        } else {
            tree.nodes[index] = Node::general(uint32_t(at.plane), above);
            tree.planes[at.plane++] = n.plane;
        }
    }
};

// The finish splits the tree at this depth: the nodes there (and the
// leaves above) are walked, counted and flattened on the build's threads,
// the interior nodes above on the calling thread. At depth 6, at most 64
// parts for the threads to share out. A finish on one thread, or of a tree
// over fewer than kFinishPartTriangles triangles (whose walk is shorter
// than starting a thread), walks the whole tree as one part.
constexpr int kFinishPartDepth = 6;
constexpr size_t kFinishPartTriangles = size_t(1) << 14;

struct Part {
    const BuildNode* root;
    int depth;
    StatsWalker stats{};
    FlatCursor at{};
};

// The parts below `n` in depth-first order; the interior nodes above them
// are counted into `top`.
void collect_parts(const BuildNode& n, int depth, int part_depth, std::vector<Part>& parts,
                   StatsWalker& top) {
    if (n.kind == NodeKind::Leaf || depth == part_depth) {
        parts.push_back({&n, depth});
        return;
    }
    top.visit(n, depth);
    collect_parts(*n.child[0], depth + 1, part_depth, parts, top);
    collect_parts(*n.child[1], depth + 1, part_depth, parts, top);
}

// Places the nodes above the parts and each part's start, in the order the
// depth-first flattening of the whole tree gives them; writes those nodes.
// Returns the flat index of `n`.
uint32_t place_parts(const BuildNode& n, int depth, int part_depth, std::vector<Part>& parts,
                     size_t& next_part, Flattener& top) {
    if (n.kind == NodeKind::Leaf || depth == part_depth) {
        Part& part = parts[next_part++];
        part.at = top.at;
        const FlatCursor size = flat_sizes(part.stats, top.tree.options.leaf_boxes == LeafBoxes::Clipped);
        top.at.node += size.node;
        top.at.ref += size.ref;
        top.at.plane += size.plane;
        top.at.box += size.box;
        return uint32_t(part.at.node);
    }
    const uint32_t index = top.claim(n);
    place_parts(*n.child[0], depth + 1, part_depth, parts, next_part, top);
    const uint32_t above = place_parts(*n.child[1], depth + 1, part_depth, parts, next_part, top);
    top.write_interior(n, index, above);
    return index;
}

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
    // The frame first: the scale then brings the scene's own size, not its
    // distance from the origin, into [1, 2).
    const Frame frame = choose_frame(tree.triangles);
    move_into(frame, tree.triangles);
    std::copy(frame.offset, frame.offset + 3, tree.offset);
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
    const CostModel cost(tree.options);
    const bool clipped = tree.options.leaf_boxes == LeafBoxes::Clipped;
    const int threads = resolve_threads(tree.options.threads);
    // The parts, counted on the build's threads (the walk over the pointer
    // tree was a twentieth of a two-thread kd build, on one thread).
    const int part_depth =
        threads > 1 && tree.triangles.size() >= kFinishPartTriangles ? kFinishPartDepth : 0;
    std::vector<Part> parts;
    StatsWalker w;
    collect_parts(root, 0, part_depth, parts, w);
    parallel_for(parts.size(), 1, threads, [&](size_t b, size_t e) {
        for (size_t i = b; i < e; ++i) parts[i].stats.walk(*parts[i].root, parts[i].depth);
    });
    for (const Part& part : parts) w.merge(part.stats);

    st.max_depth = w.max_depth;
    st.interior_nodes = w.interior_nodes;
    st.kd_nodes = w.kd_nodes;
    st.general_nodes = w.general_nodes;
    st.leaves = w.leaves;
    st.empty_leaves = w.empty_leaves;
    st.references = w.references;
    st.max_leaf_size = w.max_leaf_size;
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
    const FlatCursor sizes = flat_sizes(w, clipped);
    const uint64_t n_nodes = sizes.node;
    const uint64_t n_refs = sizes.ref;
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
    if (n_nodes > kMaxNodes) throw std::length_error("tree exceeds 2^29 nodes");
    TaskCredit credit(budget);
    Charge flat_charge(credit, flat, -1, "the flat tree");
    // Each node's SAH term at its flat index, summed in that order below:
    // the depth-first order the sum always had, whatever the threads.
    Charge terms_charge(credit, n_nodes * sizeof(double), -1, "the tree's SAH terms");
    std::vector<double> terms(n_nodes);
    tree.nodes.resize(n_nodes);
    tree.refs.resize(n_refs);
    tree.planes.resize(sizes.plane);
    tree.boxes.resize(sizes.box);

    const double inv_root_area = root.area > 0 ? 1.0 / double(root.area) : 0.0;
    Flattener top{tree, cost, inv_root_area, terms.data(), FlatCursor{}};
    size_t next_part = 0;
    place_parts(root, 0, part_depth, parts, next_part, top);
    parallel_for(parts.size(), 1, threads, [&](size_t b, size_t e) {
        for (size_t i = b; i < e; ++i) {
            Flattener f{tree, cost, inv_root_area, terms.data(), parts[i].at};
            f.emit(*parts[i].root);
        }
    });
    st.sah_cost = 0;
    for (const double t : terms) st.sah_cost += t;

    if (tree.options.leaf_boxes == LeafBoxes::Triangle) {
        tree.boxes.reserve(tree.triangles.size());
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
