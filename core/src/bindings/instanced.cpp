// Instanced scenes: the top level over instances of shared mesh trees
// (instanced.hpp), built and traced. The Python InstancedTree keeps the mesh
// trees alive; the scene only points at them.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/variant.h>
#include <nanobind/stl/vector.h>

#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bindings/arrays.hpp"
#include "bindings/bindings.hpp"
#include "bindings/paths.hpp"
#include "bindings/ray_batches.hpp"
#include "instanced.hpp"
#include "registry.hpp"
#include "trace/instanced_trace_path.hpp"

namespace bsp::bindings {

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using MatrixArray = nb::ndarray<const double, nb::shape<-1, 3, 4>, nb::c_contig, nb::device::cpu>;
using IndexArray = nb::ndarray<const uint32_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

// The top level's options by name (the registry's "top" group and threads),
// as tree.cpp's build() takes a method's: the registry sets them.
InstancedScene build(const std::vector<const Tree*>& meshes, IndexArray mesh_index,
                     MatrixArray matrices, const std::map<std::string, OptionValue>& values,
                     Progress* progress) {
    const size_t n = mesh_index.shape(0);
    if (matrices.shape(0) != n)
        throw std::invalid_argument("build_instanced: one matrix per instance");
    std::vector<uint32_t> index(mesh_index.data(), mesh_index.data() + n);
    std::vector<double> m(matrices.data(), matrices.data() + 12 * n);
    const TopLevelSettings s = top_settings_for(values);
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

// The recorded walk of both levels (InstancedTree.trace_path's keys): the hit
// and the counts, per top-level node visited its row, per instance entered
// the ray in its object space and its mesh tree's record (paths.hpp).
nb::dict trace_path(const InstancedScene& scene, std::array<float, 3> o,
                    std::array<float, 3> dir, float tmin, float tmax) {
    const InstancedTracePath p = bsp::trace_path(scene, o.data(), dir.data(), tmin, tmax);
    const size_t n = p.top.size();
    std::vector<int64_t> node(n);
    std::vector<double> t_range(2 * n);
    std::vector<float> box_lo(3 * n), box_hi(3 * n);
    for (size_t i = 0; i < n; ++i) {
        node[i] = p.top[i].node;
        t_range[2 * i] = p.top[i].t0;
        t_range[2 * i + 1] = p.top[i].t1;
        const BvhNode b = scene.top.node(p.top[i].node);
        for (int k = 0; k < 3; ++k) {
            box_lo[3 * i + k] = b.lo[k];
            box_hi[3 * i + k] = b.hi[k];
        }
    }
    nb::dict top;
    top["node"] = owned_array(std::move(node));
    top["t_range"] = owned_array(std::move(t_range), 2);
    top["box_lo"] = owned_array(std::move(box_lo), 3);
    top["box_hi"] = owned_array(std::move(box_hi), 3);
    nb::list visits;
    for (const InstancePathVisit& v : p.instances) {
        nb::dict e;
        e["instance"] = v.instance;
        e["mesh"] = v.mesh;
        e["origin"] = owned_array(std::vector<float>(v.origin, v.origin + 3));
        e["direction"] = owned_array(std::vector<float>(v.direction, v.direction + 3));
        e["path"] = path_dict(*scene.meshes[v.mesh], v.path);
        visits.append(e);
    }
    nb::dict d;
    put_hit_and_counts(d, p);
    d["instance"] = p.instance;
    d["flat_prim"] = p.flat_prim;
    d["top_steps"] = p.n_top_steps;
    d["instance_visits"] = p.n_instance_visits;
    d["top"] = top;
    d["instances"] = visits;
    return d;
}

nb::dict stats(const InstancedScene& scene) {
    const InstancedStats& s = scene.stats;
    nb::dict d;
    // The fields of InstancedStats under their own names, as a Tree's stats.
    for (const auto& [name, value] :
         {std::pair<const char*, uint64_t>{"meshes", s.meshes}, {"instances", s.instances},
          {"top_nodes", s.top_nodes}, {"top_leaves", s.top_leaves}, {"top_bytes", s.top_bytes},
          {"instanced_triangles", s.instanced_triangles}})
        d[name] = value;
    d["top_depth"] = s.top_depth;
    d["top_sah_cost"] = s.top_sah_cost;
    d["top_build_seconds"] = s.top_build_seconds;
    return d;
}

// The top level's nodes and the instances' inverse matrices, as arrays: for
// drawing the top level's boxes and carrying points between the world and
// an instance's object space (bsplab/instanced.py).
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
    m.def("trace_path_instanced", &trace_path, "scene"_a, "origin"_a, "direction"_a, "tmin"_a,
          "tmax"_a, "One ray's recorded walk through both levels.");
    m.def(
        "check_instance_matrices",
        [](MatrixArray matrices) {
            check_instance_matrices(std::vector<double>(
                matrices.data(), matrices.data() + 12 * matrices.shape(0)));
        },
        "matrices"_a, "Throws naming the first non-finite or singular instance matrix.");
    m.def("build_instanced", &build, "meshes"_a, "mesh_index"_a, "matrices"_a,
          "option_values"_a, "progress"_a.none(),
          "The top level over instances of the mesh trees (the caller keeps them alive), with "
          "`option_values` (the registry's top options, threads) set by option name.");
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
