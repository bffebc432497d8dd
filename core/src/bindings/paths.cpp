// A tree's recorded walk as the columns of Tree.trace_path (paths.hpp).
#include "bindings/paths.hpp"

#include <cmath>
#include <vector>

#include "bindings/arrays.hpp"
#include "frame.hpp"
#include "inspect/tree_geometry.hpp"  // world_plane

namespace bsp::bindings {

namespace nb = nanobind;

nb::dict path_dict(const Tree& tree, const TracePath& p) {
    const size_t n = p.steps.size(), m = p.tests.size();
    std::vector<uint32_t> node(n), test_step(m), test_prim(m);
    std::vector<int32_t> depth(n);
    std::vector<uint8_t> kind(n), result(m);
    std::vector<double> t_range(2 * n), plane(4 * n, std::nan(""));
    // A BVH step's box in world units; NaN rows on kd and BSP trees.
    std::vector<double> box_lo(3 * n, std::nan("")), box_hi(3 * n, std::nan(""));
    const bool bvh = tree.structure == Structure::Bvh;
    std::vector<float> test_t(m);
    for (size_t i = 0; i < n; ++i) {
        node[i] = p.steps[i].node;
        depth[i] = p.steps[i].depth;
        kind[i] = p.steps[i].kind;
        t_range[2 * i] = p.steps[i].t0;
        t_range[2 * i + 1] = p.steps[i].t1;
        if (!bvh) {
            world_plane(tree, node[i], &plane[4 * i]);
            continue;
        }
        const BvhNode& b = tree.bvh_nodes[node[i]];
        for (int k = 0; k < 3; ++k) {
            box_lo[3 * i + k] = to_world(b.lo[k], k, tree.offset, tree.scale);
            box_hi[3 * i + k] = to_world(b.hi[k], k, tree.offset, tree.scale);
        }
    }
    for (size_t i = 0; i < m; ++i) {
        test_step[i] = p.tests[i].step;
        test_prim[i] = p.tests[i].prim;
        result[i] = uint8_t(p.tests[i].result);
        test_t[i] = p.tests[i].t;
    }
    nb::dict d;
    d["node"] = owned_array(std::move(node));
    d["depth"] = owned_array(std::move(depth));
    d["kind"] = owned_array(std::move(kind));
    d["t_range"] = owned_array(std::move(t_range), 2);
    d["plane"] = owned_array(std::move(plane), 4);
    d["box_lo"] = owned_array(std::move(box_lo), 3);
    d["box_hi"] = owned_array(std::move(box_hi), 3);
    d["test_step"] = owned_array(std::move(test_step));
    d["test_prim"] = owned_array(std::move(test_prim));
    d["test_result"] = owned_array(std::move(result));
    d["test_t"] = owned_array(std::move(test_t));
    put_hit_and_counts(d, p);
    return d;
}

}  // namespace bsp::bindings
