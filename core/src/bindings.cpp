// The nanobind module: argument conversion and GIL handling only. Input
// checking with readable messages lives in the Python package (bsplab/).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/unique_ptr.h>

#include <cstring>
#include <memory>

#include "kd_build.hpp"
#include "traverse.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using TriArray = nb::ndarray<const float, nb::shape<-1, 3, 3>, nb::c_contig, nb::device::cpu>;
using Vec3Array = nb::ndarray<const float, nb::shape<-1, 3>, nb::c_contig, nb::device::cpu>;
using FloatIn = nb::ndarray<const float, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
template <class T>
using Out = nb::ndarray<T, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

std::unique_ptr<bsp::KdTree> build_kd(TriArray tris, float traversal_cost, float intersect_cost,
                                      float empty_bonus, int max_depth, int leaf_size,
                                      float max_duplication, double memory_limit_mb, int threads,
                                      bsp::Progress* progress) {
    bsp::BuildOptions opt;
    opt.traversal_cost = traversal_cost;
    opt.intersect_cost = intersect_cost;
    opt.empty_bonus = empty_bonus;
    opt.max_depth = max_depth;
    opt.leaf_size = leaf_size;
    opt.max_duplication = max_duplication;
    opt.memory_limit_mb = memory_limit_mb;
    opt.threads = threads;
    const size_t n = tris.shape(0);
    const float* src = tris.data();
    nb::gil_scoped_release release;
    std::vector<bsp::Triangle> copy(n);
    std::memcpy(static_cast<void*>(copy.data()), src, n * sizeof(bsp::Triangle));
    return std::make_unique<bsp::KdTree>(bsp::build_kd_tree(std::move(copy), opt, progress));
}

void intersect(const bsp::KdTree& tree, Vec3Array origins, Vec3Array directions, FloatIn tmin,
               FloatIn tmax, Out<float> t, Out<int32_t> prim, Out<float> u, Out<float> v,
               Out<uint32_t> steps, Out<uint32_t> tests, int threads, bsp::Progress* progress) {
    const size_t n = origins.shape(0);
    auto check = [n](size_t m, const char* what) {
        if (m != n) throw std::invalid_argument(std::string(what) + " has the wrong length");
    };
    check(directions.shape(0), "directions");
    check(t.shape(0), "t");
    check(prim.shape(0), "prim");
    check(u.shape(0), "u");
    check(v.shape(0), "v");
    check(steps.shape(0), "steps");
    check(tests.shape(0), "tests");
    if (tmin.shape(0) != 1) check(tmin.shape(0), "tmin");
    if (tmax.shape(0) != 1) check(tmax.shape(0), "tmax");
    bsp::RayBatch rays;
    rays.origins = origins.data();
    rays.directions = directions.data();
    rays.tmin = tmin.data();
    rays.tmax = tmax.data();
    rays.tmin_stride = tmin.shape(0) == 1 ? 0 : 1;
    rays.tmax_stride = tmax.shape(0) == 1 ? 0 : 1;
    rays.count = n;
    bsp::HitBatch hits{t.data(), prim.data(), u.data(), v.data(), steps.data(), tests.data()};
    nb::gil_scoped_release release;
    bsp::intersect(tree, rays, hits, threads, progress);
}

nb::dict stats(const bsp::KdTree& tree) {
    const bsp::BuildStats& s = tree.stats;
    nb::dict d;
    d["build_seconds"] = s.build_seconds;
    d["triangles"] = s.triangles;
    d["degenerate"] = s.degenerate;
    d["nodes"] = s.nodes;
    d["interior_nodes"] = s.interior_nodes;
    d["kd_nodes"] = s.interior_nodes;
    d["general_nodes"] = 0;
    d["leaves"] = s.leaves;
    d["empty_leaves"] = s.empty_leaves;
    d["max_depth"] = s.max_depth;
    d["depth_limit"] = s.depth_limit;
    d["mean_leaf_depth"] = s.mean_leaf_depth;
    d["references"] = s.references;
    const uint64_t live = s.triangles - s.degenerate;
    d["duplication"] = live ? double(s.references) / double(live) : 0.0;
    const uint64_t full = s.leaves - s.empty_leaves;
    d["mean_leaf_size"] = full ? double(s.references) / double(full) : 0.0;
    d["max_leaf_size"] = s.max_leaf_size;
    d["bytes"] = s.bytes;
    d["node_bytes"] = uint64_t(tree.nodes.size() * sizeof(bsp::KdNode));
    d["sah_cost"] = s.sah_cost;
    return d;
}

nb::bytes node_bytes(const bsp::KdTree& tree) {
    return nb::bytes(reinterpret_cast<const char*>(tree.nodes.data()),
                     tree.nodes.size() * sizeof(bsp::KdNode));
}

}  // namespace

NB_MODULE(_core, m) {
    m.doc() = "BSP Lab core: kd/BSP tree construction and ray traversal";

    nb::exception<bsp::Cancelled>(m, "Cancelled", PyExc_RuntimeError);

    nb::class_<bsp::Progress>(m, "Progress",
                              "Progress of a build or trace; cancel() from any thread.")
        .def(nb::init<>())
        .def_prop_ro("value", &bsp::Progress::value, "Fraction done, 0..1.")
        .def_prop_ro("cancelled", &bsp::Progress::cancelled)
        .def("cancel", &bsp::Progress::cancel, "Ask the running work to stop.")
        .def("reset", &bsp::Progress::reset);

    nb::class_<bsp::KdTree>(m, "KdTree")
        .def("stats", &stats)
        .def("node_bytes", &node_bytes, "The raw node array (for reproducibility checks).")
        .def_prop_ro(
            "triangles",
            [](const bsp::KdTree& t) {
                return nb::ndarray<const float, nb::numpy, nb::shape<-1, 3, 3>>(
                    reinterpret_cast<const float*>(t.triangles.data()), {t.triangles.size(), 3, 3},
                    nb::handle());
            },
            nb::rv_policy::reference_internal)
        .def_prop_ro("bounds", [](const bsp::KdTree& t) {
            return nb::make_tuple(nb::make_tuple(t.bounds.lo.x, t.bounds.lo.y, t.bounds.lo.z),
                                  nb::make_tuple(t.bounds.hi.x, t.bounds.hi.y, t.bounds.hi.z));
        });

    m.def("build_kd", &build_kd, "triangles"_a, "traversal_cost"_a, "intersect_cost"_a,
          "empty_bonus"_a, "max_depth"_a, "leaf_size"_a, "max_duplication"_a,
          "memory_limit_mb"_a, "threads"_a, "progress"_a.none());
    m.def("intersect", &intersect, "tree"_a, "origins"_a, "directions"_a, "tmin"_a, "tmax"_a,
          "t"_a, "prim"_a, "u"_a, "v"_a, "steps"_a, "tests"_a, "threads"_a,
          "progress"_a.none());
}
