// The binary BVH collapsed into 8-wide nodes (bvh_wide_node.hpp) for the
// traversal of every path (kernels/bvh_wide_single_ray.hpp).
//
// Greedy, top down (as Embree's and tinybvh's wide builders from binary
// trees): a wide node starts from a binary node's two children and, while it
// has a free lane, opens the interior child of the largest surface area -
// the one a random ray is likeliest to enter - replacing it by its two
// children. The leaves are the binary tree's own (the same triangles, the
// same refs[] slices), so the collapse changes which boxes are tested
// together, never which triangles a leaf holds, and the hits stay the binary
// walk's bit for bit.
#pragma once
#include <vector>

#include "bvh_node.hpp"
#include "bvh_wide_node.hpp"

namespace bsp {

// Wide nodes in depth-first order, the root first. A binary tree that is a
// single leaf (the empty tree, or one triangle) becomes one wide node whose
// lane 0 is that leaf.
// binary_of, when given, receives each lane's binary node (kWidth per wide node;
// an unused lane's is 0).
std::vector<BvhWideNode> collapse_bvh(const std::vector<BvhNode>& binary,
                                      std::vector<uint32_t>* binary_of = nullptr);

}  // namespace bsp
