// The nanobind module: argument conversion and GIL handling only. Input
// checking with readable messages lives in the Python package (bsplab/).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/unique_ptr.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/variant.h>
#include <nanobind/stl/vector.h>

#include <cstring>
#include <memory>

#include "build/bsp_build.hpp"
#include "build/cell.hpp"
#include "trace/cpu_dispatch.hpp"
#include "build/kd_build.hpp"
#include "build/memory.hpp"
#include "registry.hpp"
#include "trace/trace_path.hpp"
#include "trace/traverse.hpp"
#include "inspect/tree_geometry.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using TriArray = nb::ndarray<const float, nb::shape<-1, 3, 3>, nb::c_contig, nb::device::cpu>;
using Vec3Array = nb::ndarray<const float, nb::shape<-1, 3>, nb::c_contig, nb::device::cpu>;
using FloatIn = nb::ndarray<const float, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
template <class T>
using Out = nb::ndarray<T, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

std::unique_ptr<bsp::Tree> build(TriArray tris, const std::string& builder,
                                 const bsp::BuildOptions& opt, bsp::Progress* progress) {
    if (builder != "kd" && builder != "bsp") throw std::invalid_argument("unknown builder " + builder);
    const size_t n = tris.shape(0);
    const float* src = tris.data();
    nb::gil_scoped_release release;
    std::vector<bsp::Triangle> copy(n);
    std::memcpy(static_cast<void*>(copy.data()), src, n * sizeof(bsp::Triangle));
    if (builder == "kd")
        return std::make_unique<bsp::Tree>(bsp::build_kd_tree(std::move(copy), opt, progress));
    return std::make_unique<bsp::Tree>(bsp::build_bsp_tree(std::move(copy), opt, progress));
}

using Counter = std::optional<Out<uint32_t>>;

// The counter arrays are all given (the counting path) or all None (the
// hits-only path); the core rejects a mix.
void intersect(const bsp::Tree& tree, Vec3Array origins, Vec3Array directions, FloatIn tmin,
               FloatIn tmax, Out<float> t, Out<int32_t> prim, Out<float> u, Out<float> v,
               Counter steps, Counter general_steps, Counter tests, Counter culled, int threads,
               bool cull, bsp::Progress* progress, bool packets) {
    if (packets && cull)
        throw std::invalid_argument("intersect: packets trace without culling (use cull=False)");
    const size_t n = origins.shape(0);
    auto check = [n](size_t m, const char* what) {
        if (m != n) throw std::invalid_argument(std::string(what) + " has the wrong length");
    };
    auto counter = [&](Counter& c, const char* what) -> uint32_t* {
        if (!c) return nullptr;
        check(c->shape(0), what);
        return c->data();
    };
    check(directions.shape(0), "directions");
    check(t.shape(0), "t");
    check(prim.shape(0), "prim");
    check(u.shape(0), "u");
    check(v.shape(0), "v");
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
    bsp::HitBatch hits{t.data(),
                       prim.data(),
                       u.data(),
                       v.data(),
                       counter(steps, "steps"),
                       counter(general_steps, "general_steps"),
                       counter(tests, "tests"),
                       counter(culled, "culled")};
    nb::gil_scoped_release release;
    if (packets)
        bsp::intersect_packets(tree, rays, hits, threads, progress);
    else
        bsp::intersect(tree, rays, hits, threads, cull, progress);
}

// A vector handed to numpy without a copy: the array owns it from here on.
template <class T>
nb::ndarray<nb::numpy, T> owned_array(std::vector<T>&& v, size_t columns = 1) {
    auto* owner = new std::vector<T>(std::move(v));
    nb::capsule free_it(owner, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
    const size_t rows = owner->size() / columns;
    if (columns == 1) return nb::ndarray<nb::numpy, T>(owner->data(), {rows}, free_it);
    return nb::ndarray<nb::numpy, T>(owner->data(), {rows, columns}, free_it);
}

void put_polygons(nb::dict& d, bsp::PolygonSoup&& p) {
    d["vertices"] = owned_array(std::move(p.vertices), 3);
    d["offsets"] = owned_array(std::move(p.offsets));
}

// The per-row columns that split polygons and node cells share.
template <class Rows>
void put_node_rows(nb::dict& d, Rows& rows) {
    d["node"] = owned_array(std::move(rows.node));
    d["depth"] = owned_array(std::move(rows.depth));
    d["kind"] = owned_array(std::move(rows.kind));
    d["cut"] = rows.cut;
}

nb::dict split_polygons(const bsp::Tree& tree, int max_depth, uint32_t root, size_t max_polygons) {
    bsp::SplitPolygons s;
    {
        nb::gil_scoped_release release;
        s = bsp::split_polygons(tree, max_depth, root, max_polygons);
    }
    nb::dict d;
    put_polygons(d, std::move(s.polygons));
    put_node_rows(d, s);
    d["plane"] = owned_array(std::move(s.planes), 4);
    return d;
}

nb::dict node_cells(const bsp::Tree& tree, int max_depth, uint32_t root, size_t max_cells) {
    bsp::NodeCells c;
    {
        nb::gil_scoped_release release;
        c = bsp::node_cells(tree, max_depth, root, max_cells);
    }
    nb::dict d;
    put_polygons(d, std::move(c.faces));
    d["cell_offsets"] = owned_array(std::move(c.cell_offsets));
    put_node_rows(d, c);
    return d;
}

// The recorded walk as columns: one row per visited node, one per test.
nb::dict trace_path(const bsp::Tree& tree, std::array<float, 3> o, std::array<float, 3> dir,
                    float tmin, float tmax, bool cull) {
    const bsp::TracePath p = bsp::trace_path(tree, o.data(), dir.data(), tmin, tmax, cull);
    const size_t n = p.steps.size(), m = p.tests.size();
    std::vector<uint32_t> node(n), test_step(m), test_prim(m);
    std::vector<int32_t> depth(n);
    std::vector<uint8_t> kind(n), result(m);
    std::vector<double> t_range(2 * n), plane(4 * n, std::nan(""));
    std::vector<float> test_t(m);
    for (size_t i = 0; i < n; ++i) {
        node[i] = p.steps[i].node;
        depth[i] = p.steps[i].depth;
        kind[i] = p.steps[i].kind;
        t_range[2 * i] = p.steps[i].t0;
        t_range[2 * i + 1] = p.steps[i].t1;
        bsp::world_plane(tree, node[i], &plane[4 * i]);
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
    return d;
}

nb::dict stats(const bsp::Tree& tree) {
    const bsp::BuildStats& s = tree.stats;
    nb::dict d;
    d["build_seconds"] = s.build_seconds;
    d["triangles"] = s.triangles;
    d["degenerate"] = s.degenerate;
    d["nodes"] = s.nodes;
    d["interior_nodes"] = s.interior_nodes;
    d["kd_nodes"] = s.kd_nodes;
    d["general_nodes"] = s.general_nodes;
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
    d["node_bytes"] = uint64_t(tree.nodes.size() * sizeof(bsp::Node));
    d["plane_bytes"] = uint64_t(tree.planes.size() * sizeof(bsp::Plane));
    d["box_bytes"] = s.box_bytes;
    static const char* kinds[] = {"none", "triangle", "clipped"};
    d["leaf_boxes"] = kinds[int(tree.options.leaf_boxes)];
    d["sah_cost"] = s.sah_cost;
    d["peak_bytes"] = s.peak_bytes;
    nb::list warnings;
    for (const std::string& w : s.warnings) warnings.append(w);
    d["warnings"] = warnings;
    nb::list planes, dirs;
    for (const bsp::LevelStats& l : s.levels) {
        planes.append(l.planes);
        dirs.append(l.directions);
    }
    d["level_planes"] = planes;
    d["level_directions"] = dirs;
    return d;
}

// The registry (registry.hpp) as plain dicts and lists: what the Python
// package generates its method table, option checks and the add-on's panel from.
nb::object value(const bsp::OptionValue& v) {
    return std::visit([](const auto& x) -> nb::object { return nb::cast(x); }, v);
}

nb::object optional_value(const std::optional<bsp::OptionValue>& v) {
    return v ? value(*v) : nb::none();
}

nb::dict option_dict(const bsp::OptionSpec& o) {
    static const char* types[] = {"float", "int", "enum"};
    nb::dict d;
    d["name"] = o.name;
    d["type"] = types[int(o.type)];
    d["group"] = o.group;
    d["default"] = value(o.default_value);
    d["min"] = optional_value(o.min);
    d["max"] = optional_value(o.max);
    d["min_open"] = o.min_open;
    d["per_method_limits"] = o.per_method_limits;
    d["soft_max"] = o.soft_max ? nb::cast(*o.soft_max) : nb::none();
    nb::list choices;
    for (const bsp::Choice& c : o.choices) {
        nb::dict cd;
        cd["name"] = c.name;
        cd["label"] = c.label;
        cd["help"] = c.help;
        cd["k_values"] = c.k_values;
        choices.append(cd);
    }
    d["choices"] = choices;
    d["label"] = o.label;
    d["short_label"] = o.short_label;
    d["help"] = o.help;
    d["field"] = o.field;
    return d;
}

nb::dict method_dict(const bsp::MethodSpec& m) {
    nb::dict d;
    d["name"] = m.name;
    d["label"] = m.label;
    d["description"] = m.description;
    d["builder"] = m.builder;
    d["strategy"] = m.strategy;
    d["plus_axes"] = m.plus_axes;
    d["kd_nodes"] = m.kd_nodes;
    d["options"] = m.options;
    nb::dict defaults;
    for (const auto& [name, v] : m.defaults) defaults[name.c_str()] = value(v);
    d["defaults"] = defaults;
    d["min_k"] = m.min_k();
    d["max_k"] = m.max_k();
    return d;
}

nb::dict registry() {
    nb::dict d;
    nb::list options, methods;
    for (const bsp::OptionSpec& o : bsp::option_specs()) options.append(option_dict(o));
    for (const bsp::MethodSpec& m : bsp::method_specs()) methods.append(method_dict(m));
    d["options"] = options;
    d["methods"] = methods;
    d["strategies"] = bsp::strategy_names();
    d["max_k"] = bsp::kMaxK;
    return d;
}

nb::bytes node_bytes(const bsp::Tree& tree) {
    std::string out(reinterpret_cast<const char*>(tree.nodes.data()),
                    tree.nodes.size() * sizeof(bsp::Node));
    out.append(reinterpret_cast<const char*>(tree.planes.data()),
               tree.planes.size() * sizeof(bsp::Plane));
    return nb::bytes(out.data(), out.size());
}

}  // namespace

NB_MODULE(_core, m) {
    m.doc() = "BSP Lab core: kd/BSP tree construction and ray traversal";

    nb::exception<bsp::Cancelled>(m, "Cancelled", PyExc_RuntimeError);
    // Over memory_limit_mb: a MemoryError that says what the build needed.
    nb::register_exception_translator([](const std::exception_ptr& p, void*) {
        try {
            std::rethrow_exception(p);
        } catch (const bsp::MemoryLimitExceeded& e) {
            PyErr_SetString(PyExc_MemoryError, e.what());
        }
    });

    nb::class_<bsp::Progress>(m, "Progress",
                              "Progress of a build or trace; cancel() from any thread.")
        .def(nb::init<>())
        .def_prop_ro("value", &bsp::Progress::value, "Fraction done, 0..1.")
        .def_prop_ro("cancelled", &bsp::Progress::cancelled)
        .def("cancel", &bsp::Progress::cancel, "Ask the running work to stop.")
        .def("reset", &bsp::Progress::reset,
             "Ready for the next job: value back to 0 and any cancel cleared.");

    nb::enum_<bsp::LeafBoxes>(m, "LeafBoxes")
        .value("none", bsp::LeafBoxes::None)
        .value("triangle", bsp::LeafBoxes::Triangle)
        .value("clipped", bsp::LeafBoxes::Clipped);

    nb::class_<bsp::BuildOptions>(m, "BuildOptions")
        .def(nb::init<>())
        .def_rw("traversal_cost", &bsp::BuildOptions::traversal_cost)
        .def_rw("intersect_cost", &bsp::BuildOptions::intersect_cost)
        .def_rw("empty_bonus", &bsp::BuildOptions::empty_bonus)
        .def_rw("max_depth", &bsp::BuildOptions::max_depth)
        .def_rw("leaf_size", &bsp::BuildOptions::leaf_size)
        .def_rw("max_duplication", &bsp::BuildOptions::max_duplication)
        .def_rw("memory_limit_mb", &bsp::BuildOptions::memory_limit_mb)
        .def_rw("threads", &bsp::BuildOptions::threads)
        .def_rw("strategy", &bsp::BuildOptions::strategy)
        .def_rw("k", &bsp::BuildOptions::k)
        .def_rw("plus_axes", &bsp::BuildOptions::plus_axes)
        .def_rw("kd_nodes", &bsp::BuildOptions::kd_nodes)
        .def_rw("fixed_set", &bsp::BuildOptions::fixed_set)
        .def_rw("seed", &bsp::BuildOptions::seed)
        .def_rw("alpha", &bsp::BuildOptions::alpha)
        .def_rw("general_cost", &bsp::BuildOptions::general_cost)
        .def_rw("cluster_iterations", &bsp::BuildOptions::cluster_iterations)
        .def_rw("cluster_sample", &bsp::BuildOptions::cluster_sample)
        .def_rw("ize_candidates", &bsp::BuildOptions::ize_candidates)
        .def_rw("leaf_boxes", &bsp::BuildOptions::leaf_boxes);

    nb::class_<bsp::Tree>(m, "Tree")
        .def("stats", &stats)
        .def("node_bytes", &node_bytes, "The raw node and plane arrays (reproducibility checks).")
        .def_prop_ro(
            "triangles",
            [](const bsp::Tree& t) {
                return nb::ndarray<const float, nb::numpy, nb::shape<-1, 3, 3>>(
                    reinterpret_cast<const float*>(t.triangles.data()), {t.triangles.size(), 3, 3},
                    nb::handle());
            },
            nb::rv_policy::reference_internal)
        .def("arrays",
             [](const bsp::Tree& t) {
                 // Copies of the raw arrays, for inspection and drawing.
                 nb::dict d;
                 d["nodes"] = nb::bytes(reinterpret_cast<const char*>(t.nodes.data()),
                                        t.nodes.size() * sizeof(bsp::Node));
                 d["refs"] = nb::bytes(reinterpret_cast<const char*>(t.refs.data()),
                                       t.refs.size() * sizeof(uint32_t));
                 d["planes"] = nb::bytes(reinterpret_cast<const char*>(t.planes.data()),
                                         t.planes.size() * sizeof(bsp::Plane));
                 return d;
             })
        .def_ro("scale", &bsp::Tree::scale,
                "The power of two the triangles (and bounds) were multiplied by inside the tree.")
        .def_prop_ro("bounds", [](const bsp::Tree& t) {
            return nb::make_tuple(nb::make_tuple(t.bounds.lo.x, t.bounds.lo.y, t.bounds.lo.z),
                                  nb::make_tuple(t.bounds.hi.x, t.bounds.hi.y, t.bounds.hi.z));
        });

    m.def(
        "cell_areas",
        [](std::array<float, 3> lo, std::array<float, 3> hi, std::vector<std::array<double, 4>> cuts,
           std::array<double, 3> u, std::vector<double> ts) {
            // A box cut by planes (keeping the part below each), then the areas
            // below/above u.x = t for each t: directly and from the table.
            bsp::Box b;
            b.lo = bsp::Vec3(lo[0], lo[1], lo[2]);
            b.hi = bsp::Vec3(hi[0], hi[1], hi[2]);
            bsp::Cell c = bsp::Cell::from_box(b);
            for (auto& p : cuts) {
                bsp::Cell below, above;
                c.split(bsp::Vec3d(p[0], p[1], p[2]), p[3], below, above);
                c = below;
            }
            const bsp::Vec3d ud(u[0], u[1], u[2]);
            bsp::CellProjection direct(c, ud), table(c, ud);
            table.tabulate();
            nb::list out;
            for (double t : ts) {
                double b0, a0, b1, a1;
                direct.areas_at(t, b0, a0);
                table.eval(t, b1, a1);
                out.append(nb::make_tuple(b0, a0, b1, a1));
            }
            return nb::make_tuple(c.area(), out);
        },
        "lo"_a, "hi"_a, "cuts"_a, "u"_a, "ts"_a, "Surface areas of cut cells (for tests).");
    m.def(
        "cpu_features",
        [] {
            const bsp::CpuFeatures& f = bsp::cpu_features();
            nb::dict d;
            d["supported"] = f.supported;
            d["selected"] = f.selected;
            d["packet_width"] = bsp::selected_kernels().packet_width;
            d["forced"] = f.forced.empty() ? nb::none() : nb::object(nb::str(f.forced.c_str()));
            return d;
        },
        "The kernels' instruction-set levels: supported here, selected, forced by BSPLAB_ISA; the selected level's rays per packet.");
    m.def(
        "rays_are_valid",
        [](Vec3Array origins, Vec3Array directions) {
            if (origins.shape(0) != directions.shape(0))
                throw std::invalid_argument("origins and directions differ in length");
            return bsp::rays_are_valid(origins.data(), directions.data(), origins.shape(0));
        },
        "origins"_a, "directions"_a, "All finite, no zero direction (checks.rays names the bad ones).");
    m.def("registry", &registry, "The methods, options and strategies of registry.hpp.");
    m.def(
        "options_for",
        [](const std::string& method, const std::map<std::string, bsp::OptionValue>& values) {
            return bsp::options_for(bsp::method_spec(method), values);
        },
        "method"_a, "values"_a, "The method's BuildOptions with `values` set by option name.");
    m.def("build", &build, "triangles"_a, "builder"_a, "options"_a, "progress"_a.none());
    m.def("intersect", &intersect, "tree"_a, "origins"_a, "directions"_a, "tmin"_a, "tmax"_a,
          "t"_a, "prim"_a, "u"_a, "v"_a, "steps"_a.none(), "general_steps"_a.none(), "tests"_a.none(),
          "culled"_a.none(),
          "threads"_a, "cull"_a, "progress"_a.none(), "packets"_a = false);
    m.def("split_polygons", &split_polygons, "tree"_a, "max_depth"_a, "root"_a, "max_polygons"_a);
    m.def("node_cells", &node_cells, "tree"_a, "max_depth"_a, "root"_a, "max_cells"_a);
    m.def(
        "node_at",
        [](const bsp::Tree& tree, std::array<double, 3> p, int max_depth) {
            const bsp::NodeAt at = bsp::node_at(tree, p.data(), max_depth);
            return nb::make_tuple(at.node, at.depth);
        },
        "tree"_a, "point"_a, "max_depth"_a);
    m.def("trace_path", &trace_path, "tree"_a, "origin"_a, "direction"_a, "tmin"_a, "tmax"_a,
          "cull"_a);
}
