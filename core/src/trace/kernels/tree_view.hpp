// What the traversal of one tree reads for every ray, gathered once per batch
// by the dispatching code and handed to the kernels of every instruction set.
#pragma once
#include <algorithm>
#include <cmath>

#include "frame.hpp"
#include "tree.hpp"

namespace bsp {

struct TreeView {
    const Node* nodes;
    const Plane* planes;
    const uint32_t* refs;
    const Triangle* tris;
    const Box* boxes;
    Box bounds;
    float cull_pad;
    // The kind of `boxes` (LeafBoxes::None when the tree keeps none): every
    // path, culling or not, accepts hits by them (leaf_acceptance.hpp).
    LeafBoxes box_kind;
    // Trees with a box per reference keep one-triangle leaves in refs[] too.
    bool inline_single;
    // The scene's part of a general plane's crossing error (see cross_a in
    // trace_one): twice the largest coordinate of the scene box.
    float two_scene_scale;
    // The scene box's longest side, in double: the far-ray test's scale
    // (WalkStart, kFarTestSizes), once per tree instead of once per ray.
    double box_extent;
    // Rays and distances go into the tree's scaled space and back; rays
    // into its local frame (frame.hpp) first, where `moved`.
    double scale;
    double offset[3];
    bool moved;
    // Any general node? Trees without (kd) take the kd-only traversal.
    bool has_general;
    // References per non-empty leaf: trees of big leaves take SIMD leaf
    // blocks on the hits-only path (single_ray.hpp, kSimdLeafMean).
    float mean_leaf_refs;
    // Structure::Bvh: the box nodes (null for kd and BSP trees).
    const BvhNode* bvh_nodes;
    // Structure::Bvh: its collapse into wide nodes of BvhWideNode::kWidth
    // children (the hits-only kernel's nodes).
    const BvhWideNode* bvh_wide;
    const BvhLeafTriangle* bvh_leaf_tris;  // Structure::Bvh: the triangles in refs[] order
    const uint32_t* bvh_wide_binary;  // Structure::Bvh: each wide lane's binary node
};

// A ray origin in the tree's space (frame.hpp's to_frame): the kernels'
// entries take it where the tree is moved or scaled.
inline Vec3 to_tree_space(const TreeView& view, const float o[3]) {
    return to_frame(view.offset, view.scale, o);
}

inline TreeView make_tree_view(const Tree& tree) {
    const Box& b = tree.bounds;
    const float scene_scale =
        std::max({std::fabs(b.lo.x), std::fabs(b.lo.y), std::fabs(b.lo.z), std::fabs(b.hi.x),
                  std::fabs(b.hi.y), std::fabs(b.hi.z)});
    double box_extent = 0.0;  // 0 for an empty tree's inverted box, as before
    for (int k = 0; k < 3; ++k) box_extent = std::max(box_extent, double(b.hi[k]) - double(b.lo[k]));
    return TreeView{tree.nodes.data(),
                    tree.planes.data(),
                    tree.refs.data(),
                    tree.triangles.data(),
                    tree.boxes.data(),
                    tree.bounds,
                    tree.cull_pad,
                    tree.boxes.empty() ? LeafBoxes::None : tree.options.leaf_boxes,
                    tree.options.leaf_boxes != LeafBoxes::Clipped,
                    2.0f * scene_scale,
                    box_extent,
                    tree.scale,
                    {tree.offset[0], tree.offset[1], tree.offset[2]},
                    tree.offset[0] != 0.0 || tree.offset[1] != 0.0 || tree.offset[2] != 0.0,
                    !tree.planes.empty(),
                    float(double(tree.refs.size()) /
                          double(std::max<uint64_t>(1, tree.stats.leaves - tree.stats.empty_leaves))),
                    tree.structure == Structure::Bvh ? tree.bvh_nodes.data() : nullptr,
                    tree.structure == Structure::Bvh ? tree.bvh_wide.data() : nullptr,
                    tree.structure == Structure::Bvh ? tree.bvh_leaf_tris.data() : nullptr,
                    tree.structure == Structure::Bvh ? tree.bvh_wide_binary.data() : nullptr};
}

}  // namespace bsp
