// The nanobind module bsplab._core: the areas' binding files (bindings.hpp).
#include <nanobind/nanobind.h>

#include "bindings/bindings.hpp"

NB_MODULE(_core, m) {
    m.doc() = "BSP Lab core: kd/BSP tree construction and ray traversal";
    bsp::bindings::bind_jobs(m);
    bsp::bindings::bind_registry(m);
    bsp::bindings::bind_tree(m);
    bsp::bindings::bind_trace(m);
    bsp::bindings::bind_inspect(m);
    bsp::bindings::bind_instanced(m);
}
