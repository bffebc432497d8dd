// The binding files, one per area of the library: each adds its classes and
// functions to the module (module.cpp calls them in this order). They convert
// arguments and results and release the GIL around the work, nothing more:
// input checking with readable messages lives in the Python package
// (bsplab/), dispatch by method name in the registry (registry.hpp).
#pragma once
#include <nanobind/nanobind.h>

namespace bsp::bindings {

void bind_jobs(nanobind::module_& m);      // jobs.cpp: Progress, Cancelled, MemoryError
void bind_registry(nanobind::module_& m);  // registry.cpp: methods, options, BuildOptions
void bind_tree(nanobind::module_& m);      // tree.cpp: build() and the Tree
void bind_trace(nanobind::module_& m);     // trace.cpp: intersect, trace_path, the CPU
void bind_inspect(nanobind::module_& m);   // inspect.cpp: split polygons, node cells
void bind_instanced(nanobind::module_& m); // instanced.cpp: two-level scenes over mesh trees

}  // namespace bsp::bindings
