// The tree's geometry for drawing and inspection (inspect/tree_geometry.hpp):
// split polygons, node cells, the node at a point, as numpy columns.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/array.h>

#include "bindings/arrays.hpp"
#include "bindings/bindings.hpp"
#include "inspect/bvh_geometry.hpp"
#include "inspect/tree_geometry.hpp"

namespace bsp::bindings {

namespace nb = nanobind;
using namespace nb::literals;

namespace {

void put_polygons(nb::dict& d, PolygonSoup&& p) {
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

nb::dict split_polygons(const Tree& tree, int max_depth, uint32_t root, size_t max_polygons) {
    SplitPolygons s;
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

nb::dict node_cells(const Tree& tree, int max_depth, uint32_t root, size_t max_cells) {
    NodeCells c;
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

nb::dict node_boxes(const Tree& tree, int max_depth, uint32_t root, size_t max_boxes) {
    NodeBoxes b;
    {
        nb::gil_scoped_release release;
        b = bsp::node_boxes(tree, max_depth, root, max_boxes);
    }
    nb::dict d;
    d["lo"] = owned_array(std::move(b.lo), 3);
    d["hi"] = owned_array(std::move(b.hi), 3);
    d["node"] = owned_array(std::move(b.node));
    d["depth"] = owned_array(std::move(b.depth));
    d["leaf"] = owned_array(std::move(b.leaf));
    d["cut"] = b.cut;
    return d;
}

}  // namespace

void bind_inspect(nb::module_& m) {
    m.def("split_polygons", &split_polygons, "tree"_a, "max_depth"_a, "root"_a, "max_polygons"_a);
    m.def("node_boxes", &node_boxes, "tree"_a, "max_depth"_a, "root"_a, "max_boxes"_a);
    m.def("node_cells", &node_cells, "tree"_a, "max_depth"_a, "root"_a, "max_cells"_a);
    m.def(
        "node_at",
        [](const Tree& tree, std::array<double, 3> p, int max_depth) {
            const NodeAt at = bsp::node_at(tree, p.data(), max_depth);
            return nb::make_tuple(at.node, at.depth);
        },
        "tree"_a, "point"_a, "max_depth"_a);
}

}  // namespace bsp::bindings
