// Tracing: batches of rays through a tree (the hits-only and the counting
// path, single rays or packets), one ray's recorded walk, and the CPU's
// kernel levels.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cmath>
#include <optional>

#include "bindings/arrays.hpp"
#include "bindings/bindings.hpp"
#include "bindings/ray_batches.hpp"
#include "frame.hpp"
#include "inspect/tree_geometry.hpp"  // world_plane
#include "trace/cpu_dispatch.hpp"
#include "trace/ray_order.hpp"
#include "trace/trace_path.hpp"
#include "trace/traverse.hpp"

namespace bsp::bindings {

namespace nb = nanobind;
using namespace nb::literals;

namespace {

// The counter arrays are all given (the counting path) or all None (the
// hits-only path); the core rejects a mix.
void intersect(const Tree& tree, Vec3Array origins, Vec3Array directions, FloatIn tmin,
               FloatIn tmax, Out<float> t, Out<int32_t> prim, Out<float> u, Out<float> v,
               Counter steps, Counter general_steps, Counter tests, Counter culled,
               Counter box_tests, int threads,
               bool cull, Progress* progress, bool packets, int ray_order) {
    if (packets && cull)
        throw std::invalid_argument("intersect: packets trace without culling (use cull=False)");
    const RayBatch rays = ray_batch(origins, directions, tmin, tmax);
    HitBatch hits = hit_batch(rays.count, t, prim, u, v, steps, general_steps, tests, culled,
                              box_tests);
    nb::gil_scoped_release release;
    if (packets)
        intersect_packets(tree, rays, hits, threads, progress);
    else
        bsp::intersect(tree, rays, hits, threads, cull, progress,
                       checked_ray_order(ray_order));
}

// The recorded walk as columns: one row per visited node, one per test.
nb::dict trace_path(const Tree& tree, std::array<float, 3> o, std::array<float, 3> dir,
                    float tmin, float tmax, bool cull) {
    const TracePath p = bsp::trace_path(tree, o.data(), dir.data(), tmin, tmax, cull);
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
    d["t"] = p.t;
    d["prim"] = p.prim;
    d["u"] = p.u;
    d["v"] = p.v;
    d["steps"] = p.n_steps;
    d["general_steps"] = p.n_general_steps;
    d["tests"] = p.n_tests;
    d["culled"] = p.n_culled;
    d["box_tests"] = p.n_box_tests;
    return d;
}

nb::dict cpu_features() {
    const CpuFeatures& f = bsp::cpu_features();
    nb::dict d;
    d["supported"] = f.supported;
    d["selected"] = f.selected;
    d["packet_width"] = selected_kernels().packet_width;
    d["forced"] = f.forced.empty() ? nb::none() : nb::object(nb::str(f.forced.c_str()));
    return d;
}

}  // namespace

void bind_trace(nb::module_& m) {
    m.def("cpu_features", &cpu_features,
          "The kernels' instruction-set levels: supported here, selected, forced by BSPLAB_ISA; "
          "the selected level's rays per packet.");
    m.def(
        "rays_are_valid",
        [](Vec3Array origins, Vec3Array directions) {
            if (origins.shape(0) != directions.shape(0))
                throw std::invalid_argument("origins and directions differ in length");
            return bsp::rays_are_valid(origins.data(), directions.data(), origins.shape(0));
        },
        "origins"_a, "directions"_a, "All finite, no zero direction (checks.rays names the bad ones).");
    m.def(
        "orders_rays",
        [](Vec3Array origins, Vec3Array directions, const Tree* tree, int threads) {
            const RayBatch rays = unlimited_rays(origins, directions);
            if (!tree) return bsp::order_rays(rays, RayOrder::Spatial);
            nb::gil_scoped_release release;
            return bsp::orders_batch(*tree, rays, RayOrder::Auto, threads);
        },
        "origins"_a, "directions"_a, "tree"_a = nb::none(), "threads"_a = 0,
        "Whether the single-ray hits-only path of a kd or BSP tree traces these rays (tmin 0, "
        "tmax inf) in spatial order: under ray_order='spatial' (no tree given), or under "
        "ray_order='auto' through `tree` on `threads` threads (0: all), whose probe of the "
        "rays' walks decides too.");
    m.def("intersect", &intersect, "tree"_a, "origins"_a, "directions"_a, "tmin"_a, "tmax"_a,
          "t"_a, "prim"_a, "u"_a, "v"_a, "steps"_a.none(), "general_steps"_a.none(),
          "tests"_a.none(), "culled"_a.none(), "box_tests"_a.none(), "threads"_a, "cull"_a, "progress"_a.none(),
          "packets"_a = false, "ray_order"_a = 0);
    m.def("trace_path", &trace_path, "tree"_a, "origin"_a, "direction"_a, "tmin"_a, "tmax"_a,
          "cull"_a);
}

}  // namespace bsp::bindings
