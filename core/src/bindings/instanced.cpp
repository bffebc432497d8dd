// Instanced scenes: the top level over instances of shared mesh trees
// (instanced.hpp), built and traced. The Python InstancedTree keeps the mesh
// trees alive; the scene only points at them.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/vector.h>

#include <optional>
#include <stdexcept>
#include <string>

#include "bindings/arrays.hpp"
#include "bindings/bindings.hpp"
#include "bindings/ray_batches.hpp"
#include "instanced.hpp"

namespace bsp::bindings {

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using MatrixArray = nb::ndarray<const double, nb::shape<-1, 3, 4>, nb::c_contig, nb::device::cpu>;
using IndexArray = nb::ndarray<const uint32_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

InstancedScene build(const std::vector<const Tree*>& meshes, IndexArray mesh_index,
                     MatrixArray matrices, int bins, float traversal_cost, float intersect_cost,
                     int threads, Progress* progress) {
    const size_t n = mesh_index.shape(0);
    if (matrices.shape(0) != n)
        throw std::invalid_argument("build_instanced: one matrix per instance");
    std::vector<uint32_t> index(mesh_index.data(), mesh_index.data() + n);
    std::vector<double> m(matrices.data(), matrices.data() + 12 * n);
    TopLevelSettings s;
    s.bins = bins;
    s.traversal_cost = traversal_cost;
    s.intersect_cost = intersect_cost;
    s.threads = threads;
    nb::gil_scoped_release release;
    return build_instanced(meshes, index, m, s, progress);
}

void intersect(const InstancedScene& scene, Vec3Array origins, Vec3Array directions,
               FloatIn tmin, FloatIn tmax, Out<float> t, Out<int32_t> prim, Out<float> u,
               Out<float> v, Out<int32_t> instance, Counter steps, Counter general_steps,
               Counter tests, Counter culled, Counter box_tests, Counter top_steps,
               Counter instance_visits, int threads, bool packets, Progress* progress,
               int ray_order) {
    const RayBatch rays = ray_batch(origins, directions, tmin, tmax);
    HitBatch hits = hit_batch(rays.count, t, prim, u, v, steps, general_steps, tests, culled,
                              box_tests);
    check_length(rays.count, instance.shape(0), "instance");
    InstanceHits extra{instance.data(), counter_column(rays.count, top_steps, "top_steps"),
                       counter_column(rays.count, instance_visits, "instance_visits")};
    nb::gil_scoped_release release;
    if (packets)
        intersect_instanced_packets(scene, rays, hits, extra, threads, progress);
    else
        intersect_instanced(scene, rays, hits, extra, threads, progress,
                            checked_ray_order(ray_order));
}

nb::dict stats(const InstancedScene& scene) {
    const InstancedStats& s = scene.stats;
    nb::dict d;
    d["meshes"] = s.meshes;
    d["instances"] = s.instances;
    d["top_nodes"] = s.top_nodes;
    d["top_leaves"] = s.top_leaves;
    d["top_bytes"] = s.top_bytes;
    d["top_depth"] = s.top_depth;
    d["top_sah_cost"] = s.top_sah_cost;
    d["top_build_seconds"] = s.top_build_seconds;
    d["instanced_triangles"] = s.instanced_triangles;
    return d;
}

// The top level's nodes and the instances' inverse matrices, as arrays: for
// drawing the top level's boxes and for trace_path's walk (bsplab/instanced.py),
// which replays the core's walk from them.
nb::dict top_arrays(const InstancedScene& scene) {
    const size_t n = scene.top.size();
    std::vector<float> lo(3 * n), hi(3 * n);
    std::vector<uint32_t> first(n), count(n);
    std::vector<uint8_t> leaf(n);
    for (size_t i = 0; i < n; ++i) {
        const BvhNode b = scene.top.node(i);
        for (int k = 0; k < 3; ++k) {
            lo[3 * i + k] = b.lo[k];
            hi[3 * i + k] = b.hi[k];
        }
        leaf[i] = b.is_leaf();
        first[i] = b.is_leaf() ? b.first : b.left();
        count[i] = b.is_leaf() ? b.count() : 0;
    }
    std::vector<double> inverse(12 * scene.instances.size());
    for (size_t i = 0; i < scene.instances.size(); ++i)
        std::copy(scene.instances[i].object_from_world, scene.instances[i].object_from_world + 12,
                  inverse.begin() + 12 * i);
    nb::dict d;
    d["lo"] = owned_array(std::move(lo), 3);
    d["hi"] = owned_array(std::move(hi), 3);
    d["leaf"] = owned_array(std::move(leaf));
    d["first"] = owned_array(std::move(first));  // a leaf's first order[] slot, else its left child
    d["count"] = owned_array(std::move(count));
    d["order"] = owned_array(std::vector<uint32_t>(scene.top_order));
    d["object_from_world"] = owned_array(std::move(inverse), 12);
    return d;
}

}  // namespace

void bind_instanced(nb::module_& m) {
    nb::class_<InstancedScene>(m, "InstancedScene")
        .def("stats", &stats)
        .def("top_arrays", &top_arrays, "The top level's nodes and the instances' inverses.");
    m.def(
        "check_instance_matrices",
        [](MatrixArray matrices) {
            check_instance_matrices(std::vector<double>(
                matrices.data(), matrices.data() + 12 * matrices.shape(0)));
        },
        "matrices"_a, "Throws naming the first non-finite or singular instance matrix.");
    m.def("build_instanced", &build, "meshes"_a, "mesh_index"_a, "matrices"_a, "bins"_a,
          "traversal_cost"_a, "intersect_cost"_a, "threads"_a, "progress"_a.none(),
          "The top level over instances of the mesh trees (the caller keeps them alive).");
    m.def("intersect_instanced", &intersect, "scene"_a, "origins"_a, "directions"_a, "tmin"_a,
          "tmax"_a, "t"_a, "prim"_a, "u"_a, "v"_a, "instance"_a, "steps"_a.none(),
          "general_steps"_a.none(), "tests"_a.none(), "culled"_a.none(), "box_tests"_a.none(),
          "top_steps"_a.none(), "instance_visits"_a.none(), "threads"_a, "packets"_a, "progress"_a.none(),
          "ray_order"_a = 0);
    m.def(
        "orders_instanced_rays",
        [](const InstancedScene& scene, Vec3Array origins, Vec3Array directions, int threads) {
            const RayBatch rays = unlimited_rays(origins, directions);
            nb::gil_scoped_release release;
            return orders_batch(scene, rays, RayOrder::Auto, threads);
        },
        "scene"_a, "origins"_a, "directions"_a, "threads"_a = 0,
        "Whether the instanced hits-only path traces these rays (tmin 0, tmax inf) in spatial "
        "order under ray_order='auto' on `threads` threads (0: all).");
}

}  // namespace bsp::bindings
