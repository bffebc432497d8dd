// The flat, compact kd-tree: 8-byte nodes in depth-first order plus one
// shared array of triangle references (the layout of pbrt-v3's kd-tree).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "geometry.hpp"

namespace bsp {

// Interior: `split` is the plane position, the low two bits of `bits` the axis
// (0, 1, 2) and the upper 30 bits the index of the child above the plane; the
// child below is the next node. Leaf: low bits == 3, upper bits the reference
// count, `first` the offset into the reference array - or, for a one-triangle
// leaf, the triangle itself, which saves one indirection.
struct KdNode {
    union {
        float split;
        uint32_t first;
    };
    uint32_t bits;

    static constexpr uint32_t kLeaf = 3;
    bool is_leaf() const { return (bits & 3u) == kLeaf; }
    int axis() const { return int(bits & 3u); }
    uint32_t above_child() const { return bits >> 2; }
    uint32_t count() const { return bits >> 2; }

    static KdNode interior(int axis, float split, uint32_t above) {
        KdNode n;
        n.split = split;
        n.bits = uint32_t(axis) | (above << 2);
        return n;
    }
    static KdNode leaf(uint32_t first, uint32_t count) {
        KdNode n;
        n.first = first;
        n.bits = kLeaf | (count << 2);
        return n;
    }
};
static_assert(sizeof(KdNode) == 8, "kd nodes must stay 8 bytes");

constexpr uint32_t kMaxNodes = (1u << 30) - 1;

struct BuildOptions {
    float traversal_cost = 1.0f;
    float intersect_cost = 1.5f;
    float empty_bonus = 0.2f;
    int max_depth = 0;             // 0: 8 + 1.3 log2(N), as in pbrt
    int leaf_size = 1;             // nodes with this many triangles or fewer become leaves
    float max_duplication = 8.0f;  // references <= max_duplication * triangles
    double memory_limit_mb = 4096.0;
    int threads = 0;
};

struct BuildStats {
    double build_seconds = 0;
    uint64_t triangles = 0, degenerate = 0;
    uint64_t nodes = 0, interior_nodes = 0, leaves = 0, empty_leaves = 0;
    uint64_t references = 0, max_leaf_size = 0;
    int max_depth = 0, depth_limit = 0;
    double mean_leaf_depth = 0, sah_cost = 0;
    uint64_t bytes = 0;
};

struct KdTree {
    std::vector<Triangle> triangles;  // input numbering, degenerate ones included
    std::vector<KdNode> nodes;
    std::vector<uint32_t> refs;
    Box bounds;
    BuildOptions options;
    BuildStats stats;
};

}  // namespace bsp
