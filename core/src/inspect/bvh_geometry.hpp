// A BVH's geometry for drawing it: the boxes of its nodes level by level,
// and the leaf whose box holds a point. Boxes are handed out in world units.
// (A BVH has no split planes or cells: tree_geometry.hpp's split polygons
// and node cells refuse it.)
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "inspect/tree_geometry.hpp"
#include "tree.hpp"

namespace bsp {

struct NodeBoxes {
    std::vector<float> lo, hi;   // x, y, z per box (world units)
    std::vector<uint32_t> node;
    std::vector<int32_t> depth;  // below the walk's root, which has depth 0
    std::vector<uint8_t> leaf;
    bool cut = false;            // max_boxes stopped the walk
};

// Every node at most `max_depth` levels below `root`, level by level (a cut
// keeps the shallow levels whole), at most `max_boxes` of them. Throws
// std::invalid_argument for a tree that is not a BVH, a negative depth or a
// root out of range.
NodeBoxes node_boxes(const Tree& tree, int max_depth, uint32_t root, size_t max_boxes);

// The first leaf in traversal order (depth first, left child first) whose
// box holds the world point p - or the first node `max_depth` deep on the
// way there (negative: a leaf); {-1, -1} when no leaf's box holds it.
NodeAt bvh_node_at(const Tree& tree, const double p[3], int max_depth);

}  // namespace bsp
