// A recorded walk (trace/trace_path.hpp, trace/instanced_trace_path.hpp) as
// the dict bsplab's trace_path returns: shared by a tree's record
// (trace.cpp) and an instanced scene's (instanced.cpp), which holds a tree's
// record per instance entered.
#pragma once
#include <nanobind/nanobind.h>

#include "trace/trace_path.hpp"
#include "tree.hpp"

namespace bsp::bindings {

// The hit and the counts of a walk, under the names intersect() gives them:
// what every record holds (P: TracePath or InstancedTracePath).
template <class P>
void put_hit_and_counts(nanobind::dict& d, const P& p) {
    d["t"] = p.t;
    d["prim"] = p.prim;
    d["u"] = p.u;
    d["v"] = p.v;
    d["steps"] = p.n_steps;
    d["general_steps"] = p.n_general_steps;
    d["tests"] = p.n_tests;
    d["culled"] = p.n_culled;
    d["box_tests"] = p.n_box_tests;
}

// A tree's recorded walk as columns: one row per visited node, one per
// triangle test (Tree.trace_path's keys), with its hit and counts.
nanobind::dict path_dict(const Tree& tree, const TracePath& p);

}  // namespace bsp::bindings
