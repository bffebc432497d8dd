// A tree: built by method name (the registry's build(), one call from the
// Python package), and read back: statistics, raw arrays, bounds.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/unique_ptr.h>
#include <nanobind/stl/variant.h>

#include <cstring>
#include <memory>

#include "bindings/arrays.hpp"
#include "bindings/bindings.hpp"
#include "registry.hpp"

namespace bsp::bindings {

namespace nb = nanobind;
using namespace nb::literals;

namespace {

std::unique_ptr<Tree> build(TriArray tris, const std::string& method,
                            const std::map<std::string, OptionValue>& values, Progress* progress) {
    const size_t n = tris.shape(0);
    const float* src = tris.data();
    nb::gil_scoped_release release;
    std::vector<Triangle> copy(n);
    std::memcpy(static_cast<void*>(copy.data()), src, n * sizeof(Triangle));
    return std::make_unique<Tree>(bsp::build(method, std::move(copy), values, progress));
}

nb::dict stats(const Tree& tree) {
    const BuildStats& s = tree.stats;
    nb::dict d;
    // The fields of BuildStats under their own names, then what is derived.
    for (const auto& [name, value] :
         {std::pair<const char*, uint64_t>{"triangles", s.triangles}, {"degenerate", s.degenerate},
          {"nodes", s.nodes}, {"interior_nodes", s.interior_nodes}, {"kd_nodes", s.kd_nodes},
          {"general_nodes", s.general_nodes}, {"leaves", s.leaves},
          {"empty_leaves", s.empty_leaves}, {"references", s.references},
          {"max_leaf_size", s.max_leaf_size}, {"bytes", s.bytes}, {"box_bytes", s.box_bytes},
          {"peak_bytes", s.peak_bytes}})
        d[name] = value;
    d["build_seconds"] = s.build_seconds;
    d["max_depth"] = s.max_depth;
    d["depth_limit"] = s.depth_limit;
    d["mean_leaf_depth"] = s.mean_leaf_depth;
    d["sah_cost"] = s.sah_cost;
    const uint64_t live = s.triangles - s.degenerate;
    d["duplication"] = live ? double(s.references) / double(live) : 0.0;
    const uint64_t full = s.leaves - s.empty_leaves;
    d["mean_leaf_size"] = full ? double(s.references) / double(full) : 0.0;
    d["node_bytes"] = uint64_t(tree.nodes.size() * sizeof(Node) +
                               tree.bvh_nodes.size() * sizeof(BvhNode));
    d["structure"] = structure_name(tree.structure);
    // A BVH's wide layout (the one every path walks): its lanes per node,
    // its nodes, and the bytes of those and of the triangles copied in leaf
    // order (in "bytes" too).
    d["wide_width"] = uint64_t(tree.structure == Structure::Bvh ? BvhWideNode::kWidth : 0);
    d["wide_nodes"] = uint64_t(tree.bvh_wide.size());
    d["wide_bytes"] = uint64_t(tree.bvh_wide.size() * sizeof(BvhWideNode) +
                               tree.bvh_wide_binary.size() * sizeof(uint32_t) +
                               tree.bvh_leaf_tris.size() * sizeof(BvhLeafTriangle));
    d["plane_bytes"] = uint64_t(tree.planes.size() * sizeof(Plane));
    static const char* kinds[] = {"none", "triangle", "clipped"};
    d["leaf_boxes"] = kinds[int(tree.options.leaf_boxes)];
    // The quality the tree was built at: the BVH is binned whatever it was asked.
    d["build_quality"] = tree.structure == Structure::Bvh ? "binned"
                         : tree.options.build_quality == BuildQuality::Fast ? "fast"
                                                                            : "exact";
    nb::list warnings;
    for (const std::string& w : s.warnings) warnings.append(w);
    d["warnings"] = warnings;
    nb::list planes, dirs;
    for (const LevelStats& l : s.levels) {
        planes.append(l.planes);
        dirs.append(l.directions);
    }
    d["level_planes"] = planes;
    d["level_directions"] = dirs;
    return d;
}

// An array's bytes as a Python bytes object (a copy).
template <class T>
nb::bytes bytes_of(const std::vector<T>& v) {
    return nb::bytes(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

nb::bytes node_bytes(const Tree& tree) {
    std::string out(reinterpret_cast<const char*>(tree.nodes.data()),
                    tree.nodes.size() * sizeof(Node));
    out.append(reinterpret_cast<const char*>(tree.planes.data()),
               tree.planes.size() * sizeof(Plane));
    // A BVH's nodes and the leaves' triangle order (its refs).
    out.append(reinterpret_cast<const char*>(tree.bvh_nodes.data()),
               tree.bvh_nodes.size() * sizeof(BvhNode));
    if (tree.structure == Structure::Bvh)
        out.append(reinterpret_cast<const char*>(tree.refs.data()),
                   tree.refs.size() * sizeof(uint32_t));
    return nb::bytes(out.data(), out.size());
}

}  // namespace

void bind_tree(nb::module_& m) {
    nb::class_<Tree>(m, "Tree")
        .def("stats", &stats)
        .def("node_bytes", &node_bytes, "The raw node and plane arrays (reproducibility checks).")
        .def_prop_ro(
            "triangles",
            [](const Tree& t) {
                return nb::ndarray<const float, nb::numpy, nb::shape<-1, 3, 3>>(
                    reinterpret_cast<const float*>(t.triangles.data()), {t.triangles.size(), 3, 3},
                    nb::handle());
            },
            nb::rv_policy::reference_internal)
        .def("arrays",
             [](const Tree& t) {
                 // Copies of the raw arrays, for inspection and drawing.
                 nb::dict d;
                 d["nodes"] = bytes_of(t.nodes);
                 d["refs"] = bytes_of(t.refs);
                 d["planes"] = bytes_of(t.planes);
                 d["bvh_nodes"] = bytes_of(t.bvh_nodes);
                 return d;
             })
        .def_prop_ro("structure", [](const Tree& t) { return structure_name(t.structure); },
                     "\"bvh\" for a bounding-volume hierarchy, \"bsp\" for kd and BSP trees.")
        .def_ro("scale", &Tree::scale,
                "The power of two the triangles (and bounds) were multiplied by inside the tree.")
        .def_prop_ro("offset", [](const Tree& t) {
            return nb::make_tuple(t.offset[0], t.offset[1], t.offset[2]);
        }, "The point the triangles (and bounds) were moved by -offset from, before scaling: "
           "the tree's local frame, (0, 0, 0) unless the scene lies far from the origin.")
        .def_prop_ro("bounds", [](const Tree& t) {
            return nb::make_tuple(nb::make_tuple(t.bounds.lo.x, t.bounds.lo.y, t.bounds.lo.z),
                                  nb::make_tuple(t.bounds.hi.x, t.bounds.hi.y, t.bounds.hi.z));
        });

    m.def("build", &build, "triangles"_a, "method"_a, "option_values"_a, "progress"_a.none(),
          "The tree of the registry's method `method` with `option_values` set by option name.");
}

}  // namespace bsp::bindings
