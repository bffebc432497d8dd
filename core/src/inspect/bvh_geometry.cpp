#include "inspect/bvh_geometry.hpp"

#include <stdexcept>
#include <string>
#include <utility>

#include "frame.hpp"

namespace bsp {

NodeBoxes node_boxes(const Tree& tree, int max_depth, uint32_t root, size_t max_boxes) {
    if (tree.structure != Structure::Bvh)
        throw std::invalid_argument(
            "node_boxes: this tree has no boxes (a kd or BSP tree: use split_polygons or "
            "leaf_cells)");
    if (max_depth < 0)
        throw std::invalid_argument("max_depth must be >= 0, got " + std::to_string(max_depth));
    if (root >= tree.bvh_nodes.size())
        throw std::invalid_argument("root must be < " + std::to_string(tree.bvh_nodes.size()) +
                                    ", got " + std::to_string(root));
    NodeBoxes out;
    std::vector<uint32_t> level{root}, next;
    for (int depth = 0; depth <= max_depth && !level.empty(); ++depth) {
        next.clear();
        for (const uint32_t i : level) {
            if (out.node.size() == max_boxes) {
                out.cut = true;
                return out;
            }
            const BvhNode& n = tree.bvh_nodes[i];
            for (int k = 0; k < 3; ++k) {
                out.lo.push_back(float(to_world(n.lo[k], k, tree.offset, tree.scale)));
                out.hi.push_back(float(to_world(n.hi[k], k, tree.offset, tree.scale)));
            }
            out.node.push_back(i);
            out.depth.push_back(depth);
            out.leaf.push_back(n.is_leaf());
            if (!n.is_leaf()) {
                next.push_back(n.left());
                next.push_back(n.right());
            }
        }
        std::swap(level, next);
    }
    return out;
}

NodeAt bvh_node_at(const Tree& tree, const double p[3], int max_depth) {
    const double s = tree.scale;
    const float q[3] = {float((p[0] - tree.offset[0]) * s), float((p[1] - tree.offset[1]) * s),
                        float((p[2] - tree.offset[2]) * s)};
    auto holds = [&](const BvhNode& n) {
        for (int k = 0; k < 3; ++k)
            if (!(n.lo[k] <= q[k] && q[k] <= n.hi[k])) return false;
        return true;
    };
    // Depth first, left child first: the first leaf whose box holds q.
    std::vector<std::pair<uint32_t, int32_t>> stack{{0u, 0}};
    while (!stack.empty()) {
        const auto [i, depth] = stack.back();
        stack.pop_back();
        const BvhNode& n = tree.bvh_nodes[i];
        if (!holds(n)) continue;
        if (n.is_leaf()) {
            if (n.count() == 0) continue;
            return {int64_t(i), depth};
        }
        if (depth == max_depth) {
            // The node max_depth deep on the way to the first leaf that holds q.
            std::vector<uint32_t> below{i};
            while (!below.empty()) {
                const uint32_t j = below.back();
                below.pop_back();
                const BvhNode& m = tree.bvh_nodes[j];
                if (!holds(m)) continue;
                if (m.is_leaf()) {
                    if (m.count() != 0) return {int64_t(i), depth};
                    continue;
                }
                below.push_back(m.right());
                below.push_back(m.left());
            }
            continue;
        }
        stack.push_back({n.right(), depth + 1});
        stack.push_back({n.left(), depth + 1});
    }
    return {-1, -1};
}

}  // namespace bsp
