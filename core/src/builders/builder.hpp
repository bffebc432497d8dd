// A builder as the registry (registry.cpp) holds it: the function that turns
// triangles and options into a flat tree, and what that tree's interior nodes
// are. A method names one builder; adding a builder is a new file here that
// defines a BuildFunction, and one Builder constant in registry.cpp.
#pragma once
#include <vector>

#include "progress.hpp"
#include "tree.hpp"

namespace bsp {

// Builds a tree over `triangles` (moved into the tree). Zero-area triangles
// keep their index but are left out of the tree, so they are never hit.
// Throws Cancelled when `progress` is cancelled, MemoryLimitExceeded (a
// std::bad_alloc) as soon as the build would exceed options.memory_limit_mb.
using BuildFunction = Tree (*)(std::vector<Triangle> triangles, const BuildOptions& options,
                               Progress* progress);

struct Builder {
    const char* name;     // what the method table reports: "kd", "bsp", "bvh"
    BuildFunction build;
    // Its interior nodes are general (non-axis) nodes, axis splits included,
    // unless the method stores axis splits as kd nodes (^Kd, kd_nodes).
    bool general_nodes;
    // What its trees are made of: split planes (kd, BSP) or boxes (BVH).
    Structure structure = Structure::Bsp;
};

inline const char* structure_name(Structure s) { return s == Structure::Bvh ? "bvh" : "bsp"; }

}  // namespace bsp
