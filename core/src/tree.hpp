// The flat, compact tree: 8-byte nodes in depth-first order, one shared array
// of triangle references, and a plane array for general (non-axis) nodes -
// or, for a bounding-volume hierarchy (Structure::Bvh), 32-byte box nodes
// (bvh_node.hpp) over the same reference array.
#pragma once
#include <algorithm>
#include <cassert>
#include <cstdint>
#include <string>
#include <vector>

#include "bvh_node.hpp"
#include "bvh_wide_node.hpp"
#include "geometry.hpp"

namespace bsp {

// What a node is: a kd split along x, y or z, a leaf, or a general split
// along any plane; or a BVH's interior box node (Box, trees of
// Structure::Bvh only, whose leaves are Leaf). The kd kinds' values are
// their axes.
enum class NodeKind : uint8_t { X = 0, Y = 1, Z = 2, Leaf = 3, General = 4, Box = 5 };

// What a tree is made of: split planes (kd and BSP trees: `nodes`, `planes`)
// or a hierarchy of boxes (`bvh_nodes`). Every entry that reads a tree
// (traversal, trace_path, the geometry queries, statistics) branches on it
// once, at the top.
enum class Structure : uint8_t { Bsp = 0, Bvh = 1 };

constexpr bool is_kd(NodeKind k) { return k <= NodeKind::Z; }
constexpr NodeKind kd_kind(int axis) {
    assert(axis >= 0 && axis < 3);
    return NodeKind(axis);
}
constexpr int axis_of(NodeKind k) {
    assert(is_kd(k));
    return int(k);
}

// A node is 8 bytes: `split` or `first`, and `bits`, whose low bits say the
// kind (the tag) and whose high bits hold a child index or a count.
//   kd       tag 0, 1 or 2 in two bits, the axis: `split` is the plane
//            position along it, the other 30 bits the index of the child
//            above the plane;
//   leaf     tag 3 in three bits (0b011): the other 29 bits are the
//            reference count and `first` the offset into the reference
//            array - or, for a one-triangle leaf, the triangle itself, which
//            saves one indirection;
//   general  tag 7 in three bits (0b111): `first` indexes planes[] (n.x, n.y,
//            n.z, d; the plane n.x = d), the other 29 bits the index of the
//            child above.
// Kd nodes spend two bits on the tag; leaves and general nodes share the
// two-bit tag 3 and spend a third bit to tell themselves apart.
// The child below (n.x < d) always follows its parent.
// The encoders assert that a child index or count fits (debug, sanitizer and
// C++ test builds); callers that can overflow check before (kMaxNodes,
// kMaxLeafCount in the flattening).
struct Node {
    union {
        float split;
        uint32_t first;
    };
    uint32_t bits;

    static constexpr uint32_t kKdTagBits = 2, kKdTagMask = (1u << kKdTagBits) - 1;
    static constexpr uint32_t kTagBits = 3, kTagMask = (1u << kTagBits) - 1;
    static constexpr uint32_t kNotKdTag = 3u;  // the two-bit tag of leaves and general nodes
    static constexpr uint32_t kLeafTag = kNotKdTag, kGeneralTag = kNotKdTag | 4u;
    static constexpr uint32_t kMaxKdChild = UINT32_MAX >> kKdTagBits;
    static constexpr uint32_t kMaxPayload = UINT32_MAX >> kTagBits;  // general child, leaf count

    constexpr bool is_kd() const { return (bits & kKdTagMask) != kNotKdTag; }
    constexpr bool is_leaf() const { return (bits & kTagMask) == kLeafTag; }
    constexpr bool is_general() const { return (bits & kTagMask) == kGeneralTag; }
    constexpr NodeKind kind() const {
        return is_kd() ? NodeKind(bits & kKdTagMask)
                       : is_leaf() ? NodeKind::Leaf : NodeKind::General;
    }
    constexpr int axis() const {
        assert(is_kd());
        return int(bits & kKdTagMask);
    }
    constexpr uint32_t kd_above() const {
        assert(is_kd());
        return bits >> kKdTagBits;
    }
    constexpr uint32_t count() const {
        assert(is_leaf());
        return bits >> kTagBits;
    }
    constexpr uint32_t general_above() const {
        assert(is_general());
        return bits >> kTagBits;
    }

    static constexpr Node kd(int axis, float split, uint32_t above) {
        assert(axis >= 0 && axis < 3 && above <= kMaxKdChild);
        Node n{};
        n.split = split;
        n.bits = uint32_t(axis) | (above << kKdTagBits);
        return n;
    }
    static constexpr Node general(uint32_t plane, uint32_t above) {
        assert(above <= kMaxPayload);
        Node n{};
        n.first = plane;
        n.bits = kGeneralTag | (above << kTagBits);
        return n;
    }
    static constexpr Node leaf(uint32_t first, uint32_t count) {
        assert(count <= kMaxPayload);
        Node n{};
        n.first = first;
        n.bits = kLeafTag | (count << kTagBits);
        return n;
    }
};
static_assert(sizeof(Node) == 8, "nodes must stay 8 bytes");

struct Plane {
    float nx, ny, nz, d;
};

// Every child index must fit a general node's 29 bits, every count a leaf's.
constexpr uint32_t kMaxNodes = Node::kMaxPayload;
constexpr uint32_t kMaxLeafCount = Node::kMaxPayload;

// How much work a kd or sweep build spends looking for each plane
// (registry option build_quality). Exact sweeps every candidate position at
// every node (the trees of the theses). Fast bins the candidates of the big
// nodes near the root - kFastBins positions per direction, at nodes of at
// least kFastMinRefs references - and sweeps exactly below, and it splits a
// node only where the split saves at least kFastMinGain of the leaf's cost:
// a quicker build of a slightly worse tree, for previews. The BVH is binned
// either way.
enum class BuildQuality : int { Exact = 0, Fast = 1 };
// At most this many bins per direction. Counting a reference costs the same
// for any bin count; 32 bins put conference's root plane elsewhere than the
// exact sweep does, and its camera rays took 7 % more steps (kd) and 5 %
// (bsp_wn+kd K = 8); 1024 build as fast (docs/build_quality.md).
constexpr int kFastBins = 1024;
constexpr int kFastMinRefs = 4096;
// The sweep prices each binned plane with its cell's areas (a clip of the
// cell's faces), not a few flops as kd does, so a sweep node of n references
// prices at most kSweepMinBins + n / kSweepRefsPerBin bins per direction
// (as Embree's binned builders do, 4 + n / 20): the root of a big scene gets
// fast_bins, a node of 4096 references 36.
constexpr int kSweepMinBins = 4;
constexpr size_t kSweepRefsPerBin = 128;
inline int sweep_bins(size_t refs, int fast_bins) {
    return int(std::min<size_t>(size_t(fast_bins), kSweepMinBins + refs / kSweepRefsPerBin));
}
// The exact builds split wherever a split is any cheaper than a leaf, and
// most of their nodes are deep ones that save a few percent each. A fast
// build makes a split only where it saves at least kFastMinGain of the
// leaf's cost, counted over at most kFastGainRefs references (a node of
// more must save as much as one of that many: a small share of a big node
// can be many tests, and the camera's rays all cross the cells around it).
// At 0.05 a fast kd tree has a fifth fewer interior nodes (bunny 300,783
// -> 241,559) for an SAH cost within 1 % of exact; docs/build_quality.md
// has the measurements behind both.
constexpr double kFastMinGain = 0.05;
constexpr size_t kFastGainRefs = 10;
// A kd split clips each triangle it cuts to both children's cells ("perfect
// splits"): a clip, a sort and a merge of new events on all three axes. A
// fast build does that only where the children hold at least
// kFastClipMinRefs references; below, the triangle keeps its box in the
// node and only the split axis is cut at the plane. At 12 the fast kd
// builds were 3 - 21 % quicker on the shared meshes for SAH costs 0.0 -
// 1.3 % higher than clipping everywhere (bunny 1.021 of exact), and no
// slower to trace (docs/build_quality.md); at 16 bunny's rose past 3 %.
constexpr int kFastClipMinRefs = 12;

enum class LeafBoxes : int {
    None = 0,      // no culling possible
    Triangle = 1,  // each triangle's own box: 24 bytes per triangle
    Clipped = 2,   // each reference's triangle clipped to its leaf cell: 24 bytes per reference
};

struct BuildOptions {
    float traversal_cost = 1.0f;   // K_d: one kd step (every step without ^Kd)
    float intersect_cost = 1.5f;   // K_i: one ray-triangle test
    float empty_bonus = 0.2f;
    int max_depth = 0;             // 0: 8 + 1.3 log2(N), as in pbrt
    int leaf_size = 1;             // nodes with this many triangles or fewer become leaves
    float max_duplication = 8.0f;  // references <= max_duplication * triangles
    double memory_limit_mb = 4096.0;  // the registry's default is sized from the machine
    int threads = 0;
    // The BSP family (ignored by the kd builder).
    // How the builder picks candidate directions at a node: a name in
    // strategy_names() (builders/strategies/strategy.hpp), each in its own
    // builders/strategies/*.cpp.
    std::string strategy = "axes";
    int k = 3;                     // directions per node, the axes included for "+" methods
    bool plus_axes = false;        // "+": the three axes are among the K
    bool kd_nodes = false;         // ^Kd: axis splits become cheap kd nodes
    int fixed_set = 0;             // RBSP: 0 golden spiral, 1 k-DOP, 2 axes + spiral
    uint64_t seed = 1;
    float alpha = 0.1f;            // ^Kd: K_d,BSP = alpha K_i (n - 1) + K_d
    float general_cost = 1.4f;     // ^Kd fallback: the constant K_d,BSP (measured)
    int cluster_iterations = 16;   // BSP_cn: k-means rounds at most
    int cluster_sample = 1024;     // BSP_cn: normals clustered per node at most
    int ize_candidates = 64;       // BSP_IZE: triangles whose planes are tried per node at most
    // The BVH (ignored by the others): centroid bins per axis of the binned SAH.
    int bins = 32;  // builders/bvh_build.hpp's kBvhBins, asserted there
    // Leaf culling with the ray segment's box (seed 002): which boxes to keep.
    LeafBoxes leaf_boxes = LeafBoxes::Triangle;
    // kd and the sweep builder (the BVH ignores them): see BuildQuality.
    BuildQuality build_quality = BuildQuality::Exact;
    int fast_bins = kFastBins;          // bins per direction of a binned node
    int fast_min_refs = kFastMinRefs;   // nodes with at least this many references are binned
    float fast_min_gain = float(kFastMinGain);  // share of the leaf (<= kFastGainRefs refs) a split must save
    int fast_clip_min_refs = kFastClipMinRefs;  // kd: splits into fewer references cut boxes, not triangles
};

struct LevelStats {
    uint64_t planes = 0;      // interior nodes at this depth
    uint64_t directions = 0;  // distinct split directions among them
};

struct BuildStats {
    double build_seconds = 0;
    uint64_t triangles = 0, degenerate = 0;
    uint64_t nodes = 0, interior_nodes = 0, kd_nodes = 0, general_nodes = 0;
    uint64_t leaves = 0, empty_leaves = 0;
    uint64_t references = 0, max_leaf_size = 0;
    int max_depth = 0, depth_limit = 0;
    double mean_leaf_depth = 0, sah_cost = 0;
    uint64_t bytes = 0, box_bytes = 0;
    uint64_t peak_bytes = 0;  // the most the memory budget counted at once during the build
    std::vector<LevelStats> levels;
    // Signs of a degenerate tree (degeneracy_warnings() in build_tree.cpp), one sentence each.
    std::vector<std::string> warnings;
};

struct Tree {
    Structure structure = Structure::Bsp;
    // Input numbering, degenerate ones included, moved by -offset into the
    // tree's local frame (frame.hpp: 0 on every axis but those where the
    // scene lies far from the origin) and multiplied by `scale`: a power of
    // two that brings the largest coordinate into [1, 2). Both exact. Rays
    // go the same way on the way in (to_frame), distances are scaled back
    // on the way out (the offset does not change them).
    std::vector<Triangle> triangles;
    double offset[3] = {0.0, 0.0, 0.0};
    double scale = 1.0;
    std::vector<Node> nodes;
    std::vector<uint32_t> refs;
    std::vector<Plane> planes;
    // Structure::Bvh: the box nodes (root first, children in pairs); refs[]
    // holds the leaves' triangles, nodes and planes stay empty.
    std::vector<BvhNode> bvh_nodes;
    // Structure::Bvh: the same tree collapsed into wide nodes of
    // BvhWideNode::kWidth children (root first), which the hits-only path
    // traces (builders/bvh_collapse.hpp). Derived
    // from bvh_nodes, so not part of the tree's hash (node_bytes).
    std::vector<BvhWideNode> bvh_wide;
    // The binary node of each wide lane (BvhWideNode::kWidth per wide node): the counters and
    // trace_path report the walk in the binary tree's numbering.
    std::vector<uint32_t> bvh_wide_binary;
    // Structure::Bvh: the triangles in leaf order with their indices
    // (bvh_leaf_tris[i] = {triangles[refs[i]], refs[i]}), so that a leaf's
    // triangles are side by side and the wide walk reads no refs[].
    std::vector<BvhLeafTriangle> bvh_leaf_tris;
    // Culling boxes: per triangle (LeafBoxes::Triangle) or per reference slot
    // of refs[] (LeafBoxes::Clipped, where leaves never inline a triangle).
    std::vector<Box> boxes;
    float cull_pad = 0;  // padding of the segment box: beyond any float error of the traversal
    Box bounds;
    BuildOptions options;
    BuildStats stats;
};

}  // namespace bsp
